"""The hovering UUV over a batch of runs: each run of a batch is, bit for bit, the run alone."""

import dataclasses

import numpy as np
import pytest
from pydrake.math import RollPitchYaw, RotationMatrix
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, System
from pydrake.systems.primitives import ConstantVectorSource

from drake_uuv.models.so3 import exp_so3
from drake_uuv.plants import PlantSetting, make_plant
from drake_uuv.plants.hovering_auv import HoveringAuvPlant
from drake_uuv.plants.hovering_auv_stepped import SteppedHoveringAuv
from drake_uuv.plants.low_level_controller import LowLevelController
from drake_uuv.plants.marine_vehicle import MarineVehicle
from drake_uuv.scenario import load_scenario
from drake_uuv.scenario.plants import HoveringAuv
from drake_uuv.testing import assert_batch_equals_runs
from tests.conftest import T

SETTING = PlantSetting(
    T,
    np.array([1.0, -2.0, 3.0]),
    np.array([0.1, 0.0, -0.05]),
    RotationMatrix(RollPitchYaw(0.1, -0.05, 0.3)).matrix(),
)
CONFIGS = {
    "default": HoveringAuv(),
    "thrust-lag": HoveringAuv(thrust_time_constant=0.05),
    "step-reference": HoveringAuv(attitude_reference="step"),
    "G-off-U": dataclasses.replace(HoveringAuv(), center_of_gravity=[0.01, -0.02, -0.03]),
}


def rotations(rng: np.random.Generator, runs: int, scale: float = 1.0) -> np.ndarray:
    """``runs`` random rotation matrices, row-major (runs×9)."""
    return np.array([exp_so3(rng.normal(0.0, scale, 3)).ravel() for _ in range(runs)])


def commands(rng: np.random.Generator, runs: int) -> dict[str, np.ndarray]:
    """Outer commands of every kind, by run: gentle (unsaturated), an acceleration beyond the
    thrusters (the force scaled down), a turn beyond them (the moment scaled down, the
    attitude error past a quarter turn), and no turn at all (the small-angle branches)."""
    u1, u2 = rng.normal(0.0, 0.1, (runs, 3)), rng.normal(0.0, 0.2, (runs, 3))
    kinds = np.arange(runs) % 4
    u1[kinds == 1] *= 60.0
    u2[kinds == 2] = rng.normal(0.0, 6.0, (np.sum(kinds == 2), 3))
    u2[kinds == 3] = 0.0
    return {"u1_B": u1, "u2_W": u2}


def vehicle_states(rng: np.random.Generator, runs: int, lag_states: int) -> np.ndarray:
    """Vehicle states ``[p, q, ν, f]``, the quaternion slightly off the unit sphere."""
    q = rng.normal(size=(runs, 4))
    q *= rng.uniform(0.98, 1.02, (runs, 1)) / np.linalg.norm(q, axis=1, keepdims=True)
    return np.hstack(
        [
            rng.normal(size=(runs, 3)),
            q,
            rng.normal(0.0, 0.3, (runs, 6)),
            rng.normal(0.0, 30.0, (runs, lag_states)),
        ]
    )


def controller_states(rng: np.random.Generator, runs: int, t_k: float) -> list[np.ndarray]:
    """Random controller state groups (latch at ``t_k``, target, rate, velocity, thrusts,
    wrench, scales, counts), as ``ControllerStates`` declares them."""
    latch = np.hstack(
        [rng.normal(0.0, 0.3, (runs, 6)), rotations(rng, runs), np.full((runs, 1), t_k)]
    )
    return [
        latch,
        rotations(rng, runs),
        rng.normal(0.0, 0.3, (runs, 3)),
        rng.normal(0.0, 0.3, (runs, 3)),
        rng.normal(0.0, 100.0, (runs, 8)),
        rng.normal(0.0, 30.0, (runs, 6)),
        rng.uniform(0.0, 1.0, (runs, 2)),
        rng.integers(0, 100, (runs, 4)).astype(float),
    ]


def stepped_case(config: HoveringAuv, batch_size: int, seed: int):
    rng = np.random.default_rng(seed)
    lag = 8 if config.thrust_time_constant > 0.0 else 0
    states = [vehicle_states(rng, batch_size, lag), *controller_states(rng, batch_size, 0.0)]

    def make(B: int) -> SteppedHoveringAuv:
        return SteppedHoveringAuv(config, setting=SETTING, batch_size=B)

    return make, commands(rng, batch_size), states


