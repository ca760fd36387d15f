"""BLAS on one thread while the loop steps.

The loop's products are small (6×6 over runs, 6×N over particles). OpenBLAS splits a product
over threads from about 10⁴ elements on; waking the threads costs more than the product, the
more so beside a study's other workers (the realistic run took 12.8 s of CPU for 9 s of wall
with OpenBLAS's threads, 7.6 s with one). A threaded product also sums in another order: a run
simulated in one process, replayed or run over LCM gives the same bits only if all of them
step on the same number of threads.
"""

import functools
from collections.abc import Callable
from contextlib import AbstractContextManager
from typing import ParamSpec, TypeVar

from threadpoolctl import ThreadpoolController

P = ParamSpec("P")
T = TypeVar("T")
_controller: ThreadpoolController | None = None


def one_blas_thread() -> AbstractContextManager:
    """A context in which BLAS runs on one thread (restored on exit)."""
    global _controller
    if _controller is None:  # found once: inspecting the loaded libraries takes milliseconds
        _controller = ThreadpoolController()
    return _controller.limit(limits=1, user_api="blas")


def on_one_blas_thread(function: Callable[P, T]) -> Callable[P, T]:
    """``function`` run inside :func:`one_blas_thread` (for a loop that steps its own
    Simulators and evaluates ports between steps)."""

    @functools.wraps(function)
    def on_one_thread(*args: P.args, **kwargs: P.kwargs) -> T:
        with one_blas_thread():
            return function(*args, **kwargs)

    return on_one_thread
