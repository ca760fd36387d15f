"""The paper's kinematic vehicle (eqs. 1–2): ports, one step in closed form, long runs."""

import dataclasses

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pydrake.common.eigen_geometry import AngleAxis
from pydrake.math import RollPitchYaw, RotationMatrix
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from drake_uuv.plants import KinematicUuvPlant, PlantSetting, make_plant, plant_setting
from drake_uuv.scenario import KinematicUuv, Scenario, load_scenario
from drake_uuv.testing import assert_batch_equals_runs, discrete_update, fixed_context
from tests.conftest import T


def plant_at(R0: np.ndarray | None = None) -> KinematicUuvPlant:
    R0 = np.eye(3) if R0 is None else R0
    setting = PlantSetting(T, np.array([1.0, -2.0, 3.0]), np.array([0.1, 0.2, -0.3]), R0)
    return KinematicUuvPlant(KinematicUuv(), setting=setting)


def test_ports() -> None:
    plant = plant_at()
    assert [plant.get_input_port(i).get_name() for i in range(2)] == ["u1_B", "u2_W"]
    assert plant.GetInputPort("u1_B").size() == 3 and plant.GetInputPort("u2_W").size() == 3
    outputs = [plant.get_output_port(i) for i in range(plant.num_output_ports())]
    assert [(p.get_name(), p.size()) for p in outputs] == [("p_WU", 3), ("v_WU", 3), ("R_WB", 9)]
    # Outputs depend on state only: the plant breaks every loop.
    assert not plant.HasAnyDirectFeedthrough()


def test_initial_outputs() -> None:
    R0 = RotationMatrix(RollPitchYaw(0.1, -0.4, 2.0)).matrix()
    plant = plant_at(R0)
    context = fixed_context(plant, u1_B=np.zeros(3), u2_W=np.zeros(3))
    assert_allclose(plant.GetOutputPort("p_WU").Eval(context), [1, -2, 3])
    assert_allclose(plant.GetOutputPort("v_WU").Eval(context), [0.1, 0.2, -0.3])
    assert_allclose(plant.GetOutputPort("R_WB").Eval(context).reshape(3, 3), R0, atol=1e-15)


def test_one_step_matches_equations_1_and_2() -> None:
    R0 = RotationMatrix(RollPitchYaw(0.3, 0.2, -0.5)).matrix()
    plant = plant_at(R0)
    u1, u2 = np.array([0.4, -1.0, 2.0]), np.array([0.3, -0.2, 0.9])
    context = fixed_context(plant, u1_B=u1, u2_W=u2)
    p1 = discrete_update(plant, context, group=0)
    v1 = discrete_update(plant, context, group=1)
    R1_plant = discrete_update(plant, context, group=2).reshape(3, 3)
    p0, v0 = np.array([1.0, -2.0, 3.0]), np.array([0.1, 0.2, -0.3])
    a = R0 @ u1  # eq. (1): B R(k) u1(k)
    assert_allclose(p1, p0 + T * v0 + 0.5 * T**2 * a, rtol=1e-14)
    assert_allclose(v1, v0 + T * a, rtol=1e-14)
    # eq. (2): R(k+1) = Exp(u2 t) R(k), left-multiplied: u2 is a world-frame rate.
    angle = np.linalg.norm(u2) * T
    R1 = RotationMatrix(AngleAxis(angle, u2 / np.linalg.norm(u2))).matrix() @ R0
    assert_allclose(R1_plant, R1, atol=1e-14)


