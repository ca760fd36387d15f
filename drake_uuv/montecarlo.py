"""Monte Carlo studies: many seeded runs of a scenario, in local processes or on Dask.

Run ``i`` of a study uses seed ``scenario.random_seed + i``. A run's numbers depend only on its
scenario and seed, and the summary is computed from the runs in seed order, so a study gives
bit-identical ``runs.csv`` and ``summary.json`` whatever the number of workers, the chunking or
the backend (local processes, or a ``dask.distributed`` cluster via ``scheduler``).

Work is split into chunks of seeds. A worker builds the closed-loop diagram once per process
(or thread) and scenario (:func:`run_seeds` caches it) and returns for each run only its
metrics and four per-step error norms (position, velocity, tracking, NEES; float32), never
the log. The client writes each finished chunk at once, atomically, to
``DIR/runs/part-<first seed>-<count>.npz``: an interrupted study keeps every finished chunk,
and ``resume=True`` computes only the seeds no part holds. The study's scenario is kept in
``DIR/study.json``, and a resume against a different scenario is refused.

Outputs of a study folder ``DIR``:

* ``runs.csv``: one row per run, ``seed`` then every metric of :func:`run_seeds`;
* ``summary.json``: see :func:`summarize`;
* ``figures/bands.{png,svg}``: median and 5–95 % of the errors against k, mean NEES with
  its χ² band, and the RMS error over runs beside the Monte Carlo PCRLB.

The Monte Carlo PCRLB averages each run's measurement information ``M(k)`` over runs
(:func:`drake_uuv.models.pcrlb.pcrlb_monte_carlo`). A chunk returns the *sum* over its
runs of ``M(k)`` (position block, N×3×3), not per-run arrays, in fixed point (integers,
:func:`information_exponent`): integer sums are exact, so the total, and the bound, are the
same whatever the chunking, the order or the number of workers.
"""

import argparse
import csv
import dataclasses
import io
import json
import math
import os
import signal
import threading
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from drake_uuv.analysis.stats import bootstrap_interval, wilson_interval
from drake_uuv.io import write_atomic, write_json_atomic, write_text_atomic
from drake_uuv.scenario import Scenario

# A run has diverged when its final position error exceeds this [m] (or is not finite).
DIVERGENCE_THRESHOLD = 10.0
# The tracking error of a run stays bounded when its steady-state maximum is below this [m].
BOUNDED_TRACKING_THRESHOLD = 10.0
# Rows of the per-step error-norm array a worker returns for each run.
NORMS = ("position", "velocity", "tracking", "nees")
BOOTSTRAP_RESAMPLES = 2000
BOOTSTRAP_SEED = 0
INTERVAL_METHOD = (
    "95 % intervals: RMSEs and nees_mean by percentile bootstrap over runs "
    f"({BOOTSTRAP_RESAMPLES} resamples, generator seed {BOOTSTRAP_SEED}; the RMSE of each "
    "resample combines the per-run mean-square errors); fractions by the Wilson score interval"
)
BOUND_METHOD = (
    "pcrlb: posterior Cramér–Rao bound of the raw two-range measurement (all f samples), "
    "measurement information averaged over the runs' true trajectories, one recursion from "
    "P(0|−1) = estimator.initial_covariance (the proven bound); pcrlb_per_run: root of the "
    "mean over runs of each run's bound along its own trajectory (what a run-by-run "
    "efficient estimator attains; above pcrlb, see estimators/pcrlb.py); kf_riccati: the "
    "paper's KF's Riccati covariance with Γ on the true ranges, likewise; each √(mean over "
    "k ≥ steady_state_start of the trace of the position or velocity block)"
)
_SCHEMA = 1
# Metrics the summary reads (every completed run has them).
NEEDED_METRICS = (
    "position_rmse",
    "velocity_rmse",
    "tracking_rmse",
    "nees_mean",
    "final_position_error",
    "max_tracking_error",
    "relative_speed_mean",
    "relative_speed_peak",
    "acceleration_mean",
    "acceleration_peak",
)
_PR_SET_PDEATHSIG = 1  # <sys/prctl.h>
_STUDY_FILE = "study.json"
_PARTS = "runs"


