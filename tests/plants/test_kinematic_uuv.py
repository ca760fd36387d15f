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


# ------------------------------------------------------------------------- the top speed


def limited_plant(max_speed: float | None, batch_size: int = 1) -> KinematicUuvPlant:
    setting = PlantSetting(T, np.zeros(3), np.array([0.5, 0.0, 0.0]), np.eye(3))
    return KinematicUuvPlant(
        KinematicUuv(max_speed=max_speed), setting=setting, batch_size=batch_size
    )


def test_a_step_beyond_the_top_speed_reaches_it_in_the_asked_direction() -> None:
    # v = [0.5, 0, 0], a = [1, 0.8, 0] asks v + t a = [1, 0.4, 0] (|·| = 1.077); at 0.76 the
    # next velocity is that scaled onto the sphere, and p moves with the acceleration that
    # reaches it, a' = (v(k+1) − v)/t.
    plant = limited_plant(0.76)
    context = fixed_context(plant, u1_B=[1.0, 0.8, 0.0], u2_W=np.zeros(3))
    v0, asked = np.array([0.5, 0.0, 0.0]), np.array([1.0, 0.4, 0.0])
    v1 = 0.76 * asked / np.linalg.norm(asked)
    a = (v1 - v0) / T
    assert_allclose(discrete_update(plant, context, group=1), v1, rtol=1e-14)
    assert_allclose(discrete_update(plant, context, group=0), T * v0 + 0.5 * T**2 * a, atol=1e-15)
    assert np.linalg.norm(discrete_update(plant, context, group=1)) <= 0.76 * (1 + 1e-15)


def test_below_the_top_speed_the_step_is_the_paper_s_to_the_bit() -> None:
    u1 = {"u1_B": [0.3, -0.2, 0.1], "u2_W": [0.1, 0.2, 0.3]}  # |v(k+1)| = 0.67 < 0.76
    limited, free = limited_plant(0.76), limited_plant(None)
    for group in range(3):
        np.testing.assert_array_equal(
            discrete_update(limited, fixed_context(limited, **u1), group=group),
            discrete_update(free, fixed_context(free, **u1), group=group),
        )


@pytest.mark.parametrize("batch_size", [1, 2, 6])
def test_a_limited_batch_step_is_each_run_alone(batch_size: int) -> None:
    """Runs below, at and beyond the top speed, and a NaN command, in one batch."""
    rng = np.random.default_rng(20 + batch_size)
    R = np.array(
        [RotationMatrix(RollPitchYaw(rng.normal(size=3))).matrix() for _ in range(batch_size)]
    )
    velocities = rng.normal(scale=0.5, size=(batch_size, 3))
    states = [rng.normal(size=(batch_size, 3)), velocities, R.reshape(batch_size, 9)]
    u1 = rng.normal(size=(batch_size, 3)) * np.where(np.arange(batch_size) % 2, 0.01, 3.0)[:, None]
    if batch_size > 4:
        u1[-1, 1] = np.nan
    inputs = {"u1_B": u1, "u2_W": rng.normal(size=(batch_size, 3))}
    setting = plant_setting(Scenario())

    def make(B: int) -> KinematicUuvPlant:
        return KinematicUuvPlant(KinematicUuv(max_speed=0.76), setting=setting, batch_size=B)

    assert_batch_equals_runs(make, inputs, states)


@pytest.mark.parametrize("value", ["0", "-1.5", "nan", "true"])
def test_a_bad_top_speed_is_named(value: str) -> None:
    with pytest.raises(ValueError, match=r"^plant.max_speed: must be .*, got"):
        load_scenario("paper", [f"plant.max_speed={value}"])


def test_the_tracking_law_is_told_the_top_speed() -> None:
    from drake_uuv.tracking import tracking_setting

    assert tracking_setting(load_scenario("paper")).max_speed is None
    assert tracking_setting(load_scenario("paper", ["plant.max_speed=0.76"])).max_speed == 0.76
    assert tracking_setting(load_scenario("hovering_auv")).max_speed is None
