"""HoveringAuvPlant: the plant contract, the paper's step reproduced by thrusters, and its figures."""

import dataclasses

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pydrake.math import RollPitchYaw, RotationMatrix
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, LogVectorOutput

from drake_uuv.analysis.figures import save_figure
from drake_uuv.analysis.vehicle_figures import (
    attitude_errors,
    attitude_tracking_figure,
    roll_pitch_yaw,
    thrust_figure,
    wrap_angles,
)
from drake_uuv.models.motion import double_integrator
from drake_uuv.models.so3 import exp_so3, log_so3
from drake_uuv.plants import PlantSetting
from drake_uuv.plants.hovering_auv import HoveringAuvPlant
from drake_uuv.scenario import ScenarioError, load_scenario
from drake_uuv.scenario.plants import HoveringAuv
from tests.conftest import T

INPUTS = {"u1_B": 3, "u2_W": 3}
OUTPUTS = {
    "p_WU": 3, "v_WU": 3, "R_WB": 9, "w_WB": 3, "nu_B": 6, "thrust": 8, "thrust_command": 8,
    "R_WB_command": 9, "w_WB_command": 3, "v_WU_command": 3, "wrench_command": 6,
    "allocation_scale": 2, "saturation_ticks": 4,
}  # fmt: skip


def make_plant(config: HoveringAuv | None = None, **setting) -> HoveringAuvPlant:
    """The vehicle of ``config`` (default: HoloOcean's), at a yaw of 0.3 rad unless
    ``setting`` says otherwise."""
    args = dict(
        time_step=T,
        initial_position=np.array([1.0, -2.0, 3.0]),
        initial_velocity=np.array([0.1, 0.0, -0.05]),
        initial_R_WB=RotationMatrix(RollPitchYaw(0.0, 0.0, 0.3)).matrix(),
    )
    return HoveringAuvPlant(config or HoveringAuv(), setting=PlantSetting(**{**args, **setting}))


INTEGRATORS = {
    "runge_kutta3": ["stepped_vehicle"],
    "runge_kutta5": ["vehicle", "low_level_controller"],
}


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_ports_and_systems(integrator: str) -> None:
    plant = make_plant(HoveringAuv(integrator=integrator))
    assert {plant.get_input_port(i).get_name(): plant.get_input_port(i).size()
            for i in range(plant.num_input_ports())} == INPUTS  # fmt: skip
    assert {plant.get_output_port(i).get_name(): plant.get_output_port(i).size()
            for i in range(plant.num_output_ports())} == OUTPUTS  # fmt: skip
    assert [s.get_name() for s in plant.GetSystems()] == INTEGRATORS[integrator]
    assert plant.period == pytest.approx(0.02)
    # The outer loop's feedthrough outputs read p_WU, v_WU, R_WB: none may depend on u1, u2.
    assert not plant.HasAnyDirectFeedthrough()
    # Stepped inside the plant, the vehicle has no continuous state for Drake to integrate.
    context = plant.CreateDefaultContext()
    assert context.num_continuous_states() == (13 if integrator == "runge_kutta5" else 0)


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_initial_outputs_are_the_initial_state(integrator: str) -> None:
    plant = make_plant(HoveringAuv(integrator=integrator))
    context = plant.CreateDefaultContext()
    R0 = RotationMatrix(RollPitchYaw(0.0, 0.0, 0.3)).matrix()
    assert_allclose(plant.GetOutputPort("p_WU").Eval(context), [1.0, -2.0, 3.0])
    assert_allclose(plant.GetOutputPort("v_WU").Eval(context), [0.1, 0.0, -0.05], atol=1e-15)
    assert_allclose(plant.GetOutputPort("R_WB").Eval(context).reshape(3, 3), R0, atol=1e-15)
    assert_allclose(plant.GetOutputPort("R_WB_command").Eval(context).reshape(3, 3), R0)