class MonteCarloError(ValueError):
    """A bad study request (e.g. resuming a folder that holds another scenario's runs)."""


@dataclass(frozen=True)
class Study:
    """``runs`` seeded runs of ``scenario``, written to ``out_dir``."""

    name: str
    scenario: Scenario
    runs: int
    out_dir: Path


@dataclass
class StudyResult:
    """A finished study: per-run metrics in seed order, error norms, and the summary."""

    study: Study
    seeds: np.ndarray
    metric_names: list[str]
    metrics: np.ndarray  # runs × metrics, float64
    norms: np.ndarray  # runs × len(NORMS) × steps, float32
    summary: dict[str, Any]
    computed: int  # runs computed now (the others were kept on disk)

    def column(self, name: str) -> np.ndarray:
        """One metric over all runs, in seed order."""
        return self.metrics[:, self.metric_names.index(name)]


# ------------------------------------------------------------------------------ workers

_local = threading.local()


def _scenario_key(scenario: Scenario) -> str:
    return json.dumps(dataclasses.asdict(scenario), sort_keys=True)


def _simulation(scenario: Scenario):
    """The closed-loop simulation of ``scenario``, built once per thread of each process."""
    from drake_uuv.simulation import ClosedLoopSimulation

    cache = getattr(_local, "simulations", None)
    if cache is None:
        cache = _local.simulations = {}
    key = _scenario_key(scenario)
    if key not in cache:
        if len(cache) >= 32:
            cache.clear()
        cache[key] = ClosedLoopSimulation(scenario)
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
    monitor stopped, whose other metrics and norms are then NaN; see :func:`summarize`);
    ``wall_time_s`` is left out so results are reproducible. ``information_sum`` is Σ over
    the runs of the position block of :func:`drake_uuv.metrics.run_information` in units of
    ``2^-e`` (:func:`information_exponent`); None if any entry is not finite or a run failed.
    """
    from drake_uuv.metrics import errors, run_information
    from drake_uuv.monitor import SimulationFailure

    simulation = _simulation(scenario)
    start = scenario.steady_state_start
    rows: list[dict[str, float]] = []
    norms = []
    exponent = information_exponent(scenario)
    information: np.ndarray | None = np.zeros((scenario.steps, 3, 3), dtype=np.int64)
    with np.errstate(all="ignore"):
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
                if key not in ("seed", "steps", "wall_time_s")
            }
            metrics["max_tracking_error"] = float(np.max(tracking[start:]))
            metrics["final_tracking_error"] = float(tracking[-1])
            metrics["failed"] = 0.0
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
    names = _metric_names([list(row) for row in rows])
    return {
        "seeds": np.asarray(seeds, dtype=np.int64),
        "metric_names": names,
        "metrics": np.asarray([[row.get(n, math.nan) for n in names] for row in rows]),
        "norms": np.asarray(norms, dtype=np.float32),
        "information_sum": information,
    }


def _metric_names(lists: Sequence[list[str]]) -> list[str]:
    """The canonical metric names: a completed run's (all have the same), whatever the order.

    A failed run has only ``failed``; a chunk or study of failed runs only has that name.
    """
    longest = max(lists, key=len, default=["failed"])
    return longest + sorted({n for names in lists for n in names} - set(longest))


def _run_task(task: tuple[int, Scenario, list[int]]) -> tuple[int, dict[str, Any]]:
    index, scenario, seeds = task
    return index, run_seeds(scenario, seeds)


# ------------------------------------------------------------------------- parts on disk


def _parts_dir(out_dir: Path) -> Path:
    return Path(out_dir) / _PARTS


def _write_part(out_dir: Path, chunk: dict[str, Any]) -> Path:
    seeds = chunk["seeds"]
    path = _parts_dir(out_dir) / f"part-{int(seeds[0]):010d}-{len(seeds)}.npz"
    arrays = {
        "seeds": seeds,
        "metric_names": np.asarray(chunk["metric_names"]),
        "metrics": chunk["metrics"],
        "norms": chunk["norms"],
    }
    if chunk.get("information_sum") is not None:
        arrays["information_sum"] = chunk["information_sum"]
    return write_atomic(path, lambda f: np.savez(f, **arrays))


def _read_parts(out_dir: Path) -> Iterator[dict[str, Any]]:
    for path in sorted(_parts_dir(out_dir).glob("part-*.npz")):
        with np.load(path) as data:
            yield {
                "seeds": data["seeds"],
                "metric_names": [str(n) for n in data["metric_names"]],
                "metrics": data["metrics"],
                "norms": data["norms"],
                "information_sum": data["information_sum"]
                if "information_sum" in data.files
                else None,
            }


def completed_seeds(out_dir: Path) -> set[int]:
    """Seeds whose runs are on disk in ``out_dir/runs/``."""
    done: set[int] = set()
    for path in _parts_dir(out_dir).glob("part-*.npz"):
        with np.load(path) as data:
            done.update(int(s) for s in data["seeds"])
    return done


def _first_difference(a: Any, b: Any, prefix: str = "") -> str | None:
    if isinstance(a, dict) and isinstance(b, dict):
        for key in sorted(set(a) | set(b)):
            found = _first_difference(a.get(key), b.get(key), f"{prefix}{key}.")
            if found:
                return found
        return None
    return None if a == b else f"{prefix.rstrip('.')} ({a!r} on disk, {b!r} now)"


def _prepare(study: Study, resume: bool) -> None:
    """Creates the folder; on resume checks the scenario, otherwise clears old runs."""
    out_dir = Path(study.out_dir)
    parts = _parts_dir(out_dir)
    parts.mkdir(parents=True, exist_ok=True)
    for leftover in parts.glob(".part-*.tmp"):  # an interrupted atomic write
        leftover.unlink(missing_ok=True)
    scenario = json.loads(json.dumps(dataclasses.asdict(study.scenario)))
    marker = out_dir / _STUDY_FILE
    if resume and marker.exists():
        stored = json.loads(marker.read_text())
        difference = _first_difference(stored.get("scenario"), scenario)
        if difference:
            raise MonteCarloError(
                f"--resume: {out_dir} holds runs of another scenario: {difference}"
            )
    elif resume and any(parts.glob("part-*.npz")):
        raise MonteCarloError(f"--resume: {out_dir} has runs but no {_STUDY_FILE}")
    if not resume:
        for old in parts.glob("part-*.npz"):
            old.unlink()
    write_json_atomic(marker, {"schema": _SCHEMA, "name": study.name, "scenario": scenario})


def _chunks(seeds: list[int], size: int) -> list[list[int]]:
    return [seeds[i : i + size] for i in range(0, len(seeds), size)]


# ---------------------------------------------------------------------------- executing


def default_workers() -> int:
    """Every core this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


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