@pytest.mark.parametrize("config", CONFIGS.values(), ids=CONFIGS.keys())
@pytest.mark.parametrize("batch_size", [1, 2, 5])
def test_a_batch_step_of_the_stepped_vehicle_is_each_run_alone(
    config: HoveringAuv, batch_size: int
) -> None:
    """Random batches, runs of every kind (saturated and not) side by side: an outer step
    (25 controller ticks and RK3 steps) and every output equal the runs alone, bit for bit."""
    make, inputs, states = stepped_case(config, batch_size, seed=batch_size)
    assert_batch_equals_runs(make, inputs, states, time=3 * T)


def test_a_batch_holds_saturated_and_unsaturated_runs() -> None:
    # The case above is not vacuous: in one batch of 8, the runs asked too much scale the
    # force or the moment down, the others do not.
    make, inputs, states = stepped_case(CONFIGS["default"], 8, seed=8)
    system = make(8)
    context = system.CreateDefaultContext()
    for name, value in inputs.items():
        system.GetInputPort(name).FixValue(context, value.ravel())
    for group, value in enumerate(states):
        context.SetDiscreteState(group, value.ravel())
    update = system.EvalUniquePeriodicDiscreteUpdate(context)
    before = states[-1]
    counts = update.get_vector(len(states) - 1).CopyToVector().reshape(8, 4) - before
    assert np.all(counts[:, 0] == 25)
    kinds = np.arange(8) % 4
    assert np.all(counts[kinds == 0, 3] == 0) and np.all(counts[kinds == 3, 3] == 0)
    assert np.all(counts[kinds == 1, 1] > 0) and np.all(counts[kinds == 2, 2] > 0)


@pytest.mark.parametrize("config", CONFIGS.values(), ids=CONFIGS.keys())
def test_a_failed_run_leaves_the_others_alone(config: HoveringAuv) -> None:
    """A run whose state and commands hold NaN and inf neither raises nor touches the other
    runs: they are their runs alone to the bit, and the failed run is NaN."""
    make, inputs, states = stepped_case(config, 4, seed=11)
    states[0][1, 3:7] = np.nan  # its attitude
    states[0][2, 7] = np.inf  # its surge
    inputs["u1_B"][3] = np.nan
    with np.errstate(all="raise"):
        assert_batch_equals_runs(make, inputs, states)
    system = make(4)
    context = system.CreateDefaultContext()
    for name, value in inputs.items():
        system.GetInputPort(name).FixValue(context, value.ravel())
    for group, value in enumerate(states):
        context.SetDiscreteState(group, value.ravel())
    x = system.EvalUniquePeriodicDiscreteUpdate(context).get_vector(0).CopyToVector()
    x = x.reshape(4, -1)
    assert np.all(np.isnan(x[[1, 2, 3]]).any(axis=1)) and np.all(np.isfinite(x[0]))


@pytest.mark.parametrize("time", [0.0, 0.02 * 7], ids=["outer-tick", "between"])
@pytest.mark.parametrize("config", CONFIGS.values(), ids=CONFIGS.keys())
def test_a_batch_tick_of_the_controller_is_each_run_alone(config: HoveringAuv, time: float) -> None:
    """The continuous diagram's controller: a fresh latch at an outer tick, the held latch
    between, runs saturated and not; one failed run among them."""
    batch_size = 6
    rng = np.random.default_rng(21)
    inputs = commands(rng, batch_size)
    inputs["R_WB"] = rotations(rng, batch_size, 0.5)
    inputs["nu_B"] = rng.normal(0.0, 0.3, (batch_size, 6))
    states = controller_states(rng, batch_size, 0.0)
    inputs["nu_B"][5, 2] = np.nan

    def make(B: int) -> LowLevelController:
        return LowLevelController(
            config, outer_period=T, initial_R_WB=SETTING.initial_R_WB, batch_size=B
        )

    assert_batch_equals_runs(make, inputs, states, time=time)


@pytest.mark.parametrize("config", CONFIGS.values(), ids=CONFIGS.keys())
def test_the_continuous_vehicle_of_a_batch_is_each_run_alone(config: HoveringAuv) -> None:
    """``MarineVehicle``: every output and the time derivative of B runs equal the runs
    alone (one of them NaN)."""
    batch_size = 5
    rng = np.random.default_rng(31)
    lag = 8 if config.thrust_time_constant > 0.0 else 0
    x = vehicle_states(rng, batch_size, lag)
    x[3, 9] = np.nan
    command = rng.normal(0.0, 60.0, (batch_size, 8))
    command[1, 2] = 500.0  # beyond the limit: saturated inside

    def evaluate(runs: slice) -> dict[str, np.ndarray]:
        B = len(x[runs])
        vehicle = MarineVehicle(
            config,
            initial_position=SETTING.initial_position,
            initial_velocity=SETTING.initial_velocity,
            initial_R_WB=SETTING.initial_R_WB,
            batch_size=B,
        )
        context = vehicle.CreateDefaultContext()
        context.SetContinuousState(x[runs].ravel())
        vehicle.get_input_port().FixValue(context, command[runs].ravel())
        values = {
            vehicle.get_output_port(i).get_name(): vehicle.get_output_port(i).Eval(context)
            for i in range(vehicle.num_output_ports())
        }
        values["derivative"] = vehicle.EvalTimeDerivatives(context).CopyToVector()
        return {name: np.reshape(value, (B, -1)) for name, value in values.items()}

    batch = evaluate(slice(None))
    for i in range(batch_size):
        for name, value in evaluate(slice(i, i + 1)).items():
            assert np.array_equal(batch[name][i], value[0], equal_nan=True), (name, i)


