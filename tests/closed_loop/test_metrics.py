"""Run metrics: errors, the bounds along a run's true trajectory (the extended bound with
navigation errors and sonar timing on synthetic logs), missing returns."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from drake_uuv.metrics import (
    bound_covariances,
    bound_errors_on,
    bound_metrics,
    errors,
    extended_bound,
    ping_arrivals,
)
from drake_uuv.models.measurement import DROPPED, NO_ARRIVAL, VALID, range_measurement
from drake_uuv.models.navigation_noise import rotation_vector_covariance
from drake_uuv.models.pcrlb import kf_riccati_covariance, pcrlb_along_trajectory
from drake_uuv.models.pcrlb_timed import pcrlb_timed
from drake_uuv.models.ping_geometry import interpolate_attitude, interpolate_position
from drake_uuv.models.so3 import exp_so3, hat
from drake_uuv.scenario import Scenario, load_scenario
from drake_uuv.simulation import ClosedLoopSimulation
from tests.conftest import ETA, T, W


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


# --- The extended bound (navigation errors, sonar timing) on synthetic logs -------------------

STEPS, START = 60, 20
NO_ERRORS = "navigation=!InertialNavigation {attitude_noise_deg: [0, 0, 0], heading_bias_deg: 0, velocity_noise: 0, velocity_bias: 0}"  # noqa: E501


def _scenario(*overrides: str) -> Scenario:
    return load_scenario("paper", [f"steps={STEPS}", f"steady_state_start={START}", *overrides])


def _psd_le(a: np.ndarray, b: np.ndarray, rtol: float = 1e-9) -> bool:
    """a ⪯ b (all stacked matrices), up to rounding."""
    gap = np.linalg.eigvalsh(b - a).min(axis=-1)
    return bool(np.all(gap >= -rtol * np.abs(b).max()))


def _synthetic_log(scenario: Scenario, seed: int = 0, dropped=()) -> dict[str, np.ndarray]:
    """A run's log as the interfaces state it: the vehicle and the target with an acceleration
    held over each step, the attitude turning at a world rate held over each step, and each
    sonar's ping of step k at ``k t + τ_i`` arriving at tick ``k + ceil((τ_i + L)/t)`` with its
    ``ping_time`` and ``p_TS_W`` (``dropped``: (step, sonar) whose range arrives DROPPED)."""
    rng = np.random.default_rng(seed)
    t, N, sonar = scenario.time_step, scenario.steps, scenario.sonar
    b = np.asarray(sonar.baseline, dtype=float)
    a_U, a_T = rng.normal(size=(N, 3)), 0.05 * rng.normal(size=(N, 3))
    rates = 0.4 * rng.normal(size=(N, 3))
    state = {"p_WU": [np.array([0.0, 0.0, 0.0])], "v_WU": [np.zeros(3)],
             "p_WT": [np.array([1.0, 2.0, 2.0])], "v_WT": [np.array([0.02, 0.1, 0.1])],
             "R_WB": [np.eye(3)]}  # fmt: skip
    for k in range(N - 1):
        for p, v, a in (("p_WU", "v_WU", a_U[k]), ("p_WT", "v_WT", a_T[k])):
            state[p].append(state[p][k] + t * state[v][k] + 0.5 * t * t * a)
            state[v].append(state[v][k] + t * a)
        state["R_WB"].append(exp_so3(rates[k] * t) @ state["R_WB"][k])
    log = {name: np.array(values) for name, values in state.items()}
    log["b_W"], log["u1_W"], log["u2_W"] = log["R_WB"] @ b, a_U, rates
    log["sonar_status"] = np.full((N, 2), NO_ARRIVAL)
    log["ping_time"], log["p_TS_W"] = np.full((N, 2), np.nan), np.full((N, 6), np.nan)
    for k in range(N):
        for i, (tau, sign) in enumerate(zip(sonar.ping_offsets, (0.5, -0.5), strict=True)):
            tick = k + math.ceil((tau + sonar.latency) / t - 1e-9)
            if tick >= N:
                continue
            q = (log["p_WU"][k] - log["p_WT"][k] + tau * (log["v_WU"][k] - log["v_WT"][k])
                 + 0.5 * tau * tau * (a_U[k] - a_T[k]))  # fmt: skip
            log["sonar_status"][tick, i] = DROPPED if (k, i) in dropped else VALID
            log["ping_time"][tick, i] = k * t + tau
            log["p_TS_W"][tick, 3 * i : 3 * i + 3] = (
                q + sign * exp_so3(rates[k] * tau) @ log["R_WB"][k] @ b
            )
    return log


def test_ping_arrivals_recover_each_pings_step_offset_and_geometry() -> None:
    scenario = _scenario("sonar.ping_offsets=[0.1, 0.3]", "sonar.latency=0.6")
    log = _synthetic_log(scenario, dropped={(5, 1), (9, 0)})
    tau, lag, p_TS = ping_arrivals(log, scenario)
    assert_allclose(tau[:3], [[0.1, 0.3]] * 3, rtol=1e-12)  # ceil(0.7/0.5) = ceil(0.9/0.5) = 2
    assert np.isnan(tau[5, 1]) and np.isnan(tau[9, 0]) and np.isnan(tau[-2:]).all()
    assert np.isfinite(tau[:-2]).sum() == 2 * (STEPS - 2) - 2
    assert (lag[np.isfinite(tau)] == 2).all()
    k = 7
    assert_allclose(p_TS[k], log["p_TS_W"][k + 2].reshape(2, 3))
    # The geometry at the ping is that of the interfaces' interpolation between ticks k, k + 1.
    p_U, v_U, p_T, v_T = (log[name][k : k + 2] for name in ("p_WU", "v_WU", "p_WT", "v_WT"))
    for i, (tau_i, sign) in enumerate(((0.1, 0.5), (0.3, -0.5))):
        s = tau_i / T
        q = interpolate_position(p_U[0], v_U[0], p_U[1], v_U[1], s, T)
        q = q - interpolate_position(p_T[0], v_T[0], p_T[1], v_T[1], s, T)
        q_s = interpolate_attitude(log["R_WB"][k], log["R_WB"][k + 1], s) @ [-1.0, 1.0, 0.0]
        assert_allclose(p_TS[k, i], q + sign * q_s, rtol=1e-12, atol=1e-12)


def test_ping_arrivals_of_a_batch_are_each_runs() -> None:
    """Two runs as a batch log (dropped pings in one): each run's arrivals as alone; a run
    whose sonar's ping of one step arrives twice is refused."""
    scenario = _scenario("sonar.ping_offsets=[0.1, 0.3]", "sonar.latency=0.6")
    runs = [_synthetic_log(scenario, 1, dropped={(5, 1)}), _synthetic_log(scenario, 2)]
    log = {name: np.stack([run[name] for run in runs]) for name in runs[0]}
    batch = ping_arrivals(log, scenario)
    for i, run in enumerate(runs):
        for part, alone in zip(batch, ping_arrivals(run, scenario), strict=True):
            assert np.array_equal(part[i], alone, equal_nan=True)
    log["ping_time"][1, 12, 0] = log["ping_time"][1, 11, 0]
    with pytest.raises(ValueError, match="log: a sonar's ping of one step arrives twice"):
        ping_arrivals(log, scenario)


