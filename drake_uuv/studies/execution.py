"""Running studies: chunking, the local process pool or a Dask cluster, progress, outputs.

Run ``i`` of a study uses seed ``scenario.random_seed + i``. A run's numbers depend only on its
scenario and seed, and the summary is computed from the runs in seed order, so a study gives
bit-identical ``runs.csv`` and ``summary.json`` whatever the number of workers, the chunking or
the backend (local processes, or a ``dask.distributed`` cluster via ``scheduler``).

The missing seeds of every study are split into chunks, one task each
(:func:`drake_uuv.studies.runner.run_task`); the client writes each finished chunk to the
study folder at once (:func:`drake_uuv.studies.storage.write_part`), and when all are done
reads the runs back and writes ``runs.csv``, ``summary.json`` and the figures of
:data:`drake_uuv.analysis.registry.STUDY_FIGURES` (``figures/error_bands.{png,svg}``: median
and 5–95 % of the errors against k, mean NEES with its χ² band, and the RMS error over runs
beside the Monte Carlo PCRLB).
"""

import math
import os
import signal
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from drake_uuv.scenario import Scenario
from drake_uuv.studies.runner import NORMS, run_task
from drake_uuv.studies.statistics import monte_carlo_bound, summarize
from drake_uuv.studies.storage import (
    load_information,
    load_runs,
    missing_seeds,
    prepare,
    write_outputs,
    write_part,
)
from drake_uuv.studies.study import MonteCarloError, Study, StudyResult

Task = tuple[int, Scenario, list[int]]
OnDone = Callable[[int, dict[str, Any]], None]

_PR_SET_PDEATHSIG = 1  # <sys/prctl.h>
# Automatic chunk size: about two chunks per worker slot (load balance), at most this many
# seeds (little lost on interruption, and a worker runs a chunk as batches of runs), at least
# one.
_CHUNKS_PER_SLOT = 2
# A pool of n workers takes n times this many tasks, then a fresh pool the next. pydrake 1.51
# never frees a LeafSystem written in Python: the callbacks it stores in C++ (a port's calc,
# an event's handler) hold the system, a cycle Python's collector cannot see
# (RobotLocomotion/drake issues 23930 and 24162). So each simulation a worker builds stays
# in its memory (100-300 MB for a late-range particle row at its batch size), and a
# navigation study's worker, building one per row, grew past 11 GB and was killed.
TASKS_PER_WORKER = 8
_MAX_CHUNK = 250


def default_workers() -> int:
    """Every core this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def chunks(seeds: list[int], size: int) -> list[list[int]]:
    """``seeds`` in consecutive chunks of ``size`` (the last may be shorter)."""
    return [seeds[i : i + size] for i in range(0, len(seeds), size)]


def automatic_chunk_size(total: int, slots: int) -> int:
    """Seeds per task when not given: :data:`_CHUNKS_PER_SLOT` per slot, ≤ :data:`_MAX_CHUNK`."""
    return max(1, min(_MAX_CHUNK, math.ceil(total / (_CHUNKS_PER_SLOT * slots)) if total else 1))


def _die_with_parent() -> None:
    """Pool-worker initializer: on Linux, have the kernel kill the worker if the parent dies.

    Otherwise a killed parent (SIGKILL, out of memory) leaves forked workers blocked forever
    on the task queue, whose write end they inherited.
    """
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)
    except (OSError, AttributeError):  # not Linux: nothing to do
        pass


def execute_local(tasks: list[Task], workers: int, on_done: OnDone) -> None:
    """Runs ``tasks`` in this process (``workers`` ≤ 1) or a process pool of ``workers``.

    ``on_done(index, chunk)`` is called in this process as each task finishes.
    """
    if workers <= 1:
        for task in tasks:
            on_done(*run_task(task))
        return
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    # fork: the workers inherit the imported pydrake (≈1.2 s per process otherwise). A pool
    # takes TASKS_PER_WORKER tasks a worker, then a fresh one forked from this process takes
    # the next, while the retired one finishes what it holds: at most ``workers`` tasks run.
    context = multiprocessing.get_context("fork")
    queue = list(reversed(tasks))
    pending: set = set()
    pools: list = []  # the newest takes new tasks; the others finish theirs
    given = 0
    try:
        while queue or pending:
            while queue and len(pending) < workers:
                if not pools or given >= workers * TASKS_PER_WORKER:
                    if pools:
                        pools[-1].shutdown(wait=False)
                    pools.append(
                        ProcessPoolExecutor(
                            max_workers=workers, mp_context=context, initializer=_die_with_parent
                        )
                    )
                    given = 0
                pending.add(pools[-1].submit(run_task, queue.pop()))
                given += 1
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for future in done:
                on_done(*future.result())
    finally:
        for pool in pools:
            pool.shutdown(wait=True, cancel_futures=True)


def connect(scheduler: str) -> Any:
    """A ``dask.distributed.Client`` of ``scheduler``; :class:`MonteCarloError` if impossible."""
    try:
        from dask.distributed import Client
    except ImportError as e:
        raise MonteCarloError(
            "--scheduler: dask.distributed is not installed (pip install 'drake_uuv[montecarlo]')"
        ) from e
    try:
        return Client(scheduler)
    except (OSError, ValueError, TimeoutError) as e:
        raise MonteCarloError(f"--scheduler: cannot connect to {scheduler!r}: {e}") from e


def execute_dask(tasks: list[Task], client: Any, on_done: OnDone) -> None:
    """Runs ``tasks`` on a Dask cluster; ``on_done`` as for :func:`execute_local`."""
    from dask.distributed import as_completed

    futures = [client.submit(run_task, task, pure=False) for task in tasks]
    try:
        for future in as_completed(futures):
            on_done(*future.result())
    finally:
        for future in futures:
            future.cancel()


def _progress_bar(total: int, enabled: bool) -> Any:
    """A tqdm bar of runs, without tqdm's monitor thread (the local pool forks after this)."""
    from tqdm import tqdm

    class _Bar(tqdm):
        monitor_interval = 0

    return _Bar(total=total, unit="run", disable=not enabled, desc="runs", dynamic_ncols=True)


