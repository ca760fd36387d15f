"""LowLevelController: latching, the computed-torque law, and the designed closed-loop response."""

import dataclasses
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pydrake.math import RollPitchYaw, RotationMatrix
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, LogVectorOutput

from drake_uuv.models.so3 import exp_so3, log_so3
from drake_uuv.plants import PlantSetting
from drake_uuv.plants.hovering_auv import HoveringAuvPlant, configure_simulator
from drake_uuv.plants.low_level_controller import LowLevelController
from drake_uuv.scenario import ScenarioError
from drake_uuv.scenario.plants import HoveringAuv
from drake_uuv.testing import discrete_update, fixed_context
from tests.conftest import T

LATCH, TARGET, RATE, VELOCITY, THRUST, WRENCH, SCALE = range(7)
OUTPUTS = {
    "thrust_command": 8,
    "R_WB_command": 9,
    "w_WB_command": 3,
    "v_WU_command": 3,
    "wrench_command": 6,
    "allocation_scale": 2,
    "saturation_ticks": 4,
}


def test_ports_period_and_gains() -> None:
    config = HoveringAuv(controller_rate=30.0)
    controller = LowLevelController(config, outer_period=T, initial_R_WB=np.eye(3))
    assert [controller.get_input_port(i).get_name() for i in range(4)] == [
        "u1_B", "u2_W", "R_WB", "nu_B",
    ]  # fmt: skip
    assert {controller.get_output_port(i).get_name(): controller.get_output_port(i).size()
            for i in range(controller.num_output_ports())} == OUTPUTS  # fmt: skip
    assert not controller.HasAnyDirectFeedthrough()  # all held state: breaks every loop
    assert controller.period == pytest.approx(T / 15)  # 30 Hz → 15 ticks per outer step
    M = config.vehicle_model().M
    gains = controller.gains()
    assert_allclose(gains["attitude_stiffness"], 64.0 * M[3:, 3:])  # M_rot ω², ω = 8 rad/s
    assert_allclose(gains["attitude_damping"], 16.0 * M[3:, 3:])  # 2ζω M_rot, ζ = 1
    assert_allclose(gains["velocity"], 4.0 * M[:3, :3])  # M_trans ω_v


def controller_context(controller: LowLevelController, time: float, nu: np.ndarray, R: np.ndarray):
    context = fixed_context(
        controller,
        u1_B=np.array([0.4, -0.2, 0.3]),
        u2_W=np.array([0.1, 0.2, -0.3]),
        R_WB=R.ravel(),
        nu_B=nu,
    )
    context.SetTime(time)
    return context


def test_an_outer_tick_uses_the_fresh_command_and_other_ticks_the_latch() -> None:
    config = HoveringAuv()
    model = config.vehicle_model()
    R = RotationMatrix(RollPitchYaw(0.0, 0.0, 0.8)).matrix()  # upright: no restoring moment
    controller = LowLevelController(config, outer_period=T, initial_R_WB=R)
    u1, u2 = np.array([0.4, -0.2, 0.3]), np.array([0.1, 0.2, -0.3])
    for time in (0.0, T, 7 * T):  # outer ticks
        context = controller_context(controller, time, np.zeros(6), R)
        latch = discrete_update(controller, context, LATCH)
        assert_allclose(latch[:3], R @ u1)
        assert latch[15] == time
        assert_allclose(discrete_update(controller, context, RATE), u2)
        assert_allclose(
            discrete_update(controller, context, TARGET).reshape(3, 3), exp_so3(u2 * T) @ R
        )
        # At rest, ν̇_des is the body acceleration Rᵀ a_W and the rate step 2ζω (u2 − 0) as
        # angular acceleration (the attitude error is 0 at s = 0); the wrench adds the bias
        # C ν + D ν + g at the mid-period velocity ½ h ν̇_des.
        nu_dot = np.concatenate([u1, R.T @ (16.0 * u2)])
        expected = model.M @ nu_dot + model.bias_force(0.01 * nu_dot, R)
        assert_allclose(discrete_update(controller, context, WRENCH), expected, atol=1e-12)
        thrust = discrete_update(controller, context, THRUST)
        assert_allclose(config.allocator().A @ thrust, expected, atol=1e-11)
    # Between outer ticks the inputs are ignored: the default latch (no acceleration, rate 0,
    # R(kt) = R) holds the vehicle at rest, whatever the outer loop's ports now say.
    context = controller_context(controller, 0.02, np.zeros(6), R)
    assert_allclose(discrete_update(controller, context, WRENCH), 0.0, atol=1e-12)
    assert_allclose(discrete_update(controller, context, LATCH)[:3], 0.0)