def _execute_local(
    tasks: list[tuple[int, Scenario, list[int]]],
    workers: int,
    on_done: Callable[[int, dict[str, Any]], None],
) -> None:
    if workers <= 1:
        for task in tasks:
            on_done(*_run_task(task))
        return
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    # fork: the workers inherit the imported pydrake (≈1.2 s per process otherwise).
    context = multiprocessing.get_context("fork")
    pool = ProcessPoolExecutor(
        max_workers=workers, mp_context=context, initializer=_die_with_parent
    )
    try:
        pending = {pool.submit(_run_task, task) for task in tasks}
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for future in done:
                on_done(*future.result())
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _connect(scheduler: str):
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


def _execute_dask(
    tasks: list[tuple[int, Scenario, list[int]]],
    client,
    on_done: Callable[[int, dict[str, Any]], None],
) -> None:
    from dask.distributed import as_completed

    futures = [client.submit(_run_task, task, pure=False) for task in tasks]
    try:
        for future in as_completed(futures):
            on_done(*future.result())
    finally:
        for future in futures:
            future.cancel()


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
    """
    if chunk_size is not None and chunk_size < 1:
        raise MonteCarloError(f"--chunk-size: must be ≥ 1, got {chunk_size}")
    for study in studies:
        if study.runs < 1:
            raise MonteCarloError(f"--runs: must be ≥ 1, got {study.runs}")
        _prepare(study, resume)
    missing: list[list[int]] = []
    for study in studies:
        done = completed_seeds(study.out_dir) if resume else set()
        first = study.scenario.random_seed
        missing.append([first + i for i in range(study.runs) if first + i not in done])
    total = sum(len(m) for m in missing)

    client = None
    if scheduler is not None:
        client = _connect(scheduler)
        slots = max(1, sum(client.nthreads().values()))
    else:
        workers = default_workers() if workers is None else workers
        if workers < 1:
            raise MonteCarloError(f"--workers: must be ≥ 1, got {workers}")
        slots = workers
    size = chunk_size or max(1, min(25, math.ceil(total / (4 * slots)) if total else 1))
    tasks = [
        (index, study.scenario, chunk)
        for index, study in enumerate(studies)
        for chunk in _chunks(missing[index], size)
    ]

    from tqdm import tqdm

    class _Bar(tqdm):
        monitor_interval = 0  # no monitor thread: the local pool forks after this

    bar = _Bar(total=total, unit="run", disable=not progress, desc="runs", dynamic_ncols=True)

    def on_done(index: int, chunk: dict[str, Any]) -> None:
        _write_part(studies[index].out_dir, chunk)
        bar.update(len(chunk["seeds"]))

    try:
        if client is not None:
            _execute_dask(tasks, client, on_done)
        else:
            _execute_local(tasks, slots, on_done)
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


# ---------------------------------------------------------------------------- summaries


def load_runs(study: Study) -> tuple[np.ndarray, list[str], np.ndarray, np.ndarray]:
    """Seeds, metric names, metrics and norms of the study's runs, in seed order."""
    wanted = {study.scenario.random_seed + i for i in range(study.runs)}
    by_seed: dict[int, tuple[dict[str, float], np.ndarray]] = {}
    name_lists: list[list[str]] = []
    for part in _read_parts(study.out_dir):
        name_lists.append(part["metric_names"])
        for row, seed in enumerate(part["seeds"]):
            if int(seed) in wanted:
                values = dict(zip(part["metric_names"], part["metrics"][row], strict=True))
                by_seed[int(seed)] = (values, part["norms"][row])
    if len(by_seed) != len(wanted):
        raise MonteCarloError(
            f"{study.out_dir}: {len(wanted) - len(by_seed)} of {len(wanted)} runs are missing"
        )
    seeds = np.array(sorted(by_seed), dtype=np.int64)
    names = _metric_names(name_lists)
    metrics = np.array([[by_seed[int(s)][0].get(n, math.nan) for n in names] for s in seeds])
    norms = np.stack([by_seed[int(s)][1] for s in seeds])
    return seeds, names, metrics, norms


