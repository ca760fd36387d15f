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


def test_the_feasible_configuration_rarely_saturates_and_is_followed(feasible_run) -> None:
    """Within the derived envelope: at most 5 % of the fast ticks saturated (1.5 % measured on
    this seed, during the first steps' catch-up), the attitude within 0.01 rad of its target
    and the acceleration followed to 0.05 m/s² RMS."""
    m = feasible_run.metrics
    assert m["thrust_saturated_fraction"] <= 0.05
    assert m["attitude_error_peak"] < 0.01
    assert m["angular_rate_peak"] < 0.3 * 1.1  # the rate limit, and the loop's overshoot
    assert m["acceleration_peak"] <= 0.6 + 1e-12
    assert 0.0 < m["model_acceleration_rmse"] < 0.05


def test_the_kinematic_plant_follows_its_commands_exactly(paper) -> None:
    scenario = load_scenario("paper", ["steps=60", "steady_state_start=10"])
    metrics = ClosedLoopSimulation(scenario).run().metrics
    assert metrics["model_acceleration_rmse"] < 1e-9
    assert "thrust_saturated_fraction" not in metrics


def test_on_a_followable_target_the_vehicle_estimates_like_the_kinematic_plant() -> None:
    """8 seeds (0–7) of the ``slow-*`` rows, as the study runs them (500 steps, k ≥ 200; the
    first steps differ between the two plants while the estimate converges): the vehicle's
    pooled position RMSE within 1.5× the kinematic plant's on the same seeds (1.01 measured),
    at most 2 % of the thrust ticks saturated on average (0 measured), and the mean NEES
    inside the 99 % band of the mean of 8 runs at one step, χ²(48)/8 (the time average varies
    less, so the band is lenient; 6.1 measured)."""
    rows = {v.name: v.overrides for v in vehicle_variants()}
    seeds = range(8)
    results = {}
    for name in ("slow-kinematic", "slow-vehicle"):
        simulation = ClosedLoopSimulation(load_scenario("paper", list(rows[name])))
        results[name] = [simulation.run(seed).metrics for seed in seeds]
    mse = {
        name: np.mean([m["position_rmse"] ** 2 for m in metrics])
        for name, metrics in results.items()
    }
    vehicle = results["slow-vehicle"]
    assert np.sqrt(mse["slow-vehicle"] / mse["slow-kinematic"]) <= 1.5
    assert np.mean([m["thrust_saturated_fraction"] for m in vehicle]) <= 0.02
    low, high = nees_band(6, len(seeds), level=0.99)
    assert low <= np.mean([m["nees_mean"] for m in vehicle]) <= high


# A seed whose commanded run falls behind its commands within 100 steps (on most seeds that
# happens later in the 500-step run), and the window after the first steps' transient.
MOTION_SEED = 21
MOTION_STEPS, MOTION_START = 100, 20


@pytest.fixture(scope="module")
def motion_runs():
    """The feasible configuration, seed 21, 100 steps: the kinematic plant and the vehicle
    with each ``estimator.vehicle_motion``."""
    short = [f"steps={MOTION_STEPS}", f"steady_state_start={MOTION_START}"]
    runs = {
        "kinematic": load_scenario("paper", [*_overrides("feasible-kinematic"), *short]),
        "commanded": load_scenario("paper", [*_overrides("feasible-vehicle"), *short]),
        "navigation": load_scenario("paper", [*_overrides("feasible-vehicle-navigation"), *short]),
    }
    return {name: ClosedLoopSimulation(s).run(MOTION_SEED) for name, s in runs.items()}


def test_navigation_keeps_the_filter_consistent_where_the_commanded_prediction_does_not(
    motion_runs,
) -> None:
    """Neither vehicle run follows its commanded acceleration; the filter that predicts with
    it falls out of consistency and its error grows, the one that takes the vehicle's state
    from its navigation estimates as on the kinematic plant.

    NEES bound from the run length: a consistent filter's NEES is χ²(6) at every step, so
    over the window's N steps the largest exceeds the χ²(6) quantile at 1 − 0.01/N with
    probability at most 1 % (union bound, whatever the correlation between steps; 27.3 for
    N = 80). Measured: peak 16.4 with navigation; mean 64 (peak 213) with the commanded
    prediction. Error: position RMSE over the window within the acceptance's 1.5× the
    kinematic plant's on the same seed (1.77 m with navigation, 5.25 m commanded, 1.65 m
    kinematic), and its peak error within 1.5× the kinematic plant's peak."""
    kinematic, commanded, navigation = (
        motion_runs[name] for name in ("kinematic", "commanded", "navigation")
    )
    window = slice(MOTION_START, None)
    nees = {name: errors(r.log, r.scenario)["nees"][window] for name, r in motion_runs.items()}
    bound = chi2_ppf(1.0 - 0.01 / len(nees["navigation"]), 6)
    # The vehicle does not follow its commands in either run (the kinematic plant does).
    for result in (commanded, navigation):
        assert result.metrics["model_acceleration_rmse"] > 0.1  # m/s², 0.16 and 0.18 measured
    assert kinematic.metrics["model_acceleration_rmse"] < 1e-9
    assert np.max(nees["navigation"]) <= bound
    assert np.mean(nees["commanded"]) > bound  # even its mean is beyond any consistent step
    reference = kinematic.metrics["position_rmse"]
    assert navigation.metrics["position_rmse"] <= 1.5 * reference
    assert commanded.metrics["position_rmse"] > 1.5 * reference
    # Bounded: the navigation estimate's error stays within 1.5× the kinematic plant's peak
    # over the window (3.9 m against 3.5 m), the commanded one drifts beyond (10.6 m).
    peak = {
        name: np.linalg.norm(errors(r.log, r.scenario)["position"][window], axis=1).max()
        for name, r in motion_runs.items()
    }
    assert peak["navigation"] <= 1.5 * peak["kinematic"]
    assert peak["commanded"] > 1.5 * peak["kinematic"]


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