def simulate(plant: System, u1: np.ndarray, u2: np.ndarray, steps: int) -> dict[str, np.ndarray]:
    """The plant under constant commands for ``steps`` outer steps; every output at the end."""
    builder = DiagramBuilder()
    builder.AddSystem(plant)
    for name, value in (("u1_B", u1), ("u2_W", u2)):
        source = builder.AddSystem(ConstantVectorSource(value.ravel()))
        builder.Connect(source.get_output_port(), plant.GetInputPort(name))
    simulator = Simulator(builder.Build())
    plant.configure_simulator(simulator)
    simulator.AdvanceTo(steps * T - 1e-9)
    context = plant.GetMyContextFromRoot(simulator.get_context())
    return {
        plant.get_output_port(i).get_name(): plant.get_output_port(i).Eval(context).copy()
        for i in range(plant.num_output_ports())
    }


def test_a_batch_of_runs_through_the_plant_is_each_run_alone() -> None:
    """Five outer steps of ``HoveringAuvPlant`` (the default, stepped): four runs of a batch,
    saturated and not, end where each run alone ends, to the bit."""
    rng = np.random.default_rng(41)
    inputs = commands(rng, 4)
    batch = simulate(
        HoveringAuvPlant(HoveringAuv(), setting=SETTING, batch_size=4), *inputs.values(), 5
    )
    for i in range(4):
        alone = simulate(
            HoveringAuvPlant(HoveringAuv(), setting=SETTING),
            *(value[i] for value in inputs.values()),
            5,
        )
        for name, value in alone.items():
            assert np.array_equal(batch[name].reshape(4, -1)[i], value), (name, i)


@pytest.mark.parametrize("integrator", ["runge_kutta3", "runge_kutta5"])
def test_ports_scale_with_the_batch(integrator: str) -> None:
    config = HoveringAuv(integrator=integrator)
    single = HoveringAuvPlant(config, setting=SETTING)
    batch = HoveringAuvPlant(config, setting=SETTING, batch_size=3)
    assert batch.batch_size == 3 and single.batch_size == 1
    for i in range(single.num_input_ports()):
        assert batch.get_input_port(i).size() == 3 * single.get_input_port(i).size()
    for i in range(single.num_output_ports()):
        assert batch.get_output_port(i).size() == 3 * single.get_output_port(i).size()
    # Every run starts at the setting's initial state.
    context, alone = batch.CreateDefaultContext(), single.CreateDefaultContext()
    for name in ("p_WU", "v_WU", "R_WB", "R_WB_command", "saturation_ticks"):
        value = batch.GetOutputPort(name).Eval(context).reshape(3, -1)
        assert np.array_equal(value, np.tile(single.GetOutputPort(name).Eval(alone), (3, 1)))


def test_the_factory_passes_the_batch_size() -> None:
    scenario = load_scenario("paper", ["plant=!HoveringAuv"])
    plant = make_plant(scenario, batch_size=4)
    assert isinstance(plant, HoveringAuvPlant) and plant.batch_size == 4
    assert plant.GetInputPort("u1_B").size() == 12
    assert make_plant(load_scenario("paper"), batch_size=3).batch_size == 3


@pytest.mark.parametrize(
    "system",
    [
        lambda B: HoveringAuvPlant(HoveringAuv(), setting=SETTING, batch_size=B),
        lambda B: SteppedHoveringAuv(HoveringAuv(), setting=SETTING, batch_size=B),
        lambda B: LowLevelController(
            HoveringAuv(), outer_period=T, initial_R_WB=np.eye(3), batch_size=B
        ),
        lambda B: MarineVehicle(
            HoveringAuv(),
            initial_position=np.zeros(3),
            initial_velocity=np.zeros(3),
            initial_R_WB=np.eye(3),
            batch_size=B,
        ),
    ],
    ids=["plant", "stepped", "controller", "vehicle"],
)
def test_a_bad_batch_size_is_named(system) -> None:
    with pytest.raises(ValueError, match=r"^batch_size: must be an integer ≥ 1, got 0$"):
        system(0)
