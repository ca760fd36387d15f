"""Rotation, excitation and reference-acceleration metrics of a logged attitude sequence."""

import math

import numpy as np
from numpy.testing import assert_allclose

from drake_uuv.metrics import attitude_metrics
from drake_uuv.models.so3 import exp_so3
from drake_uuv.scenario import load_scenario


def test_constant_rate_spin_about_z_closed_form() -> None:
    """Spinning at θ per step about z: every rotation is θ; ``R q*`` moves on a circle of
    radius ``|q*_xy|``, whose second difference is ``2|q*_xy|(1 − cos θ)``; the baseline
    ``[−1, 1, 0]`` stays in the xy plane, so the Gramian's z eigenvalue is 0."""
    scenario = load_scenario("paper")
    theta, n = 0.3, 60
    R = np.array([exp_so3(np.array([0.0, 0.0, k * theta])) for k in range(n)])
    log = {"R_WB": R, "b_W": R @ np.asarray(scenario.sonar.baseline)}
    metrics = attitude_metrics(log, scenario)
    assert_allclose(metrics["rotation_mean"], theta, rtol=1e-12)
    assert_allclose(metrics["rotation_peak"], theta, rtol=1e-12)
    assert abs(metrics["excitation_min"]) < 1e-12
    radius = math.hypot(-2.0, -2.0)
    expected = 2.0 * radius * (1.0 - math.cos(theta)) / scenario.time_step**2
    assert_allclose(metrics["reference_acceleration_mean"], expected, rtol=1e-12)
    assert_allclose(metrics["reference_acceleration_peak"], expected, rtol=1e-12)


def test_a_run_shorter_than_the_window_has_no_excitation_value() -> None:
    scenario = load_scenario("paper")
    R = np.array([np.eye(3)] * 5)
    metrics = attitude_metrics({"R_WB": R, "b_W": R @ np.ones(3)}, scenario)
    assert math.isnan(metrics["excitation_min"])
    assert metrics["rotation_peak"] == 0.0
