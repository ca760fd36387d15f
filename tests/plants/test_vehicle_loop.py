"""The closed loop on the hovering UUV: metrics consistent with the log, what the paper's
commands and the feasible configuration cost the vehicle, and the filter that takes the
vehicle's motion from its navigation instead of its commands.

Each run is the whole diagram with ``plant=!HoveringAuv``; the short runs keep the suite fast
(a 100-step vehicle run takes about 4 s of CPU).
"""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from drake_uuv import ClosedLoopSimulation, load_scenario
from drake_uuv.metrics import errors
from drake_uuv.models.so3 import log_so3
from drake_uuv.models.statistics import chi2_ppf, nees_band
from drake_uuv.models.vehicle_envelope import followable_target_scale
from tests.conftest import study_module

vehicle_study = study_module("vehicle")
scenario_feasible_limits = vehicle_study.scenario_feasible_limits
vehicle_variants = vehicle_study.vehicle_variants

# Every test here runs the hovering UUV's closed loop (seconds each).
pytestmark = pytest.mark.slow

VEHICLE = "plant=!HoveringAuv"
# Fast ticks per outer step: 50 Hz in t = 0.5 s.
TICKS = 25


def _overrides(name: str) -> tuple[str, ...]:
    return next(v for v in vehicle_variants() if v.name == name).overrides


def _feasible_overrides() -> tuple[str, ...]:
    return _overrides("feasible-vehicle")


@pytest.fixture(scope="module")
def feasible_run():
    scenario = load_scenario(
        "paper", [*_feasible_overrides(), "steps=100", "steady_state_start=20"], seed=0
    )
    return ClosedLoopSimulation(scenario).run()


@pytest.fixture(scope="module")
def paper_run():
    scenario = load_scenario("paper", [VEHICLE, "steps=30", "steady_state_start=10"], seed=0)
    return ClosedLoopSimulation(scenario).run()


def test_group_feasible_configuration_is_the_derived_one(paper) -> None:
    """The comparison group's hard-coded limits are feasible_limits' for the default vehicle."""
    scenario = base = load_scenario("paper", [VEHICLE])
    derived = scenario_feasible_limits(scenario)
    overrides = set(_feasible_overrides())
    assert set(derived.overrides()) <= overrides
    names = [v.name for v in vehicle_variants()]
    assert names == [
        "paper-kinematic", "paper-vehicle", "paper-vehicle-navigation",
        "feasible-kinematic", "feasible-vehicle", "feasible-vehicle-inflated",
        "feasible-vehicle-navigation",
        "hull-kinematic", "hull-vehicle", "hull-vehicle-inflated", "hull-vehicle-navigation",
        "slow-kinematic", "slow-vehicle", "slow-vehicle-navigation",
    ]  # fmt: skip
    rows = {v.name: set(v.overrides) for v in vehicle_variants()}
    for variant in vehicle_variants():
        scenario = load_scenario("paper", list(variant.overrides))
        assert (type(scenario.plant).__name__ == "HoveringAuv") == ("vehicle" in variant.name)
        navigation = variant.name.endswith("navigation")
        motion = "navigation" if navigation else "commanded"
        assert scenario.estimator.vehicle_motion == motion
        if navigation:  # the commanded row with the one override, nothing else
            commanded = rows[variant.name.removesuffix("-navigation")]
            assert rows[variant.name] - commanded == {"estimator.vehicle_motion=navigation"}
            assert commanded <= rows[variant.name]
        if variant.name.startswith("hull"):
            assert np.linalg.norm(scenario.sonar.baseline) <= 0.5
        if variant.name.endswith("inflated"):
            assert scenario.estimator.added_acceleration_variance > 0.0
        if variant.name.startswith("slow"):
            target = base.target
            scale = followable_target_scale(
                target.initial_velocity,
                np.asarray(target.acceleration_covariance),
                base.time_step,
                base.steps,
                derived.speed_budget,
            )
            assert_allclose(
                scenario.target.acceleration_covariance,
                round(scale, 3) * np.asarray(target.acceleration_covariance),
                rtol=1e-12,
            )


def _window(result) -> slice:
    return slice(result.scenario.steady_state_start, None)