def run_studies(
    studies: Sequence[Study],
    workers: int | None = None,
    scheduler: str | None = None,
    resume: bool = False,
    chunk_size: int | None = None,
    progress: bool = True,
    figures: bool = True,
) -> list[StudyResult]:
    """Runs every study's missing seeds on one pool (or cluster) and writes their outputs.

    ``workers``: local processes (default: every core; 1 runs in this process).
    ``scheduler``: a ``dask.distributed`` scheduler address; overrides ``workers``.
    ``resume``: keep the runs already in each ``out_dir`` and compute only the missing ones.
    ``chunk_size``: seeds per task (default: small enough to balance the load and to lose
    little on interruption, large enough to keep task overhead negligible).
    ``figures``: also draw each study's ``figures/error_bands.{png,svg}``.
    Raises :class:`MonteCarloError` on a bad request (naming the option and the value).
    """
    if chunk_size is not None and chunk_size < 1:
        raise MonteCarloError(f"--chunk-size: must be ≥ 1, got {chunk_size}")
    for study in studies:
        if study.runs < 1:
            raise MonteCarloError(f"--runs: must be ≥ 1, got {study.runs}")
        prepare(study, resume)
    missing = [missing_seeds(study, resume) for study in studies]
    total = sum(len(m) for m in missing)

    client = None
    if scheduler is not None:
        client = connect(scheduler)
        slots = max(1, sum(client.nthreads().values()))
    else:
        workers = default_workers() if workers is None else workers
        if workers < 1:
            raise MonteCarloError(f"--workers: must be ≥ 1, got {workers}")
        slots = workers
    size = chunk_size or automatic_chunk_size(total, slots)
    tasks = [
        (index, study.scenario, chunk)
        for index, study in enumerate(studies)
        for chunk in chunks(missing[index], size)
    ]

    bar = _progress_bar(total, progress)

    def on_done(index: int, chunk: dict[str, Any]) -> None:
        write_part(studies[index].out_dir, chunk)
        bar.update(len(chunk["seeds"]))

    try:
        if client is not None:
            execute_dask(tasks, client, on_done)
        else:
            execute_local(tasks, slots, on_done)
    finally:
        bar.close()
        if client is not None:
            client.close()
    return [
        finish_study(study, computed=len(missing[i]), figures=figures)
        for i, study in enumerate(studies)
    ]


def run_study(study: Study, **options: Any) -> StudyResult:
    """One study; ``options`` as for :func:`run_studies`."""
    return run_studies([study], **options)[0]


def finish_study(study: Study, computed: int = 0, figures: bool = True) -> StudyResult:
    """Reads the study's runs from disk; writes ``runs.csv``, ``summary.json``, the figure."""
    seeds, names, metrics, norms = load_runs(study)
    information = load_information(study)
    summary = summarize(names, metrics, study.scenario, seeds, information)
    out_dir = Path(study.out_dir)
    write_outputs(out_dir, seeds, names, metrics, summary)
    if figures:
        _band_figure(study, norms, information, len(seeds))
    return StudyResult(study, seeds, names, metrics, norms, summary, computed)


def _band_figure(
    study: Study, norms: np.ndarray, information: np.ndarray | None, runs: int
) -> None:
    # Imported here: matplotlib is loaded only when a figure is drawn.
    from drake_uuv.analysis.figures import bound_curves
    from drake_uuv.analysis.registry import write_study_figures

    bounds = None
    if information is not None:
        bounds = bound_curves(monte_carlo_bound(information, runs, study.scenario))
    write_study_figures(
        dict(zip(NORMS, np.moveaxis(norms, 1, 0), strict=True)),
        study.scenario,
        Path(study.out_dir),
        bounds=bounds,
    )