def test_without_errors_the_bound_is_todays_to_the_bit_and_the_extension_to_rounding() -> None:
    scenario = _scenario(NO_ERRORS)
    log = _synthetic_log(scenario)
    assert not bound_errors_on(scenario)
    metrics = bound_metrics(log, scenario)
    assert sorted(metrics) == sorted(f"{name}_{part}_rmse" for name in ("pcrlb", "kf_riccati")
                                     for part in ("position", "velocity"))  # fmt: skip
    q = log["p_WU"] - log["p_WT"]
    today = pcrlb_along_trajectory(q, log["b_W"], np.eye(6), W, ETA, 1, T)
    assert np.array_equal(bound_covariances(log, scenario)["pcrlb"], today)
    bound, floor = extended_bound(log, scenario)  # the same run through the extended path
    assert np.abs(bound - today).max() <= 1e-12 * np.abs(today).max()
    assert not floor.any()
    # Without the sonar's timing keys (today's logs): the same.
    for key in ("ping_time", "p_TS_W"):
        del log[key]
    assert np.abs(extended_bound(log, scenario)[0] - today).max() <= 1e-12 * np.abs(today).max()


ERRORS = {
    "attitude noise, commanded": [
        "navigation=!InertialNavigation {heading_bias_deg: 0, velocity_noise: 0, velocity_bias: 0}"
    ],
    "attitude noise, navigation": [
        "navigation=!InertialNavigation {heading_bias_deg: 0, velocity_noise: 0, velocity_bias: 0}",
        "estimator.vehicle_motion=navigation",
    ],
    "dvl": [
        "navigation=!InertialNavigation {attitude_noise_deg: [0, 0, 0], heading_bias_deg: 0}",
        "estimator.vehicle_motion=navigation",
    ],
    "heading bias": [
        "navigation=!InertialNavigation {attitude_noise_deg: [0, 0, 0], velocity_noise: 0, velocity_bias: 0}"  # noqa: E501
    ],
    "sound speed": ["sonar.sound_speed_error=0.005"],
    "latency": ["sonar.latency=0.7"],
    "all": [
        "navigation=!InertialNavigation",
        "sonar.latency=0.7",
        "sonar.sound_speed_error=-0.01",
    ],
}