def test_attitude_metrics_are_those_of_the_logged_attitudes(feasible_run, paper_run) -> None:
    for result in (feasible_run, paper_run):
        log, m, w = result.log, result.metrics, _window(result)
        # The angle of R_cmd Rᵀ by the rotation's logarithm (the metric takes the trace).
        angles = [
            np.linalg.norm(log_so3(C @ R.T))
            for C, R in zip(log["R_WB_command"][w], log["R_WB"][w], strict=True)
        ]
        assert m["attitude_error_mean"] == pytest.approx(np.mean(angles), rel=1e-6, abs=1e-9)
        assert m["attitude_error_peak"] == pytest.approx(np.max(angles), rel=1e-6, abs=1e-9)
        rates = np.linalg.norm(log["w_WB"][w], axis=1)
        assert m["angular_rate_peak"] == pytest.approx(rates.max(), rel=1e-12)


def test_saturation_metric_agrees_with_the_logged_thrusts(feasible_run, paper_run) -> None:
    for result in (feasible_run, paper_run):
        log, config = result.log, result.scenario.plant
        ticks = log["saturation_ticks"]
        assert np.all(np.diff(ticks[:, 0]) == TICKS)
        # "either" counts a tick once when force, moment or both were scaled.
        either, force, moment = (np.diff(ticks[:, i]) for i in (3, 1, 2))
        assert np.all(either >= np.maximum(force, moment)) and np.all(either <= force + moment)
        # Row k holds the thrusts and scales of the last fast tick before kt: a scaled wrench
        # puts a thruster exactly at its limit, an unscaled one none.
        thrust = np.abs(log["thrust"]).max(axis=1)
        scaled = np.any(log["allocation_scale"] < 1.0, axis=1)
        assert np.all(thrust <= config.max_thrust * (1 + 1e-12))
        assert np.allclose(thrust[scaled], config.max_thrust, rtol=1e-9)
        assert np.all(thrust[~scaled] < config.max_thrust * (1 + 1e-12))
        # ... and that tick is counted in the step before row k.
        assert np.all(either[scaled[1:]] >= 1)
        w = _window(result)
        counted = (ticks[-1, 3] - ticks[w][0, 3]) / (ticks[-1, 0] - ticks[w][0, 0])
        assert result.metrics["thrust_saturated_fraction"] == pytest.approx(counted)


def test_the_papers_commands_saturate_the_vehicle_and_are_not_followed(paper_run) -> None:
    m, log = paper_run.metrics, paper_run.log
    assert m["thrust_saturated_fraction"] == 1.0
    # Hundreds of m/s² asked, almost none delivered: the mismatch is the command itself.
    start = paper_run.scenario.steady_state_start
    commanded = np.sqrt(np.mean(np.sum(log["u1_W"][start:-1] ** 2, axis=1)))
    assert commanded > 100.0
    assert m["model_acceleration_rmse"] == pytest.approx(commanded, rel=0.05)
    assert m["attitude_error_mean"] > 0.5  # rad: the attitude does not keep up either


def test_the_kinematic_plant_follows_its_commands_exactly(paper) -> None:
    scenario = load_scenario("paper", ["steps=60", "steady_state_start=10"])
    metrics = ClosedLoopSimulation(scenario).run().metrics
    assert metrics["model_acceleration_rmse"] < 1e-9
    assert "thrust_saturated_fraction" not in metrics


# The feasible configuration's runs of 100 steps, and the window after the first steps'
# transient.
MOTION_RUNS, MOTION_STEPS, MOTION_START = 60, 100, 20


@pytest.fixture(scope="module")
def motion_runs():
    """The feasible configuration, seeds 0–59, 100 steps, each as one batch: the kinematic
    plant and the vehicle with each ``estimator.vehicle_motion``."""
    short = [f"steps={MOTION_STEPS}", f"steady_state_start={MOTION_START}"]
    rows = {
        "kinematic": "feasible-kinematic",
        "commanded": "feasible-vehicle",
        "navigation": "feasible-vehicle-navigation",
    }
    runs = {}
    for name, row in rows.items():
        scenario = load_scenario("paper", [*_overrides(row), *short])
        simulation = ClosedLoopSimulation(scenario, batch_size=MOTION_RUNS)
        runs[name] = (simulation.run_batch(range(MOTION_RUNS)), scenario)
    return runs


