"""The extended bound of a batch of closed-loop runs: each run's bits alone, and the numpy
formulation's values (a ping at a time, the recursion step by step) to rounding."""

import numpy as np
import pytest

from drake_uuv.batch_logs import run_log
from drake_uuv.models.navigation_noise import (
    navigated_velocity_covariance,
    range_attitude_jacobian,
    rotation_vector_covariance,
)
from drake_uuv.models.ping_geometry import interpolate_attitude
from drake_uuv.run_bounds import extended_bound, ping_arrivals
from drake_uuv.scenario import Scenario, load_scenario
from drake_uuv.simulation import ClosedLoopSimulation
from tests.models.test_pcrlb_timed import reference_pcrlb_timed

STEPS = 60
#: The navigation and the sonars' timing of the bound's slowest rows: an inertial navigation
#: whose velocity drives the estimate, a ping between ticks and a latency.
NAVIGATION = [
    "navigation=InertialNavigation",
    "estimator.vehicle_motion=navigation",
    "sonar.ping_offsets=[0.0,0.25]",
    "sonar.latency=0.2",
]


def _scenario() -> Scenario:
    return load_scenario("paper", [*NAVIGATION, f"steps={STEPS}", "steady_state_start=30"])


@pytest.fixture(scope="module")
def batch() -> dict[str, np.ndarray]:
    """Three closed-loop runs as one batch log."""
    simulation = ClosedLoopSimulation(_scenario(), batch_size=3, log="metrics")
    return simulation.run_batch([1, 2, 3]).log


def _reference(log: dict[str, np.ndarray], scenario: Scenario) -> np.ndarray:
    """The bound of one run as numpy wrote it: each ping's baseline from its own geodesic,
    the recursion of the test's reference."""
    t = scenario.time_step
    nav = scenario.navigation.error_figures()
    tau, lag, p_TS = ping_arrivals(log, scenario)
    Sigma = rotation_vector_covariance(log["R_WB"], nav.attitude_noise)
    sonar = scenario.sonar
    noise = np.zeros((STEPS, 2, 2))
    noise[:, [0, 1], [0, 1]] = np.asarray(sonar.noise_variances) / sonar.samples_per_step
    q_s = np.zeros(p_TS.shape)
    for k, i in zip(*np.nonzero(np.isfinite(tau)), strict=True):
        s = tau[k, i] / t
        R = log["R_WB"][k] if s == 0.0 else interpolate_attitude(*log["R_WB"][k : k + 2], s)
        q_s[k, i] = R @ np.asarray(sonar.baseline)
    J = range_attitude_jacobian(p_TS, q_s)
    noise = noise + J @ Sigma @ np.swapaxes(J, -1, -2)
    velocity = navigated_velocity_covariance(
        log["v_WU"], Sigma, nav.velocity_noise, nav.velocity_bias
    )
    bound = reference_pcrlb_timed(
        tau, lag, p_TS, noise, np.asarray(scenario.estimator.initial_covariance),
        np.asarray(scenario.target.acceleration_covariance), t, position_noise=t * t * velocity,
    )  # fmt: skip
    bound[:, 3:, 3:] += velocity
    return bound


def test_the_batch_is_each_run_alone_and_the_numpy_formulation(batch) -> None:
    scenario = _scenario()
    bound, floor = extended_bound(batch, scenario)
    assert bound.shape == floor.shape == (3, STEPS, 6, 6)
    for i in range(3):
        alone, alone_floor = extended_bound(run_log(batch, i), scenario)
        assert np.array_equal(bound[i], alone) and np.array_equal(floor[i], alone_floor)
        expected = _reference(run_log(batch, i), scenario)
        scale = np.abs(expected).max(axis=(1, 2), keepdims=True)
        assert np.all(np.abs(bound[i] - expected) <= 1e-10 * scale)
    reordered = {k: v if k in ("k", "time") else v[[2, 0, 1]] for k, v in batch.items()}
    again, again_floor = extended_bound(reordered, scenario)
    assert np.array_equal(again, bound[[2, 0, 1]]) and np.array_equal(again_floor, floor[[2, 0, 1]])


def test_a_failed_run_is_nan_and_leaves_the_others(batch) -> None:
    """Run 1 NaN from step 30 on (its state and its ping times): its bound is NaN, the other
    runs' bits are theirs alone; a sound run whose ping times are wrong raises."""
    scenario = _scenario()
    clean, _ = extended_bound(batch, scenario)
    broken = {k: v if k in ("k", "time") else v.copy() for k, v in batch.items()}
    for name in ("p_WU", "ping_time"):
        broken[name][1, 30:] = np.nan
    bound, floor = extended_bound(broken, scenario)
    assert np.array_equal(bound[[0, 2]], clean[[0, 2]])
    assert np.isnan(bound[1]).all() and np.isnan(floor[1]).all()
    broken["p_WU"][1] = batch["p_WU"][1]  # a sound state: the ping times are the log's fault
    with pytest.raises(ValueError, match="(?s)log: ping_time .* must be at or before"):
        extended_bound(broken, scenario)