@pytest.mark.parametrize("name", ERRORS)
def test_each_error_raises_the_bound_above_todays(name: str) -> None:
    base = _scenario()
    scenario = _scenario(*ERRORS[name])
    log = _synthetic_log(scenario)
    assert bound_errors_on(scenario)
    today = bound_covariances(_synthetic_log(base), base)["pcrlb"]  # the same trajectory
    bounds = bound_covariances(log, scenario)
    assert _psd_le(today, bounds["pcrlb"])
    metrics, before = bound_metrics(log, scenario), bound_metrics(_synthetic_log(base), base)
    assert metrics["pcrlb_position_rmse"] > before["pcrlb_position_rmse"]
    riccati = bound_metrics(log, base)["kf_riccati_position_rmse"]  # today's, on this log
    assert metrics["kf_riccati_position_rmse"] == riccati
    floor = bounds["pcrlb_floor"]
    assert _psd_le(floor, bounds["pcrlb"])
    assert set(metrics) - set(before) == {"pcrlb_floor_position_rmse", "pcrlb_floor_velocity_rmse"}


def test_the_floors_are_their_closed_forms_on_the_run() -> None:
    sigma, epsilon = math.radians(3.0), 0.02
    scenario = _scenario(
        "navigation=!InertialNavigation {attitude_noise_deg: [0, 0, 0], heading_bias_deg: 3.0, "
        "velocity_noise: 0, velocity_bias: 0}",
        f"sonar.sound_speed_error={epsilon}",
    )
    log = _synthetic_log(scenario)
    q, v = log["p_WU"] - log["p_WT"], log["v_WU"] - log["v_WT"]
    floor = bound_covariances(log, scenario)["pcrlb_floor"]
    position = sigma**2 * np.sum(q[:, :2] ** 2, axis=1) + epsilon**2 * np.sum(q**2, axis=1)
    velocity = sigma**2 * np.sum(v[:, :2] ** 2, axis=1)
    assert_allclose(np.trace(floor[:, :3, :3], axis1=1, axis2=2), position, rtol=1e-12)
    assert_allclose(np.trace(floor[:, 3:, 3:], axis1=1, axis2=2), velocity, rtol=1e-12)
    metrics = bound_metrics(log, scenario)
    assert metrics["pcrlb_floor_position_rmse"] == pytest.approx(
        math.sqrt(np.mean(position[START:])), rel=1e-12
    )
    # The bound is the information's bound plus the floors: the same with the floors off.
    info = bound_metrics(log, _scenario(NO_ERRORS))["pcrlb_position_rmse"]
    assert metrics["pcrlb_position_rmse"] ** 2 == pytest.approx(
        info**2 + metrics["pcrlb_floor_position_rmse"] ** 2, rel=1e-9
    )


