"""Running seeds of a scenario in one process: metrics, error norms, information sums.

A worker (a local process, a thread of a Dask worker, or the caller itself) runs its seeds as
batches: one closed-loop diagram stepping a batch of runs at once, built once per thread,
scenario and batch size (:func:`cached_simulation`). Each run draws its noise from its own
seed, so a run's numbers do not depend on the batch, the chunking or the worker. A batch is as
large as the chunk, up to :func:`max_batch_size` (its log, which the metrics read, is held in
memory). For each run it returns only its metrics and four per-step error norms (:data:`NORMS`,
float32), never the log, so a chunk of runs is small enough to send back and write at once.

The Monte Carlo PCRLB needs the measurement information ``M(k)`` averaged over runs. A chunk
returns the *sum* over its runs of the position block (steps × 3 × 3) in fixed point
(int64 in units of ``2^-e``, :func:`information_exponent`): integer sums are exact and
associative, so the total, and the bound, are the same whatever the chunking, the order or
the number of workers.
"""

import json
import math
import threading
from collections.abc import Sequence
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

from drake_uuv.diagnostics import batch_warnings
from drake_uuv.estimators.factory import make_estimator
from drake_uuv.estimators.particle_cloud import bytes_per_run as cloud_bytes_per_run
from drake_uuv.metrics import errors, metric_signals, run_information
from drake_uuv.scenario import Scenario, scenario_as_dict
from drake_uuv.scenario.estimators import RawRangeOptions
from drake_uuv.signals import SIGNAL_BY_NAME
from drake_uuv.simulation import ClosedLoopSimulation

# Rows of the per-step error-norm array a worker returns for each run.
NORMS = ("position", "velocity", "tracking", "nees")
# Simulations a thread keeps built; a compare batch cycles through up to ~30 scenarios.
_CACHE_SIZE = 32
# Metrics of drake_uuv.metrics.run_metrics left out of a study: not functions of the seed.
_DROPPED_METRICS = ("seed", "steps", "wall_time_s")

_local = threading.local()


def scenario_key(scenario: Scenario) -> str:
    """A string equal for equal scenarios (the simulation cache's key)."""
    return json.dumps(scenario_as_dict(scenario), sort_keys=True)


def cached_simulation(scenario: Scenario, batch_size: int = 1) -> ClosedLoopSimulation:
    """The closed-loop simulation of ``scenario`` stepping ``batch_size`` runs, built once per
    thread of each process.

    Per thread because a Drake ``Simulator`` and its context are not safe to share between
    threads (a Dask worker runs several tasks at once in threads).
    """
    cache = getattr(_local, "simulations", None)
    if cache is None:
        cache = _local.simulations = {}
    key = (scenario_key(scenario), batch_size)
    if key not in cache:
        if len(cache) >= _CACHE_SIZE:
            cache.clear()
        cache[key] = ClosedLoopSimulation(scenario, log="metrics", batch_size=batch_size)
    return cache[key]


#: The memory a batch's log may take [bytes]: the logged signals of every run and step.
BATCH_LOG_BYTES = 256 * 2**20
#: The most runs in one batch: beyond a few hundred, numpy's cost per run no longer falls.
MAX_BATCH = 500


def max_batch_size(scenario: Scenario) -> int:
    """The most runs one batch of ``scenario`` steps: its log (the signals the metrics read,
    every step) within :data:`BATCH_LOG_BYTES`, and a system's own estimate of its memory a
    run (a particle filter's ``bytes_per_run``) within the same budget."""
    # A signal a system declares of its own (a vehicle's thrusts) is counted as 16 numbers.
    logged = sum(
        SIGNAL_BY_NAME[name].size if name in SIGNAL_BY_NAME else 16
        for name in metric_signals(scenario)
    )
    per_run = 8 * logged * scenario.steps + _state_bytes_per_run(scenario)
    return max(1, min(MAX_BATCH, BATCH_LOG_BYTES // max(per_run, 1)))


def information_exponent(scenario: Scenario) -> int:
    """Binary exponent ``e`` of the fixed-point information sums: ``round(M · 2^e)`` as int64.

    Every entry of ``M(k)`` is at most ``f (1/η1 + 1/η2)`` in magnitude; ``e`` leaves room for
    2^20 runs below 2^63, so one unit is ≈ 2^-42 of the largest entry (relative rounding far
    below anything the bound is used for).
    """
    eta = np.asarray(scenario.sonar.noise_variances, dtype=float)
    largest = scenario.sonar.samples_per_step * float(np.sum(1.0 / eta))
    return 62 - 20 - math.ceil(math.log2(largest))


def run_seeds(scenario: Scenario, seeds: Sequence[int]) -> dict[str, Any]:
    """Runs ``scenario`` once per seed; returns metrics and error norms, not logs.

    Returns ``{"seeds": int64 (n,), "metric_names": [...], "metrics": float64 (n × m),
    "norms": float32 (n × 4 × steps), "information_sum": int64 (steps × 3 × 3) or None}``.
    The metrics are those of :func:`drake_uuv.metrics.run_metrics` plus ``max_tracking_error``
    (steady state), ``final_tracking_error`` and ``failed`` (1 for a run the estimator-health
    monitor stopped, whose other metrics and norms are then NaN); ``wall_time_s`` is left out
    so results are reproducible. ``information_sum`` is Σ over the runs of the position block
    of :func:`drake_uuv.metrics.run_information` in units of ``2^-e``
    (:func:`information_exponent`); None if any entry is not finite or a run failed.
    """
    # One BLAS thread per worker: a run's matrices are small (6×6, at most 6×N particles),
    # and two workers each spawning a thread per core slowed a particle filter 30-fold.
    blas = threadpool_limits(limits=1, user_api="blas")
    seeds = [int(seed) for seed in seeds]
    size = max_batch_size(scenario)
    parts = []
    with blas, np.errstate(all="ignore"):
        for first in range(0, len(seeds), size):
            parts.append(_run_batch(scenario, seeds[first : first + size]))
    rows = [row for part in parts for row in part[0]]
    names = canonical_metric_names([list(row) for row in rows])
    information = None
    if all(part[2] is not None for part in parts):
        information = sum(part[2] for part in parts)
    with np.errstate(over="ignore"):  # a diverged run's norms beyond float32 become inf
        norms = np.concatenate([part[1] for part in parts]).astype(np.float32)
    return {
        "seeds": np.asarray(seeds, dtype=np.int64),
        "metric_names": names,
        "metrics": np.asarray([[row.get(n, math.nan) for n in names] for row in rows]),
        "norms": norms,
        "information_sum": information,
    }


def _run_batch(
    scenario: Scenario, seeds: list[int]
) -> tuple[list[dict[str, float]], np.ndarray, np.ndarray | None]:
    """The seeds' metric rows, error norms (B × :data:`NORMS` × steps) and information sum
    (None if a run failed or its information is not finite).

    The seeds run as one batch; should a system raise inside it (not the monitor's finding),
    they run again one by one, each as it would alone, so that the error is the failing
    run's own, raised naming its seed."""
    try:
        batch = cached_simulation(scenario, len(seeds)).run_batch(seeds)
    except Exception:
        batch = None
    if batch is None:
        alone = [_run_alone(scenario, seed) for seed in seeds]
        parts = [_summary(*result, scenario) for result in alone]
        rows = [row for part in parts for row in part[0]]
        information = None
        if all(part[2] is not None for part in parts):
            information = sum(part[2] for part in parts)
        return rows, np.concatenate([part[1] for part in parts]), information
    return _summary(batch.log, batch.metrics, batch.failures, scenario)


def _run_alone(
    scenario: Scenario, seed: int
) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray], list[str | None]]:
    """Seed ``seed`` alone, as a batch of one (its log, metrics and failure)."""
    try:
        batch = cached_simulation(scenario, 1).run_batch([seed])
    except Exception as e:
        raise RuntimeError(f"run with seed {seed} failed: {e}") from e
    return batch.log, batch.metrics, batch.failures