def load_information(study: Study) -> np.ndarray | None:
    """Σ over the study's runs of the measurement information ``M(k)`` (steps × 6 × 6).

    None when it cannot be had exactly: a part without it (written before it existed, or
    with a non-finite run) or a part that also holds runs outside the study (after a
    ``--resume`` with fewer runs).
    """
    wanted = {study.scenario.random_seed + i for i in range(study.runs)}
    total: np.ndarray | None = None
    seen: set[int] = set()
    for part in _read_parts(study.out_dir):
        seeds = {int(seed) for seed in part["seeds"]}
        if not seeds & wanted:
            continue
        if part["information_sum"] is None or not seeds <= wanted or seeds & seen:
            return None
        seen |= seeds
        total = part["information_sum"] if total is None else total + part["information_sum"]
    if total is None or seen != wanted:
        return None
    information = np.zeros((total.shape[0], 6, 6))
    information[:, :3, :3] = np.ldexp(total.astype(float), -information_exponent(study.scenario))
    return information


def monte_carlo_bound(information_sum: np.ndarray, runs: int, scenario: Scenario) -> np.ndarray:
    """The Monte Carlo PCRLB (steps × 6 × 6) from :func:`load_information`'s sum: the
    recursion once on the information averaged over runs, prior ``estimator.initial_covariance``.
    """
    from drake_uuv.models.pcrlb import pcrlb_recursion

    return pcrlb_recursion(
        information_sum / runs,
        np.asarray(scenario.estimator.initial_covariance, dtype=float),
        np.asarray(scenario.target.acceleration_covariance, dtype=float),
        scenario.time_step,
    )