def test_one_update_is_the_computed_torque_law() -> None:
    config = HoveringAuv()
    model = config.vehicle_model()
    R_k = RotationMatrix(RollPitchYaw(0.2, -0.1, 0.5)).matrix()
    controller = LowLevelController(config, outer_period=T, initial_R_WB=R_k)
    context = controller_context(controller, 0.1, np.zeros(6), R_k)
    # A latched step k at t_k = 0: a_W, v(kt), R(kt), and u2 in force; now s = 0.1 s.
    a_W, v_k, u2 = np.array([0.3, -0.1, 0.2]), np.array([0.2, 0.1, 0.0]), np.array([0.2, -0.1, 0.4])
    context.SetDiscreteState(LATCH, np.concatenate([a_W, v_k, R_k.ravel(), [0.0]]))
    context.SetDiscreteState(RATE, u2)
    R = exp_so3(np.array([0.01, 0.02, 0.05])) @ R_k  # the vehicle, somewhat behind
    nu = np.array([0.25, 0.05, -0.02, 0.1, -0.05, 0.3])
    controller.GetInputPort("R_WB").FixValue(context, R.ravel())
    controller.GetInputPort("nu_B").FixValue(context, nu)
    s = 0.1
    e = log_so3(exp_so3(u2 * s) @ R_k @ R.T)
    alpha_W = 64.0 * e + 16.0 * (u2 - R @ nu[3:])
    a_cmd = a_W + 4.0 * (v_k + a_W * s - R @ nu[:3])
    nu_dot = np.concatenate([R.T @ a_cmd - np.cross(nu[3:], nu[:3]), R.T @ alpha_W])
    nu_mid = nu + 0.01 * nu_dot  # half a 50 Hz period ahead
    expected = (
        model.M @ nu_dot
        + model.coriolis_matrix(nu_mid) @ nu_mid
        + model.damping_force(nu_mid)
        + model.restoring_force(R)
    )
    assert_allclose(discrete_update(controller, context, WRENCH), expected, rtol=1e-12, atol=1e-12)
    assert_allclose(discrete_update(controller, context, VELOCITY), v_k + a_W * s)
    assert_allclose(discrete_update(controller, context, SCALE), [1.0, 1.0])


def run_plant(config: HoveringAuv, outer_period: float, u1: np.ndarray, u2: np.ndarray,
              duration: float, rpy=(0.0, 0.0, 0.0), log_period: float = 0.005):  # fmt: skip
    """HoveringAuvPlant under constant commands; returns (times, R_WB rows, v_WU rows). The
    continuous vehicle (``runge_kutta5``): the responses are read between outer ticks."""
    config = dataclasses.replace(config, integrator="runge_kutta5")
    builder = DiagramBuilder()
    R0 = RotationMatrix(RollPitchYaw(np.array(rpy))).matrix()
    setting = PlantSetting(outer_period, np.zeros(3), np.zeros(3), R0)
    plant = builder.AddSystem(HoveringAuvPlant(config, setting=setting))
    for name, value in (("u1_B", u1), ("u2_W", u2)):
        source = builder.AddSystem(ConstantVectorSource(value))
        builder.Connect(source.get_output_port(), plant.GetInputPort(name))
    loggers = {
        name: LogVectorOutput(plant.GetOutputPort(name), builder, log_period)
        for name in ("R_WB", "v_WU", "allocation_scale")
    }
    simulator = Simulator(builder.Build())
    configure_simulator(simulator, config, outer_period)
    simulator.AdvanceTo(duration)
    logs = {name: log.FindLog(simulator.get_context()) for name, log in loggers.items()}
    return logs["R_WB"].sample_times(), {n: log.data().T for n, log in logs.items()}


