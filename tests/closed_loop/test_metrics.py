"""Run metrics: errors, the bounds along a run's true trajectory, missing returns."""

import numpy as np
from numpy.testing import assert_allclose

from drake_uuv.metrics import bound_covariances
from drake_uuv.models.measurement import range_measurement
from drake_uuv.models.pcrlb import kf_riccati_covariance, pcrlb_along_trajectory
from drake_uuv.scenario import load_scenario
from drake_uuv.simulation import ClosedLoopSimulation
from tests.conftest import T, W


def test_run_bounds_are_the_pcrlb_and_the_kf_riccati_on_the_true_trajectory() -> None:
    scenario = load_scenario("paper", ["steps=120", "steady_state_start=60"])
    log = ClosedLoopSimulation(scenario).run(2).log
    bounds = bound_covariances(log, scenario)
    q = log["p_WU"] - log["p_WT"]
    eta = np.asarray(scenario.sonar.noise_variances)
    expected = pcrlb_along_trajectory(q, log["b_W"], np.eye(6), W, eta, 1, T)
    assert_allclose(bounds["pcrlb"], expected, rtol=1e-12, atol=1e-15)
    d = np.stack(
        [range_measurement(np.r_[qk, 0, 0, 0], s) for qk, s in zip(q, log["b_W"], strict=True)]
    )
    gamma = d**2 @ eta + 0.5 * eta @ eta  # the derived Γ on the true ranges
    riccati = kf_riccati_covariance(log["b_W"], np.eye(6), W, gamma, T)
    assert_allclose(bounds["kf_riccati"], riccati, rtol=1e-9, atol=1e-13)