def bound_summary(
    summary: dict[str, Any],
    column: dict[str, np.ndarray],
    scenario: Scenario,
    information_sum: np.ndarray | None,
) -> dict[str, Any]:
    """The bounds of a study and the RMSEs' ratios to them (see :func:`summarize`)."""
    from drake_uuv.models.pcrlb import bound_rmse

    out: dict[str, Any] = {}
    bounds: dict[str, tuple[float, float]] = {}
    if information_sum is not None:
        covs = monte_carlo_bound(information_sum, summary["runs"], scenario)
        bounds["pcrlb"] = bound_rmse(covs, scenario.steady_state_start)
    for name, key in (("pcrlb_per_run", "pcrlb"), ("kf_riccati", "kf_riccati")):
        if f"{key}_position_rmse" in column:
            position, velocity = (
                math.sqrt(float(np.mean(column[f"{key}_{part}_rmse"] ** 2)))
                for part in ("position", "velocity")
            )
            bounds[name] = (position, velocity)
    for name, (position, velocity) in bounds.items():
        out[f"{name}_position_rmse"] = _finite(position)
        out[f"{name}_velocity_rmse"] = _finite(velocity)
    for name, suffix in (("pcrlb", "pcrlb"), ("pcrlb_per_run", "per_run_pcrlb")):
        if name not in bounds:
            continue
        for index, part in enumerate(("position", "velocity")):
            bound = bounds[name][index]
            rmse = summary.get(f"{part}_rmse")
            key = f"{part}_rmse_over_{suffix}"
            out[key] = None if rmse is None else _finite(rmse / bound)
            out[f"{key}_ci95"] = [
                None if v is None else _finite(v / bound) for v in summary[f"{part}_rmse_ci95"]
            ]
    if bounds:
        out["bound_method"] = BOUND_METHOD
    return out


def _finite(value: float) -> float | None:
    """JSON has no inf/NaN: non-finite values become null."""
    return float(value) if math.isfinite(value) else None


def summarize(
    metric_names: list[str],
    metrics: np.ndarray,
    scenario: Scenario,
    seeds: np.ndarray,
    information_sum: np.ndarray | None = None,
) -> dict[str, Any]:
    """The study summary.

    ``position_rmse``, ``velocity_rmse``, ``tracking_rmse``: √(mean over runs and steady-state
    steps of the squared error norm), i.e. the per-run mean-square errors averaged, then the
    root. ``nees_mean``: mean over runs and steady-state steps. These, the speeds and the bounds
    are taken over the ``completed_runs``; ``failed_fraction`` counts the runs the
    estimator-health monitor stopped. ``diverged_fraction``: runs whose final position error
    exceeds :data:`DIVERGENCE_THRESHOLD` or is not finite (so failed runs count as diverged).
    ``tracking_bounded_fraction``: runs whose steady-state tracking error stays below
    :data:`BOUNDED_TRACKING_THRESHOLD`. Each has a 95 % interval (``*_ci95``, see
    :data:`INTERVAL_METHOD`). Non-finite numbers are written as null.

    Bounds (:data:`BOUND_METHOD`), each as ``*_position_rmse`` and ``*_velocity_rmse``:
    ``pcrlb`` (the Monte Carlo PCRLB, from ``information_sum``, Σ over runs of ``M(k)``),
    ``pcrlb_per_run`` (√ of the mean over runs of each run's squared bound) and
    ``kf_riccati`` (the paper's KF's Riccati covariance, likewise); and the ratios
    ``position_rmse_over_pcrlb``, ``velocity_rmse_over_pcrlb``,
    ``position_rmse_over_per_run_pcrlb``, ``velocity_rmse_over_per_run_pcrlb``, each with the
    RMSE's 95 % interval divided by the bound (``*_ci95``; the bound taken as exact).
    """
    every = {name: metrics[:, i] for i, name in enumerate(metric_names)}
    runs = len(seeds)
    failed = every.get("failed", np.zeros(runs)) != 0.0
    column = {name: values[~failed] for name, values in every.items()}
    for name in NEEDED_METRICS:  # a study whose runs all failed has no other metric
        column.setdefault(name, np.empty(0))
        every.setdefault(name, np.full(runs, math.nan))
    summary: dict[str, Any] = {
        "runs": runs,
        "first_seed": int(seeds[0]),
        "steps": scenario.steps,
        "steady_state_start": scenario.steady_state_start,
        "completed_runs": int(np.sum(~failed)),
        "failed_fraction": float(np.mean(failed)),
    }
    with np.errstate(all="ignore"):
        for name in ("position", "velocity", "tracking"):
            mse = column[f"{name}_rmse"] ** 2
            summary[f"{name}_rmse"] = _finite(math.sqrt(float(np.mean(mse))))
            interval = bootstrap_interval(
                mse,
                lambda x: np.sqrt(np.mean(x, axis=-1)),
                BOOTSTRAP_RESAMPLES,
                seed=BOOTSTRAP_SEED,
            )
            summary[f"{name}_rmse_ci95"] = [_finite(v) for v in interval]
        nees = column["nees_mean"]
        summary["nees_mean"] = _finite(float(np.mean(nees)))
        interval = bootstrap_interval(
            nees, lambda x: np.mean(x, axis=-1), BOOTSTRAP_RESAMPLES, seed=BOOTSTRAP_SEED
        )
        summary["nees_mean_ci95"] = [_finite(v) for v in interval]
        diverged = int(np.sum(~(every["final_position_error"] <= DIVERGENCE_THRESHOLD)))
        summary["diverged_fraction"] = diverged / runs
        summary["diverged_fraction_ci95"] = list(wilson_interval(diverged, runs))
        bounded = int(np.sum(every["max_tracking_error"] < BOUNDED_TRACKING_THRESHOLD))
        summary["tracking_bounded_fraction"] = bounded / runs
        summary["tracking_bounded_fraction_ci95"] = list(wilson_interval(bounded, runs))
        for name in ("relative_speed", "acceleration"):
            summary[f"{name}_mean"] = _finite(float(np.mean(column[f"{name}_mean"])))
            peaks = column[f"{name}_peak"]
            summary[f"{name}_peak"] = _finite(float(np.max(peaks))) if len(peaks) else None
    summary["divergence_threshold_m"] = DIVERGENCE_THRESHOLD
    summary["bounded_tracking_threshold_m"] = BOUNDED_TRACKING_THRESHOLD
    summary["interval_method"] = INTERVAL_METHOD
    with np.errstate(all="ignore"):
        summary.update(bound_summary(summary, column, scenario, information_sum))
    return summary