def _summary(
    log: dict[str, np.ndarray],
    metrics: dict[str, np.ndarray],
    failures: list[str | None],
    scenario: Scenario,
) -> tuple[list[dict[str, float]], np.ndarray, np.ndarray | None]:
    """What a study keeps of a batch (see :func:`_run_batch`), computed for all its runs at
    once."""
    failed = np.array([f is not None for f in failures], dtype=bool)
    e = errors(log, scenario)
    tracking = np.linalg.norm(e["tracking"], axis=-1)
    norms = np.stack(
        [
            np.linalg.norm(e["position"], axis=-1),
            np.linalg.norm(e["velocity"], axis=-1),
            tracking,
            e["nees"],
        ],
        axis=1,
    )
    norms[failed] = np.nan
    warnings = batch_warnings(log, metrics, scenario)
    start = scenario.steady_state_start
    rows = []
    for i in range(len(failures)):
        if failed[i]:  # a broken estimator: a failed (and diverged) run
            rows.append({"failed": 1.0})
            continue
        row = {k: float(v[i]) for k, v in metrics.items() if k not in _DROPPED_METRICS}
        row["max_tracking_error"] = float(np.max(tracking[i, start:]))
        row["final_tracking_error"] = float(tracking[i, -1])
        row["failed"] = 0.0
        row["warnings"] = float(len(warnings[i]))
        rows.append(row)
    information = None
    if not failed.any():
        M = run_information(log, scenario)[..., :3, :3]
        if np.all(np.isfinite(M)):
            exponent = information_exponent(scenario)
            information = np.rint(np.ldexp(M, exponent)).astype(np.int64).sum(axis=0)
    return rows, norms, information


def _state_bytes_per_run(scenario: Scenario) -> int:
    """What a run's systems hold beyond the log: a particle cloud's state and weights
    (:func:`~drake_uuv.estimators.particle_cloud.bytes_per_run`, with late ranges each window
    step's draws) for an estimator that may carry particles (the particle filter, or the
    bridge of the Gaussian raw-range filters); nothing worth counting otherwise."""
    if not isinstance(scenario.estimator, RawRangeOptions):
        return 0
    estimator = make_estimator(scenario)  # one run: what its cloud declares
    if getattr(estimator, "cloud", None) is None:
        return 0
    window = estimator.window  # late ranges: each window step's draws per particle too
    return cloud_bytes_per_run(
        scenario.estimator.particle_count,
        0 if window is None else window.schedule.window,
        navigation_noise=window is not None and estimator.error_model.active,
    )


def canonical_metric_names(lists: Sequence[list[str]]) -> list[str]:
    """The canonical metric names: a completed run's (all have the same), whatever the order.

    A failed run has only ``failed``; a chunk or study of failed runs only has that name.
    """
    longest = max(lists, key=len, default=["failed"])
    return longest + sorted({n for names in lists for n in names} - set(longest))


def run_task(task: tuple[int, Scenario, list[int]]) -> tuple[int, dict[str, Any]]:
    """``(index, scenario, seeds)`` → ``(index, run_seeds(scenario, seeds))``: one pool task.

    A module-level function so that process pools and Dask can pickle it by name.
    """
    index, scenario, seeds = task
    return index, run_seeds(scenario, seeds)
