"""The sonar in the closed loop: its logged ranges against the logged truth, at the paper's
timing and with ping offsets, a latency and a sound-speed error (the kinematic plant)."""

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from drake_uuv import ClosedLoopSimulation, load_scenario
from drake_uuv.models.measurement import NO_ARRIVAL, VALID
from tests.conftest import study_module
from tests.sensors.sonar_harness import rotation

_VEHICLE = study_module("vehicle")
#: The flyable configuration of the vehicle study (its ``feasible`` overrides).
FEASIBLE = [*_VEHICLE.VEHICLE_LOOP, f"attitude.max_angular_rate={_VEHICLE.VEHICLE_ANGULAR_RATE}"]
STEPS = 300


def run(overrides: list[str]) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray]:
    scenario = load_scenario("paper", [*overrides, f"steps={STEPS}", "steady_state_start=100"])
    log = ClosedLoopSimulation(scenario).run(1).log
    return log, np.asarray(scenario.sonar.baseline), np.asarray(scenario.sonar.noise_variances)


def assert_standard_normal(residuals: np.ndarray) -> None:
    """Mean 0 and variance 1 within 4 standard errors of ``n`` independent draws."""
    n = residuals.size
    assert abs(residuals.mean()) < 4.0 / np.sqrt(n), residuals.mean()
    assert abs(residuals.var() - 1.0) < 4.0 * np.sqrt(2.0 / n), residuals.var()


def test_the_paper_timing_measures_the_logged_truth_at_the_tick() -> None:
    """Default timing: the sonar at the tick's ``q ± ½ R b``, pinged at the tick, ranges its
    distance plus N(0, η), Y from the ranges: the same arithmetic as before, bit for bit."""
    log, b, eta = run([])
    q, half = log["p_WU"] - log["p_WT"], 0.5 * log["R_WB"] @ b
    assert_array_equal(log["p_TS_W"], np.concatenate([q + half, q - half], axis=1))
    assert_array_equal(log["ping_time"], np.stack([log["time"]] * 2, axis=1))
    assert_array_equal(log["b_W"], log["R_WB"] @ b)
    d1, d2 = log["ranges"].T
    assert_array_equal(log["Y"], 0.5 * (d1 * d1 - d2 * d2))
    assert np.all(log["sonar_status"] == VALID)
    true = np.linalg.norm(log["p_TS_W"].reshape(-1, 2, 3), axis=2)
    assert_standard_normal((log["ranges"] - true) / np.sqrt(eta))


@pytest.mark.slow
def test_pings_between_ticks_see_the_kinematic_plant_at_their_time() -> None:
    """τ = [0.1, 0.35] s, L = 0.4 s (d = [1, 2]), ε = 0.02: each arriving range's sonar is where
    the constant-acceleration formula puts it at the ping, from the logged states and
    commands of its step (the plant's ``p + τ v + ½ τ² R u1``, ``Exp(u2 τ) R``, and the
    target's acceleration from its logged velocities), and its range is ``1.02 |p_TS_W|``
    plus N(0, η)."""
    tau, latency, epsilon = np.array([0.1, 0.35]), 0.4, 0.02
    log, b, eta = run([*FEASIBLE, f"sonar.ping_offsets={tau.tolist()}",
                       f"sonar.latency={latency}", f"sonar.sound_speed_error={epsilon}"])  # fmt: skip
    t = log["time"][1] - log["time"][0]
    delays = (1, 2)
    a_T = np.diff(log["v_WT"], axis=0) / t
    for i, d in enumerate(delays):
        status = log["sonar_status"][:, i]
        assert_array_equal(status[:d], NO_ARRIVAL)
        assert np.all(status[d:] == VALID)
        k = np.arange(STEPS - d)  # the step of the ping arriving at tick k + d
        s = tau[i]
        assert_allclose(log["ping_time"][d:, i], log["time"][k] + s, atol=1e-12)
        p_U = log["p_WU"][k] + s * log["v_WU"][k] + 0.5 * s * s * log["u1_W"][k]
        p_T = log["p_WT"][k] + s * log["v_WT"][k] + 0.5 * s * s * a_T[k]
        R = np.array([rotation(log["u2_W"][j] * s) @ log["R_WB"][j] for j in k])
        sign = 1.0 if i == 0 else -1.0
        p_TS = p_U + sign * 0.5 * R @ b - p_T
        assert_allclose(log["p_TS_W"][d:, 3 * i : 3 * i + 3], p_TS, atol=1e-9)
        residual = log["ranges"][d:, i] - (1 + epsilon) * np.linalg.norm(p_TS, axis=1)
        assert_standard_normal(residual / np.sqrt(eta[i]))
