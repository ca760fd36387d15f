"""Running seeds of a scenario in one process: metrics, error norms, information sums.

A worker (a local process, a thread of a Dask worker, or the caller itself) builds the
closed-loop diagram once per thread and scenario (:func:`cached_simulation`) and returns for
each run only its metrics and four per-step error norms (:data:`NORMS`, float32), never the
log, so a chunk of runs is small enough to send back and write at once.

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

from drake_uuv.metrics import errors, run_information
from drake_uuv.monitor import SimulationFailure
from drake_uuv.scenario import Scenario, scenario_as_dict
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


def cached_simulation(scenario: Scenario) -> ClosedLoopSimulation:
    """The closed-loop simulation of ``scenario``, built once per thread of each process.

    Per thread because a Drake ``Simulator`` and its context are not safe to share between
    threads (a Dask worker runs several tasks at once in threads).
    """
    cache = getattr(_local, "simulations", None)
    if cache is None:
        cache = _local.simulations = {}
    key = scenario_key(scenario)
    if key not in cache:
        if len(cache) >= _CACHE_SIZE:
            cache.clear()
        cache[key] = ClosedLoopSimulation(scenario, log="metrics")
    return cache[key]


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
    simulation = cached_simulation(scenario)
    # One BLAS thread per worker: a run's matrices are small (6×6, at most 6×N particles),
    # and two workers each spawning a thread per core slowed a particle filter 30-fold.
    blas = threadpool_limits(limits=1, user_api="blas")
    start = scenario.steady_state_start
    rows: list[dict[str, float]] = []
    norms = []
    exponent = information_exponent(scenario)
    information: np.ndarray | None = np.zeros((scenario.steps, 3, 3), dtype=np.int64)
    with blas, np.errstate(all="ignore"):
        for seed in seeds:
            try:
                result = simulation.run(int(seed))
            except SimulationFailure:  # a broken estimator: a failed (and diverged) run
                rows.append({"failed": 1.0})
                norms.append(np.full((len(NORMS), scenario.steps), np.nan, dtype=np.float32))
                information = None
                continue
            except Exception as e:
                raise RuntimeError(f"run with seed {seed} failed: {e}") from e
            e = errors(result.log, result.scenario)
            tracking = np.linalg.norm(e["tracking"], axis=1)
            metrics = {
                key: float(value)
                for key, value in result.metrics.items()
                if key not in _DROPPED_METRICS
            }
            metrics["max_tracking_error"] = float(np.max(tracking[start:]))
            metrics["final_tracking_error"] = float(tracking[-1])
            metrics["failed"] = 0.0
            metrics["warnings"] = float(len(result.warnings))
            rows.append(metrics)
            norms.append(
                np.stack(
                    [
                        np.linalg.norm(e["position"], axis=1),
                        np.linalg.norm(e["velocity"], axis=1),
                        tracking,
                        e["nees"],
                    ]
                ).astype(np.float32)
            )
            M = run_information(result.log, result.scenario)[:, :3, :3]
            if information is not None and np.all(np.isfinite(M)):
                information += np.rint(np.ldexp(M, exponent)).astype(np.int64)
            else:
                information = None
    names = canonical_metric_names([list(row) for row in rows])
    return {
        "seeds": np.asarray(seeds, dtype=np.int64),
        "metric_names": names,
        "metrics": np.asarray([[row.get(n, math.nan) for n in names] for row in rows]),
        "norms": np.asarray(norms, dtype=np.float32),
        "information_sum": information,
    }


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