def _runs_csv(seeds: np.ndarray, names: list[str], metrics: np.ndarray) -> str:
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(["seed", *names])
    for seed, row in zip(seeds, metrics, strict=True):
        writer.writerow([int(seed), *(repr(float(v)) for v in row)])
    return buffer.getvalue()


def finish_study(study: Study, computed: int = 0, figures: bool = True) -> StudyResult:
    """Reads the study's runs from disk; writes ``runs.csv``, ``summary.json``, the figure."""
    seeds, names, metrics, norms = load_runs(study)
    information = load_information(study)
    summary = summarize(names, metrics, study.scenario, seeds, information)
    out_dir = Path(study.out_dir)
    write_text_atomic(out_dir / "runs.csv", _runs_csv(seeds, names, metrics))
    write_json_atomic(out_dir / "summary.json", summary)
    if figures:
        from drake_uuv.analysis.figures import band_figure, bound_curves, save_figure

        bounds = None
        if information is not None:
            bounds = bound_curves(monte_carlo_bound(information, len(seeds), study.scenario))
        save_figure(
            band_figure(
                dict(zip(NORMS, np.moveaxis(norms, 1, 0), strict=True)),
                study.scenario,
                bounds=bounds,
            ),
            out_dir / "figures" / "bands",
        )
    return StudyResult(study, seeds, names, metrics, norms, summary, computed)


# --------------------------------------------------------------------------------- CLI


def add_execution_options(parser: argparse.ArgumentParser) -> None:
    """The options of how a study runs: runs, workers, scheduler, resume, chunk size, progress."""
    parser.add_argument("--runs", type=int, default=100, help="runs per study (default: 100)")
    parser.add_argument(
        "--workers", type=int, default=None, help="local processes (default: every core)"
    )
    parser.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="run on a dask.distributed cluster, e.g. tcp://host:8786",
    )
    parser.add_argument(
        "--resume", action="store_true", help="keep finished runs in --out, compute the rest"
    )
    parser.add_argument(
        "--chunk-size",
        type=int,
        default=None,
        help="seeds per task (default: automatic; smaller loses less on interruption)",
    )
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")


