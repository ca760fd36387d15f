"""A batch of runs in one system: the layout every system of the loop shares.

Every system of the closed loop steps a *batch* of ``B`` independent runs at once (``B = 1``
for a single run, through the same code). Its ports and its discrete state carry the batch
row-major by run: a port whose per-run value has ``n`` entries has ``B·n`` entries, run ``i``'s
at ``[i·n, (i + 1)·n)``; a 3×3 matrix per run is ``B·9`` entries, each run's row-major. The math
broadcasts over a leading run axis: a system reshapes what it reads to ``(B, n)`` (or
``(B, 3, 3)``) without copying, and writes ``(B, n)`` arrays back flattened.

This is the batch evaluation Drake's developers proposed for the systems framework (a context
whose state and ports carry a leading batch dimension, each system opting in with a vectorised
implementation, RobotLocomotion/drake issue 16339), done in Python for this loop: one diagram,
one ``Simulator``, B runs, the framework's cost per step shared by all of them.

A system of the loop takes ``batch_size`` (keyword, default 1) and exposes it as its
``batch_size`` attribute; the builder refuses a batch for a system without one, naming it.
Arithmetic a run does must not depend on the others: each run's numbers are the same bits
whatever its batch (reductions run along a run's own axes only, never across runs).
"""

import numpy as np

#: The attribute a system of the loop exposes: the number of runs it steps at once.
BATCH_SIZE = "batch_size"


def batch_size_field(value: object) -> int:
    """``value`` as a batch size: an integer ≥ 1 (one-line error naming it otherwise)."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise ValueError(f"batch_size: must be an integer ≥ 1, got {value!r}")
    return int(value)


def batch_size_of(system: object) -> int | None:
    """The batch a system steps (its ``batch_size``), or None for one that cannot batch."""
    value = getattr(system, BATCH_SIZE, None)
    return None if value is None else int(value)


def tiled(value: np.ndarray | list | tuple, batch_size: int) -> np.ndarray:
    """A per-run initial value repeated for each run of the batch, flattened row-major."""
    row = np.asarray(value, dtype=float).ravel()
    return np.tile(row, batch_size)


def per_run(vector: np.ndarray, batch_size: int, *shape: int) -> np.ndarray:
    """A batched port or state vector as a ``(B, *shape)`` view (``(B, n)`` by default)."""
    return np.asarray(vector).reshape(batch_size, *(shape or (-1,)))