@pytest.mark.slow
def test_navigation_keeps_the_filter_consistent_where_the_commanded_prediction_does_not(
    motion_runs,
) -> None:
    """The vehicle does not always follow its commanded acceleration; in the runs where it
    falls behind (model acceleration RMSE above 0.1 m/s²), the filter that predicts with the
    commands falls out of consistency, while the one that takes the vehicle's state from its
    navigation stays consistent in every run.

    NEES bound from the run length: a consistent filter's NEES is χ²(6) at every step, so over
    the window's N = 80 steps the largest exceeds the χ²(6) quantile at 1 − 0.01/N with
    probability at most 1 % (union bound, whatever the correlation between steps; 27.3). Over
    60 runs a consistent filter then exceeds it in 3 runs or more with probability under 2 %
    (binomial, p = 0.01). Measured: none with navigation; the commanded filter's mean NEES
    beyond the bound in 9 of the 10 runs that fell behind. The navigation's pooled position
    RMSE is within the acceptance's 1.5× the kinematic plant's (0.82× measured)."""
    (kinematic, scenario), (commanded, _), (navigation, _) = (
        motion_runs[name] for name in ("kinematic", "commanded", "navigation")
    )
    window = slice(MOTION_START, None)
    nees = {name: errors(r.log, s)["nees"][:, window] for name, (r, s) in motion_runs.items()}
    bound = chi2_ppf(1.0 - 0.01 / nees["navigation"].shape[1], 6)
    assert np.max(kinematic.metrics["model_acceleration_rmse"]) < 1e-9
    assert np.sum(np.max(nees["navigation"], axis=1) > bound) < 3
    behind = commanded.metrics["model_acceleration_rmse"] > 0.1
    assert behind.sum() >= 3  # the vehicle falls behind its commands in some runs
    assert np.mean(np.mean(nees["commanded"][behind], axis=1) > bound) > 0.5
    mse = {name: np.mean(r.metrics["position_rmse"] ** 2) for name, (r, _) in motion_runs.items()}
    assert np.sqrt(mse["navigation"] / mse["kinematic"]) <= 1.5


@pytest.mark.slow
def test_the_feasible_configuration_rarely_saturates_and_is_followed(motion_runs) -> None:
    """Within the derived envelope over 60 runs of 100 steps: the rate and acceleration limits
    held in every run; the thrusters saturated in at most 10 % of the fast ticks in the median
    run and 15 % on average (the first steps' catch-up is much of a short run; measured 4.9 %
    and 9.1 %, up to 36 % in one run); the applied acceleration within a quarter of the
    0.6 m/s² limit of the command, RMS, in the median run (0.073 m/s² measured; 28 % of the
    runs follow it to 0.001 m/s², the rest fall behind while the catch-up lasts)."""
    m = motion_runs["commanded"][0].metrics
    assert np.median(m["thrust_saturated_fraction"]) <= 0.1
    assert np.mean(m["thrust_saturated_fraction"]) <= 0.15
    assert np.max(m["angular_rate_peak"]) < 0.3 * 1.1  # the rate limit, and the overshoot
    assert np.max(m["acceleration_peak"]) <= 0.6 + 1e-12
    assert 0.0 < np.median(m["model_acceleration_rmse"]) < 0.25 * 0.6


def test_navigation_on_a_followable_target_estimates_like_the_kinematic_plant() -> None:
    """The acceptance where the vehicle can follow the target (``slow-kinematic`` and
    ``slow-vehicle-navigation`` as the study runs them, 500 steps, k ≥ 200) on 8 seeds outside
    the study's (100–107): the vehicle's pooled position RMSE within 1.5× the kinematic
    plant's on the same seeds, and its mean NEES inside the 99 % band of the mean of 8 runs at
    one step, χ²(48)/8 (the time average varies less, so the band is lenient).

    Not with the paper's target: it outruns the vehicle's top speed in some runs, the vehicle
    falls tens of metres behind and the ranging error grows with the range (the results page
    measures it over 30 runs); a few seeds would pass or fail by which runs they hold."""
    rows = {v.name: v.overrides for v in vehicle_variants()}
    seeds = range(100, 108)
    results = {}
    for name in ("slow-kinematic", "slow-vehicle-navigation"):
        simulation = ClosedLoopSimulation(load_scenario("paper", list(rows[name])))
        results[name] = [simulation.run(seed).metrics for seed in seeds]
    mse = {
        name: np.mean([m["position_rmse"] ** 2 for m in metrics])
        for name, metrics in results.items()
    }
    assert np.sqrt(mse["slow-vehicle-navigation"] / mse["slow-kinematic"]) <= 1.5
    low, high = nees_band(6, len(seeds), level=0.99)
    nees = np.mean([m["nees_mean"] for m in results["slow-vehicle-navigation"]])
    assert low <= nees <= high