def second_order_step(zeta: float, omega: float, t: np.ndarray) -> np.ndarray:
    """Unit-step response of ë + 2ζω ė + ω² e = 0 from e = 1: the fraction of the step done."""
    if zeta < 1.0:
        wd = omega * math.sqrt(1 - zeta**2)
        return 1 - np.exp(-zeta * omega * t) * (np.cos(wd * t) + zeta * omega / wd * np.sin(wd * t))
    if zeta == 1.0:
        return 1 - (1 + omega * t) * np.exp(-omega * t)
    r1, r2 = -omega * (zeta - math.sqrt(zeta**2 - 1)), -omega * (zeta + math.sqrt(zeta**2 - 1))
    return 1 - (r2 * np.exp(r1 * t) - r1 * np.exp(r2 * t)) / (r2 - r1)


def sampled_step(zeta: float, omega: float, h: float, steps: int) -> np.ndarray:
    """The same loop with the acceleration ω² e + 2ζω ė held over periods h (exact)."""
    e, e_dot, done = 1.0, 0.0, []
    for _ in range(steps):
        u = omega**2 * e + 2 * zeta * omega * e_dot
        e, e_dot = e + h * e_dot - 0.5 * h * h * u, e_dot - h * u
        done.append(1.0 - e)
    return np.array(done)


@pytest.mark.parametrize("zeta, axis", [(1.0, [0, 0, 1]), (0.6, [0, 0, 1]), (0.6, [1, 0, 0])])
def test_attitude_step_response_has_the_designed_rise_time_and_overshoot(
    zeta: float, axis: list
) -> None:
    # "step" reference: from kt the controller regulates to R(k+1) = Exp(u2 t) R(kt). With an
    # outer period of 2 s the response to a 0.3 rad step is seen whole. The design says the
    # attitude error obeys ë + 2ζω ė + ω² e = 0: 90 % of the step at the linear model's t90
    # (3.89/ω for ζ = 1), overshoot exp(−πζ/√(1−ζ²)) (9.5 % for ζ = 0.6, none for ζ = 1).
    omega, angle, outer = 8.0, 0.3, 2.0
    config = HoveringAuv(attitude_reference="step", attitude_damping_ratio=zeta)
    axis = np.array(axis, dtype=float)
    times, log = run_plant(config, outer, np.zeros(3), axis * angle / outer, 1.9)
    progress = np.array([log_so3(R.reshape(3, 3)) @ axis / angle for R in log["R_WB"]])
    assert np.all(log["allocation_scale"] == 1.0)  # the design holds while unsaturated
    fine = np.linspace(0.0, 1.9, 19001)
    linear = second_order_step(zeta, omega, fine)
    t90_linear = fine[np.argmax(linear >= 0.9)]
    t90 = times[np.argmax(progress >= 0.9)]
    h = config.controller_period(outer)
    assert abs(t90 - t90_linear) <= h
    # Holding the acceleration over h (ωh = 0.16) makes the loop slightly faster and adds
    # < 1 % of overshoot; the sampled model of the same law predicts it.
    sampled = sampled_step(zeta, omega, h, round(1.9 / h))
    assert abs(progress.max() - sampled.max()) < 0.01
    assert progress.max() - 1.0 <= linear.max() - 1.0 + 0.015
    if zeta < 1.0:
        assert progress.max() - 1.0 >= linear.max() - 1.0
    assert abs(progress[-1] - 1.0) < 0.001