def test_the_dvl_drives_the_position_and_adds_its_variance_to_the_velocity() -> None:
    scenario = _scenario(*ERRORS["dvl"])
    log = _synthetic_log(scenario)
    variance = 0.01**2 + 0.005**2
    q = log["p_WU"] - log["p_WT"]
    p_TS = np.stack([q + 0.5 * log["b_W"], q - 0.5 * log["b_W"]], axis=1)
    noise = np.broadcast_to(np.diag(ETA), (STEPS, 2, 2))
    expected = pcrlb_timed(np.zeros((STEPS, 2)), np.zeros((STEPS, 2), int), p_TS, noise,
                           np.eye(6), W, T, position_noise=T * T * variance)  # fmt: skip
    expected[:, 3:, 3:] += variance * np.eye(3)
    assert_allclose(extended_bound(log, scenario)[0], expected, rtol=1e-12, atol=1e-15)
    commanded = extended_bound(log, _scenario(*ERRORS["dvl"][:1]))[0]  # the DVL unused
    assert_allclose(commanded, bound_covariances(log, _scenario())["pcrlb"], rtol=1e-10)


def _range_derivative(q: np.ndarray, offset: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """``∂|q + Exp(θ) offset|/∂θ`` at θ = 0, by central differences."""

    def distance(theta: np.ndarray) -> float:
        return float(np.linalg.norm(q + exp_so3(theta) @ offset))

    return np.array([(distance(h * axis) - distance(-h * axis)) / (2 * h) for axis in np.eye(3)])


def test_the_attitude_noise_enters_the_ranges_and_the_commanded_acceleration() -> None:
    """Against the bound built from the pieces: ``J`` by finite differences of the ranges at
    each ping's geometry (its baseline turned at the step's rate), ``W + [a]× Σ_θ [a]×ᵀ``."""
    timing = ["sonar.ping_offsets=[0.1, 0.3]"]
    scenario = _scenario(*ERRORS["attitude noise, commanded"], *timing)
    log = _synthetic_log(scenario)
    tau, lag, p_TS = ping_arrivals(log, scenario)
    Sigma = rotation_vector_covariance(log["R_WB"], np.radians([0.5, 0.5, 2.0]))
    noise = np.zeros((STEPS, 2, 2))
    for k in range(STEPS - 1):  # the last step's pings arrive after the run
        J = np.zeros((2, 3))
        for i, sign in enumerate((0.5, -0.5)):
            q_s = exp_so3(log["u2_W"][k] * tau[k, i]) @ log["R_WB"][k] @ [-1.0, 1.0, 0.0]
            J[i] = _range_derivative(p_TS[k, i] - sign * q_s, sign * q_s)
        noise[k] = np.diag(ETA) + J @ Sigma[k] @ J.T
    Ws = W + np.stack([hat(a) @ S @ hat(a).T for a, S in zip(log["u1_W"], Sigma, strict=True)])
    expected = pcrlb_timed(tau, lag, p_TS, noise, np.eye(6), Ws, T)
    assert_allclose(extended_bound(log, scenario)[0], expected, rtol=1e-7, atol=1e-12)
    timed = _scenario(*timing)  # the same timing without the attitude noise: below
    assert _psd_le(extended_bound(log, timed)[0], expected)


def test_with_navigated_motion_the_attitude_noise_turns_the_navigated_velocity() -> None:
    """``Σ_ev = [v]× Σ_θ [v]×ᵀ`` on the true velocity: the position's walk ``t² Σ_ev`` per
    step and ``Σ_ev`` on the velocity block (the commanded acceleration unused)."""
    scenario = _scenario(*ERRORS["attitude noise, navigation"])
    log = _synthetic_log(scenario)
    tau, lag, p_TS = ping_arrivals(log, scenario)
    Sigma = rotation_vector_covariance(log["R_WB"], np.radians([0.5, 0.5, 2.0]))
    noise = np.zeros((STEPS, 2, 2))
    for k in range(STEPS):  # the paper's timing: both pings at the tick
        J = np.stack([_range_derivative(p_TS[k, i] - sign * log["b_W"][k], sign * log["b_W"][k])
                      for i, sign in enumerate((0.5, -0.5))])  # fmt: skip
        noise[k] = np.diag(ETA) + J @ Sigma[k] @ J.T
    velocity = np.stack([hat(v) @ S @ hat(v).T for v, S in zip(log["v_WU"], Sigma, strict=True)])
    expected = pcrlb_timed(tau, lag, p_TS, noise, np.eye(6), W, T, position_noise=T * T * velocity)
    expected[:, 3:, 3:] += velocity
    assert_allclose(extended_bound(log, scenario)[0], expected, rtol=1e-7, atol=1e-12)


def test_the_timed_bound_reads_the_logs_pings() -> None:
    """Against the models' recursion on the pings the synthetic log was built from."""
    scenario = _scenario("sonar.ping_offsets=[0.1, 0.3]", "sonar.latency=0.6")
    log = _synthetic_log(scenario, dropped={(5, 1)})
    tau = np.tile([0.1, 0.3], (STEPS, 1))
    tau[5, 1] = tau[-2:] = np.nan
    p_TS = np.full((STEPS, 2, 3), np.nan)
    p_TS[:-2] = log["p_TS_W"][2:].reshape(-1, 2, 3)
    noise = np.broadcast_to(np.diag(ETA), (STEPS, 2, 2))
    expected = pcrlb_timed(tau, np.full((STEPS, 2), 2), p_TS, noise, np.eye(6), W, T)
    assert_allclose(bound_covariances(log, scenario)["pcrlb"], expected, rtol=1e-9, atol=1e-14)


def test_sonar_timing_without_the_sonars_keys_is_refused() -> None:
    scenario = _scenario("sonar.latency=0.6")
    log = _synthetic_log(scenario)
    del log["p_TS_W"]
    with pytest.raises(ValueError, match=r"log: has no 'ping_time' and 'p_TS_W'.* latency 0.6"):
        bound_metrics(log, scenario)


def test_the_nees_of_a_covariance_that_is_not_positive_definite_is_infinite() -> None:
    """``eᵀ P⁻¹ e`` where P is positive definite; where it lost definiteness (an eigenvalue
    below zero, a NaN, or a condition number past the rounding) the NEES is ``inf``, never a
    negative number."""
    scenario = _scenario()
    log = _synthetic_log(scenario)
    rng = np.random.default_rng(3)
    L = rng.normal(size=(STEPS, 6, 6))
    log["P_TU"] = L @ np.swapaxes(L, 1, 2) + 0.1 * np.eye(6)
    log["x_TU_hat"] = rng.normal(size=(STEPS, 6))
    log["P_TU"][3] = np.diag([1.0, 1.0, 1.0, 1.0, 1.0, -1e-3])
    log["P_TU"][5, 0, 0] = np.nan
    log["P_TU"][7] = np.diag([1e17, 1.0, 1.0, 1.0, 1.0, 1.0])  # P⁻¹ below rounding
    nees = errors(log, scenario)["nees"]
    e = np.concatenate([log["p_WU"] - log["p_WT"], log["v_WU"] - log["v_WT"]], 1) - log["x_TU_hat"]
    for k in range(STEPS):
        expected = math.inf if k in (3, 5, 7) else e[k] @ np.linalg.inv(log["P_TU"][k]) @ e[k]
        assert nees[k] == pytest.approx(expected, rel=1e-9)
