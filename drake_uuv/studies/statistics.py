"""The statistics of a study: the summary, its intervals, and the Monte Carlo PCRLB.

:func:`summarize` turns the per-run metrics (in seed order) into ``summary.json``; it depends
only on the metrics, the seeds and the information sum, never on how the runs were computed,
so a study's summary is bit-identical on one core, many, or a cluster. Intervals come from
:mod:`drake_uuv.analysis.stats` (seeded bootstrap, Wilson score); bounds from
:mod:`drake_uuv.models.pcrlb`.
"""

import math
import warnings
from typing import Any

import numpy as np

from drake_uuv.analysis.stats import bootstrap_interval, wilson_interval
from drake_uuv.metrics import bound_errors_on
from drake_uuv.models.pcrlb import bound_rmse, pcrlb_recursion
from drake_uuv.scenario import Scenario

# A run has diverged when its final position error exceeds this [m] (or is not finite).
DIVERGENCE_THRESHOLD = 10.0
# The tracking error of a run stays bounded when its steady-state maximum is below this [m].
BOUNDED_TRACKING_THRESHOLD = 10.0
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
    "efficient estimator attains; above pcrlb, see models/pcrlb.py); kf_riccati: the "
    "paper's KF's Riccati covariance with Γ on the true ranges, likewise; each √(mean over "
    "k ≥ steady_state_start of the trace of the position or velocity block)"
)
# Appended to BOUND_METHOD when the scenario has navigation errors or sonar timing.
EXTENDED_BOUND_METHOD = (
    "; with navigation errors or sonar timing, pcrlb_per_run is the extended per-run bound "
    "(each range at its ping time once arrived, navigation noise, the biases' error floors; "
    "pcrlb_per_run_floor is the floors' part), while pcrlb stays the Monte Carlo bound of "
    "the ranges at the ticks they arrive, without navigation noise, latency or floors"
)
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


def monte_carlo_bound(information_sum: np.ndarray, runs: int, scenario: Scenario) -> np.ndarray:
    """The Monte Carlo PCRLB (steps × 6 × 6) from the information summed over ``runs`` runs.

    ``information_sum`` as :func:`drake_uuv.studies.storage.load_information` returns it; the
    recursion runs once on the information averaged over runs, from the prior
    ``estimator.initial_covariance``. With navigation errors or sonar timing
    (:func:`drake_uuv.metrics.bound_errors_on`) it stays this bound of the ranges at the
    ticks they arrive (:func:`drake_uuv.metrics.run_information`): it does not include the
    ping times, the latency, the navigation noise nor the biases' error floors, which the
    per-run bound (``pcrlb_per_run``) does.
    """
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
    out: dict[str, Any] = {}
    bounds: dict[str, tuple[float, float]] = {}
    if information_sum is not None:
        covs = monte_carlo_bound(information_sum, summary["runs"], scenario)
        bounds["pcrlb"] = bound_rmse(covs, scenario.steady_state_start)
    per_run = (("pcrlb_per_run", "pcrlb"), ("kf_riccati", "kf_riccati"),
               ("pcrlb_per_run_floor", "pcrlb_floor"))  # fmt: skip
    for name, key in per_run:
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
        extended = EXTENDED_BOUND_METHOD if bound_errors_on(scenario) else ""
        out["bound_method"] = BOUND_METHOD + extended
    return out


def _finite(value: float) -> float | None:
    """JSON has no inf/NaN: non-finite values become null."""
    return float(value) if math.isfinite(value) else None


def _fractions(every: dict[str, np.ndarray], failed: np.ndarray, runs: int) -> dict[str, Any]:
    """The diverged, tracking-bounded and warned fractions of the runs, with 95 % intervals."""
    counts = {
        "diverged": int(np.sum(~(every["final_position_error"] <= DIVERGENCE_THRESHOLD))),
        "tracking_bounded": int(np.sum(every["max_tracking_error"] < BOUNDED_TRACKING_THRESHOLD)),
        # Runs that warned of a broken assumption (drake_uuv.diagnostics), failed ones too.
        "warned": int(np.sum(failed | (every.get("warnings", np.zeros(runs)) > 0.0))),
    }
    out: dict[str, Any] = {}
    for name, count in counts.items():
        out[f"{name}_fraction"] = count / runs
        out[f"{name}_fraction_ci95"] = list(wilson_interval(count, runs))
    return out


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
    :data:`BOUNDED_TRACKING_THRESHOLD`. ``warned_fraction``: runs that warned of a broken
    assumption (:mod:`drake_uuv.diagnostics`; a failed run counts). Each has a 95 % interval
    (``*_ci95``, see
    :data:`INTERVAL_METHOD`). Non-finite numbers are written as null.

    Bounds (:data:`BOUND_METHOD`), each as ``*_position_rmse`` and ``*_velocity_rmse``:
    ``pcrlb`` (the Monte Carlo PCRLB, from ``information_sum``, Σ over runs of ``M(k)``),
    ``pcrlb_per_run`` (√ of the mean over runs of each run's squared bound),
    ``kf_riccati`` (the paper's KF's Riccati covariance, likewise) and, with navigation
    errors or sonar timing, ``pcrlb_per_run_floor`` (the per-run bound's error floors,
    likewise); and the ratios
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
    # A study whose runs all failed has empty columns: their statistics are null, not warnings.
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
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
        summary.update(_fractions(every, failed, runs))
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