def test_trajectory_reference_matches_the_sampled_linear_design() -> None:
    # "trajectory" reference with the rate u2 fed forward. For a small angle the error of the
    # reference ahead of the vehicle is the double integrator ë = −u with u(t_i) = ω² e(t_i)
    # + 2ζω ė(t_i) held over each fast period (computed torque cancels the rest): simulate
    # that scalar loop exactly and compare.
    config = HoveringAuv()
    u2 = np.array([0.0, 0.0, 0.4])
    times, log = run_plant(config, T, np.zeros(3), u2, 4 * T - 1e-9, log_period=T)
    h, omega = config.controller_period(T), 8.0
    # The reference restarts at each kt from the achieved attitude, so the error e restarts
    # at 0 while its rate carries over: at k = 0 the whole rate 0.4 rad/s is a step, later
    # only what the loop has not yet absorbed. Each step adds e(t) to the lag.
    e_dot, lags = 0.4, []
    for _ in range(3):
        e = 0.0
        for _ in range(round(T / h)):
            u = omega**2 * e + 2 * omega * e_dot
            e, e_dot = e + h * e_dot - 0.5 * h * h * u, e_dot - h * u
        lags.append(e)
    achieved = [
        log_so3(exp_so3(u2 * k * T).T @ R.reshape(3, 3))[2] for k, R in enumerate(log["R_WB"])
    ]
    assert_allclose(np.diff(achieved), -np.array(lags), rtol=0.05, atol=2e-6)
    # Continuous design: e(t) = Δω t e^(−ωt), 1.8 % of the step Δω t; sampled, 1.4 %.
    assert lags[0] < 0.4 * T * math.exp(-omega * T)
    assert abs(lags[1]) < 0.05 * lags[0]


def test_constant_body_acceleration_is_tracked_over_an_outer_step() -> None:
    config = HoveringAuv()
    u1 = np.array([0.2, -0.1, 0.05])
    times, log = run_plant(config, T, u1, np.zeros(3), 2 * T - 1e-9, log_period=T)
    # v((k+1)t) = v(kt) + R u1 t, the paper's double integrator (R stays I: u2 = 0).
    assert_allclose(log["v_WU"][1] - log["v_WU"][0], u1 * T, rtol=0.02, atol=1e-4)


def test_bad_constructor_arguments_name_the_parameter() -> None:
    with pytest.raises(ValueError, match=r"^outer_period: must be > 0, got 0\.0$"):
        LowLevelController(HoveringAuv(), outer_period=0.0, initial_R_WB=np.eye(3))
    with pytest.raises(ValueError, match=r"^initial_R_WB: must be a rotation matrix"):
        LowLevelController(HoveringAuv(), outer_period=T, initial_R_WB=np.ones((3, 3)))
    with pytest.raises(ScenarioError, match=r"^config\.max_thrust: must be > 0, got 0\.0$"):
        LowLevelController(
            dataclasses.replace(HoveringAuv(), max_thrust=0.0),
            outer_period=T,
            initial_R_WB=np.eye(3),
        )


def test_saturation_ticks_count_the_ticks_whose_wrench_was_scaled() -> None:
    """An impossible acceleration command saturates every tick; a zero command none."""
    for u1, saturated in ((np.zeros(3), False), (np.array([50.0, 0.0, 0.0]), True)):
        at_rest = PlantSetting(T, np.zeros(3), np.zeros(3), np.eye(3))
        plant = HoveringAuvPlant(HoveringAuv(), setting=at_rest)
        context = plant.CreateDefaultContext()
        plant.GetInputPort("u1_B").FixValue(context, u1)
        plant.GetInputPort("u2_W").FixValue(context, np.zeros(3))
        simulator = Simulator(plant, context)
        plant.configure_simulator(simulator)
        simulator.AdvanceTo(2.0)
        ticks, force_scaled, _, either = plant.GetOutputPort("saturation_ticks").Eval(context)
        # The stepped plant has run the ticks of the steps at 0, 0.5, 1 and 1.5 s.
        assert ticks == round(2.0 / plant.period)
        assert force_scaled == (pytest.approx(ticks) if saturated else 0.0)
        assert either >= force_scaled