@pytest.mark.slow
def test_attitude_stays_orthonormal_over_a_long_run() -> None:
    builder = DiagramBuilder()
    plant = builder.AddSystem(plant_at())
    u1 = builder.AddSystem(ConstantVectorSource(np.zeros(3)))
    w = builder.AddSystem(ConstantVectorSource(np.array([0.37, -1.21, 2.9])))
    builder.Connect(u1.get_output_port(), plant.GetInputPort("u1_B"))
    builder.Connect(w.get_output_port(), plant.GetInputPort("u2_W"))
    diagram = builder.Build()
    simulator = Simulator(diagram)
    steps = 20_000
    simulator.AdvanceTo(steps * T)
    context = plant.GetMyContextFromRoot(simulator.get_context())
    R = plant.GetOutputPort("R_WB").Eval(context).reshape(3, 3)
    assert_allclose(R.T @ R, np.eye(3), atol=1e-13)
    assert abs(np.linalg.det(R) - 1.0) < 1e-13
    # And it is the right rotation: a constant rate for N steps is Exp(N u2 t).
    w_W = np.array([0.37, -1.21, 2.9])
    expected = RotationMatrix(
        AngleAxis(np.linalg.norm(w_W) * T * steps % (2 * np.pi), w_W / np.linalg.norm(w_W))
    ).matrix()
    assert_allclose(R, expected, atol=1e-8)


def test_factory_builds_it_from_the_scenario() -> None:
    scenario = Scenario()
    scenario.uuv.initial_position = [4.0, 5.0, 6.0]
    scenario.uuv.initial_rpy = [0.0, 0.0, np.pi / 2]
    plant = make_plant(scenario)
    assert isinstance(plant, KinematicUuvPlant)
    context = fixed_context(plant, u1_B=np.zeros(3), u2_W=np.zeros(3))
    assert_allclose(plant.GetOutputPort("p_WU").Eval(context), [4, 5, 6])
    R = plant.GetOutputPort("R_WB").Eval(context).reshape(3, 3)
    assert_allclose(R @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-15)  # yaw 90°: x → y


def test_the_setting_is_checked_and_read_only() -> None:
    setting = plant_setting(load_scenario("paper", ["uuv.initial_rpy=[0.1, -0.2, 0.3]"]))
    assert_allclose(setting.initial_R_WB, RotationMatrix(RollPitchYaw(0.1, -0.2, 0.3)).matrix())
    assert setting.time_step == 0.5
    with pytest.raises(ValueError, match="read-only"):
        setting.initial_position[0] = 1.0
    for field, value, message in (
        ("time_step", 0.0, r"^time_step: must be > 0, got 0.0$"),
        ("initial_velocity", [1.0, 2.0], r"^initial_velocity: must be 3 finite numbers"),
        ("initial_R_WB", np.diag([1.0, 1.0, -1.0]), r"^initial_R_WB: must be a rotation matrix"),
    ):
        with pytest.raises(ValueError, match=message):
            dataclasses.replace(setting, **{field: value})


@pytest.mark.parametrize("batch_size", [1, 2, 7])
def test_a_batch_step_is_each_run_alone(batch_size: int) -> None:
    """Random batches: outputs and the update of B runs equal B single runs, bit for bit."""
    rng = np.random.default_rng(batch_size)
    R = np.array(
        [RotationMatrix(RollPitchYaw(rng.normal(size=3))).matrix() for _ in range(batch_size)]
    )
    states = [
        rng.normal(size=(batch_size, 3)),
        rng.normal(size=(batch_size, 3)),
        R.reshape(batch_size, 9),
    ]
    inputs = {"u1_B": rng.normal(size=(batch_size, 3)), "u2_W": rng.normal(size=(batch_size, 3))}
    inputs["u2_W"][0] = 0.0  # the small-angle branch of Exp beside the others
    scenario = Scenario()

    def make(B: int) -> KinematicUuvPlant:
        return KinematicUuvPlant(KinematicUuv(), setting=plant_setting(scenario), batch_size=B)

    assert_batch_equals_runs(make, inputs, states)


def test_a_bad_batch_size_is_named() -> None:
    with pytest.raises(ValueError, match=r"batch_size: must be an integer ≥ 1, got 0"):
        KinematicUuvPlant(KinematicUuv(), setting=plant_setting(Scenario()), batch_size=0)