def simulate(plant: HoveringAuvPlant, u1: np.ndarray, u2: np.ndarray, steps: int):
    builder = DiagramBuilder()
    builder.AddSystem(plant)
    for name, value in (("u1_B", u1), ("u2_W", u2)):
        source = builder.AddSystem(ConstantVectorSource(value))
        builder.Connect(source.get_output_port(), plant.GetInputPort(name))
    names = ("p_WU", "v_WU", "R_WB", "R_WB_command", "w_WB", "w_WB_command", "thrust")
    loggers = {n: LogVectorOutput(plant.GetOutputPort(n), builder, T) for n in names}
    simulator = Simulator(builder.Build())
    plant.configure_simulator(simulator)
    simulator.AdvanceTo(steps * T - 1e-9)
    context = simulator.get_context()
    log = {n: logger.FindLog(context).data().T for n, logger in loggers.items()}
    log["time"] = loggers["p_WU"].FindLog(context).sample_times()
    return log


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_thrusters_reproduce_the_papers_step(integrator: str) -> None:
    # X(k+1) = A X(k) + B R(k) u1, R(k+1) = Exp(u2 t) R(k) (paper eqs. 1–2), each step from the
    # state the vehicle actually reached. Gentle commands: the loop is unsaturated.
    u1, u2 = np.array([0.1, -0.05, 0.03]), np.array([0.05, -0.1, 0.2])
    log = simulate(make_plant(HoveringAuv(integrator=integrator)), u1, u2, 9)
    A, B = double_integrator(T)
    for k in range(1, 8):
        R = log["R_WB"][k].reshape(3, 3)
        x = np.concatenate([log["p_WU"][k], log["v_WU"][k]])
        x_next = A @ x + B @ (R @ u1)
        # Steps of 0.09–0.25 m and 0.06 m/s; the attitude turns 0.11 rad per step.
        assert np.linalg.norm(log["p_WU"][k + 1] - x_next[:3]) < 1e-4
        assert np.linalg.norm(log["v_WU"][k + 1] - x_next[3:]) < 3e-4
        R_next = exp_so3(u2 * T) @ R
        assert np.linalg.norm(log_so3(log["R_WB"][k + 1].reshape(3, 3) @ R_next.T)) < 3e-4
    # The commanded attitude published at k + 1 is the target R(k+1) set at k. The first step
    # starts the rotation from rest (rate step 0.23 rad/s, lag Δω t e^(−ωt) ≈ 2e-3 rad).
    errors = attitude_errors(log)
    assert errors[0] < 1e-12 and errors[1] < 2.2e-3 and errors[2:].max() < 3e-4
    assert np.abs(log["thrust"]).max() < HoveringAuv().max_thrust


@pytest.mark.slow
def test_figures_are_written(tmp_path) -> None:
    log = simulate(make_plant(), np.array([0.3, 0.0, 0.0]), np.array([0.0, 0.3, 0.6]), 12)
    scenario = load_scenario("paper", ["plant=!HoveringAuv", "steps=12", "steady_state_start=2"])
    for name, figure in (
        ("attitude", attitude_tracking_figure(log, scenario)),
        ("thrusts", thrust_figure(log, scenario)),
    ):
        (path,) = save_figure(figure, tmp_path / name, ("png",))
        assert path.stat().st_size > 10_000


def test_wrapped_angles_stay_within_pi_of_their_command() -> None:
    """Unwrapped, a command and an achieved angle 0.1 rad apart can be drawn 2π + 0.1 apart;
    wrapped, the gap drawn is 0.1, and the lines break (a NaN row) where the command crosses
    ±π, between 3.1 and 3.2 rad (= 3.2 − 2π), not across the panel."""
    time = np.arange(5.0)
    commanded = np.array([3.0, 3.1, 3.2, 3.3, -1.0])
    achieved = commanded - 0.1 + 2.0 * np.pi * np.array([0, 1, -1, 3, -2])
    shown_time, shown_command, shown = wrap_angles(time, commanded, achieved)
    assert np.flatnonzero(np.isnan(shown_command)).tolist() == [2]
    assert np.flatnonzero(np.isnan(shown)).tolist() == [2]
    assert np.flatnonzero(np.isnan(shown_time)).tolist() == [2]
    keep = ~np.isnan(shown_time)
    assert_allclose(shown_time[keep], time)
    assert_allclose(shown_command[keep], [3.0, 3.1, 3.2 - 2 * np.pi, 3.3 - 2 * np.pi, -1.0])
    assert_allclose(shown_command[keep] - shown[keep], 0.1, atol=1e-12)


def test_roll_pitch_yaw_matches_drake() -> None:
    rng = np.random.default_rng(3)
    rpy = rng.uniform([-3, -1.5, -3], [3, 1.5, 3], size=(10, 3))
    rows = np.array([RotationMatrix(RollPitchYaw(r)).matrix().ravel() for r in rpy])
    assert_allclose(roll_pitch_yaw(rows), rpy, atol=1e-12)


@pytest.mark.parametrize(
    "kwargs, error, message",
    [
        (dict(time_step=-0.5), ValueError, r"^time_step: must be > 0, got -0\.5$"),
        (dict(initial_R_WB=np.ones((3, 3))), ValueError, r"^initial_R_WB: must be a rotation"),
        (dict(initial_R_WB=-np.eye(3)), ValueError, r"^initial_R_WB: must be a rotation"),
        (
            dict(initial_position=np.array([0, 0, np.inf])),
            ValueError,
            r"^initial_position: must be 3 finite numbers",
        ),
        (
            dict(config=dataclasses.replace(HoveringAuv(), mass=-1.0)),
            ScenarioError,
            r"^config\.mass: must be > 0, got -1\.0$",
        ),
    ],
)
def test_bad_constructor_arguments_name_the_parameter(
    kwargs: dict, error: type, message: str
) -> None:
    with pytest.raises(error, match=message):
        make_plant(**kwargs)