def execution_options(args: argparse.Namespace) -> dict[str, Any]:
    """The :func:`run_studies` keywords from :func:`add_execution_options`'s options."""
    return dict(
        workers=args.workers,
        scheduler=args.scheduler,
        resume=args.resume,
        chunk_size=args.chunk_size,
        progress=not args.no_progress,
    )


def format_summary(summary: dict[str, Any]) -> str:
    """A few lines for the terminal."""

    def number(value: float | None, fmt: str = ".4g") -> str:
        return "—" if value is None else format(value, fmt)

    def interval(key: str) -> str:
        low, high = summary[key]
        return f"[{number(low)}, {number(high)}]"

    return "\n".join(
        [
            f"{summary['runs']} runs, seeds {summary['first_seed']}.."
            f"{summary['first_seed'] + summary['runs'] - 1}, k ≥ {summary['steady_state_start']}:",
            f"  position RMSE {number(summary['position_rmse'])} m "
            f"{interval('position_rmse_ci95')}",
            f"  velocity RMSE {number(summary['velocity_rmse'])} m/s "
            f"{interval('velocity_rmse_ci95')}",
            f"  tracking RMSE {number(summary['tracking_rmse'])} m "
            f"{interval('tracking_rmse_ci95')}",
            f"  mean NEES {number(summary['nees_mean'])} {interval('nees_mean_ci95')} (6 if "
            "consistent)",
            f"  diverged {summary['diverged_fraction']:.1%}, tracking bounded "
            f"{summary['tracking_bounded_fraction']:.1%}",
            *_bound_lines(summary, number),
        ]
    )


def _bound_lines(summary: dict[str, Any], number: Callable[..., str]) -> list[str]:
    """The PCRLB lines of :func:`format_summary` (none when the summary has no bound)."""
    lines = []
    for part, unit in (("position", "m"), ("velocity", "m/s")):
        if f"{part}_rmse_over_pcrlb" not in summary:
            continue
        line = (
            f"  {part} PCRLB {number(summary[f'pcrlb_{part}_rmse'])} {unit}: RMSE / PCRLB "
            f"{number(summary[f'{part}_rmse_over_pcrlb'], '.3f')}"
        )
        if f"{part}_rmse_over_per_run_pcrlb" in summary:
            line += (
                f", / per-run bound {number(summary[f'pcrlb_per_run_{part}_rmse'])} "
                f"{number(summary[f'{part}_rmse_over_per_run_pcrlb'], '.3f')}"
            )
        if f"kf_riccati_{part}_rmse" in summary:
            line += f"; paper-KF Riccati {number(summary[f'kf_riccati_{part}_rmse'])}"
        lines.append(line)
    return lines


def _montecarlo(args: argparse.Namespace) -> int:
    from drake_uuv.cli import UsageError, scenario_from_args

    scenario = scenario_from_args(args)
    out = Path(args.out)
    study = Study(name=args.scenario, scenario=scenario, runs=args.runs, out_dir=out)
    try:
        result = run_study(study, **execution_options(args))
    except MonteCarloError as e:
        raise UsageError(str(e)) from e
    except KeyboardInterrupt:
        kept = len(completed_seeds(out))
        print(f"\ninterrupted: {kept} finished runs kept in {out}/runs; rerun with --resume")
        return 130
    kept = study.runs - result.computed
    print(f"computed {result.computed} runs" + (f", kept {kept}" if kept else "") + f" -> {out}/")
    print(format_summary(result.summary))
    return 0


def add_subcommand(subparsers: argparse._SubParsersAction) -> None:
    """Registers ``drake-uuv montecarlo``."""
    from drake_uuv.cli import add_scenario_options

    parser = subparsers.add_parser(
        "montecarlo", help="many seeded runs: runs.csv, summary.json, error bands"
    )
    add_scenario_options(parser)
    add_execution_options(parser)
    parser.add_argument(
        "--out", default="out/montecarlo", help="output folder (default: out/montecarlo)"
    )
    parser.set_defaults(handler=_montecarlo)
