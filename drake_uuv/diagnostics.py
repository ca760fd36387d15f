"""A run that breaks its own assumptions says so: warnings from its log and metrics.

Each :class:`RunWarning` names a cause and its fix, in one line. A run's metrics can look like
any other run's while the loop behind them has failed: a vehicle whose thrusters are
saturated does not follow the commands the filter predicts with, an estimator whose NEES is
far from the state's dimension does not describe its own error, a tracking error of metres
means the vehicle lost the target, and a raw-range filter that never left its linear start
is the paper's KF under another name. ``drake-uuv run`` prints them after its summary,
``metrics.json`` lists them, and a study counts the runs that had any.
"""

from dataclasses import dataclass

import numpy as np

from drake_uuv.metrics import batch_log, errors
from drake_uuv.models.handover import Phase
from drake_uuv.models.statistics import chi2_ppf, integrated_autocorrelation_time
from drake_uuv.scenario import HoveringAuv, Scenario

#: Thrusters saturated in more than this fraction of the controller's ticks.
SATURATION_LIMIT = 0.5
#: The probability of the NEES band: a consistent filter's mean NEES leaves it once in 1000.
NEES_BAND_PROBABILITY = 0.999
#: [m] The steady-state tracking RMSE beyond which the vehicle has lost its target.
TRACKING_LIMIT = 10.0


@dataclass(frozen=True)
class RunWarning:
    """What a run got wrong: a short code, and one line naming the cause and the fix."""

    code: str
    message: str

    def __str__(self) -> str:
        return f"WARNING: {self.message}"


def nees_band(samples: float, dimension: int = 6) -> tuple[float, float]:
    """The :data:`NEES_BAND_PROBABILITY` band of the mean of ``samples`` independent NEES
    values of a consistent filter: ``χ²(d·n)`` quantiles over n."""
    tail = 0.5 * (1.0 - NEES_BAND_PROBABILITY)
    dof = dimension * samples
    return chi2_ppf(tail, dof) / samples, chi2_ppf(1.0 - tail, dof) / samples


def run_nees_band(nees: np.ndarray) -> tuple[float, float, float]:
    """``(low, high, n_eff)``: the band of a run's mean NEES over its steady state.

    A filter's NEES is correlated from step to step (an error persists for as long as the
    filter's memory), so the n steps are worth ``n_eff = n / τ`` independent ones, with ``τ``
    the series' integrated autocorrelation time; the band is :func:`nees_band` of ``n_eff``
    (with independent steps it would be far too narrow: the paper's KF, consistent over 100
    runs, leaves it in one run of three).
    """
    tau = integrated_autocorrelation_time(nees)
    effective = max(np.count_nonzero(np.isfinite(nees)) / tau, 1.0)
    low, high = nees_band(effective)
    return low, high, effective


def run_warnings(
    log: dict[str, np.ndarray], metrics: dict[str, float], scenario: Scenario
) -> list[RunWarning]:
    """The warnings of a run (empty when it kept its assumptions): :func:`batch_warnings` of
    a batch of one."""
    batch = {name: np.array([value]) for name, value in metrics.items()}
    return batch_warnings(batch_log(log), batch, scenario)[0]


def batch_warnings(
    log: dict[str, np.ndarray], metrics: dict[str, np.ndarray], scenario: Scenario
) -> list[list[RunWarning]]:
    """The warnings of each run of a batch log (B×N×shape signals, ``k`` and ``time`` shared)
    from its metrics (each a (B,) array, :func:`~drake_uuv.metrics.batch_metrics`): run i's
    list, as :func:`run_warnings` of its own log. The NEES is computed for the batch at once;
    the rest, a few checks per run, one run at a time."""
    nees = errors(log, scenario)["nees"][:, scenario.steady_state_start :]
    phase = log.get("estimator_phase")
    return [
        _warnings(
            {name: float(value[i]) for name, value in metrics.items()},
            nees[i],
            None if phase is None else phase[i],
            scenario,
        )
        for i in range(len(nees))
    ]


def _warnings(
    metrics: dict[str, float], nees: np.ndarray, phase: np.ndarray | None, scenario: Scenario
) -> list[RunWarning]:
    """One run's warnings from its metrics, its steady-state NEES and its estimator's phase."""
    out = []
    vehicle = isinstance(scenario.plant, HoveringAuv)
    saturated = metrics.get("thrust_saturated_fraction", 0.0)
    if saturated > SATURATION_LIMIT:
        out.append(
            RunWarning(
                "saturation",
                f"thrusters saturated in {saturated:.0%} of the controller's ticks: the loop "
                "commands more than the vehicle can fly (use --scenario hovering_auv, a loop "
                "derived from its thrusters)",
            )
        )
    low, high, _ = run_nees_band(nees)
    nees_mean = metrics.get("nees_mean", float("nan"))
    if not low <= nees_mean <= high:
        out.append(RunWarning("nees", _nees_message(nees_mean, low, high, scenario, vehicle)))
    tracking = metrics.get("tracking_rmse", float("nan"))
    if not tracking <= TRACKING_LIMIT:
        out.append(
            RunWarning(
                "tracking",
                f"tracking RMSE {tracking:.3g} m exceeds {TRACKING_LIMIT:g} m: the vehicle lost "
                "its target (a fixed attitude leaves it unobservable; a loop the plant cannot "
                "fly or a target it cannot follow outruns it)",
            )
        )
    if phase is not None and len(phase) and np.all(phase[:, 0] == float(Phase.LINEAR)):
        out.append(
            RunWarning(
                "linear_start",
                f"the {type(scenario.estimator).__name__} never left its linear start: its "
                "estimate is the paper's KF's (the hand-over's tests never held; "
                "docs/handover.md says why, e.g. a fixed attitude or too few steps)",
            )
        )
    return out


def _nees_message(nees: float, low: float, high: float, scenario: Scenario, vehicle: bool) -> str:
    where = f"mean NEES {nees:.3g} (k ≥ {scenario.steady_state_start}) is outside {low:.2f}–"
    where += f"{high:.2f}, the 99.9 % band of a consistent filter"
    if nees < low and scenario.estimator.noise_model == "paper_printed":
        return where + (
            ": the paper's printed Γ overstates Y's noise (use --set estimator.noise_model=derived)"
        )
    if nees < low:
        return where + ": the estimator is cautious here (its covariance overstates its error)"
    if vehicle and scenario.estimator.vehicle_motion == "commanded":
        return where + (
            ": the vehicle does not move as commanded (use --set "
            "estimator.vehicle_motion=navigation)"
        )
    return where + (
        ": the estimator is overconfident here (docs/results/regimes.md compares the estimators' "
        "consistency by regime)"
    )
