"""MarineVehicle: ports, closed-form derivatives, hydrostatics, damping, and the MultibodyPlant cross-check."""

import dataclasses
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pydrake.math import RollPitchYaw, RotationMatrix
from pydrake.systems.analysis import ApplySimulatorConfig, Simulator, SimulatorConfig
from pydrake.systems.framework import BasicVector, Context, DiagramBuilder, LeafSystem
from pydrake.systems.primitives import ConstantVectorSource, ZeroOrderHold

from drake_uuv.models.marine_vehicle import rotation_from_quaternion
from drake_uuv.models.so3 import exp_so3, log_so3
from drake_uuv.models.vehicle_dynamics import VehicleDynamics
from drake_uuv.plants.hovering_auv import configure_simulator
from drake_uuv.plants.marine_vehicle import MarineVehicle, vehicle_initial_state
from drake_uuv.scenario.plants import HoveringAuv
from drake_uuv.testing import fixed_context
from tests.plants.multibody_vehicle import MultibodyVehicle

OUTPUTS = {"p_WU": 3, "v_WU": 3, "R_WB": 9, "w_WB": 3, "nu_B": 6, "thrust": 8}


def marine_vehicle(
    config: HoveringAuv,
    p0: np.ndarray,
    v0: np.ndarray,
    R0: np.ndarray,
    w0: np.ndarray | None = None,
) -> MarineVehicle:
    """The vehicle at ``p_WU = p0``, ``v_WU = v0``, ``R_WB = R0``, ``ω_WB = w0`` (default 0)."""
    return MarineVehicle(
        config,
        initial_position=p0,
        initial_velocity=v0,
        initial_R_WB=R0,
        initial_angular_velocity=w0,
    )


def accurate(config: HoveringAuv) -> HoveringAuv:
    """``config`` integrated by Drake's error-controlled RK5 (the continuous model's physics;
    the default fixed step is checked against the MultibodyPlant below)."""
    return dataclasses.replace(config, integrator="runge_kutta5")


def simulate(
    vehicle: MarineVehicle,
    config: HoveringAuv,
    duration: float,
    thrust: np.ndarray | None = None,
    samples: int = 1,
) -> list[dict[str, np.ndarray]]:
    """Runs the vehicle under a constant thrust command; outputs at ``samples`` even times."""
    builder = DiagramBuilder()
    builder.AddSystem(vehicle)
    source = builder.AddSystem(ConstantVectorSource(np.zeros(8) if thrust is None else thrust))
    builder.Connect(source.get_output_port(), vehicle.get_input_port())
    simulator = Simulator(builder.Build())
    configure_simulator(simulator, accurate(config), 0.5)
    context = vehicle.GetMyContextFromRoot(simulator.get_context())
    result = []
    for time in np.linspace(duration / samples, duration, samples):
        simulator.AdvanceTo(time)
        result.append({name: vehicle.GetOutputPort(name).Eval(context).copy() for name in OUTPUTS})
    return result


def test_ports_and_initial_outputs() -> None:
    R0 = RotationMatrix(RollPitchYaw(0.1, -0.3, 2.0)).matrix()
    p0, v0, w0 = np.array([1.0, -2.0, 3.0]), np.array([0.1, 0.2, -0.3]), np.array([0.4, -0.5, 0.6])
    vehicle = marine_vehicle(HoveringAuv(), p0, v0, R0, w0)
    assert vehicle.get_input_port().get_name() == "thrust_command"
    assert vehicle.get_input_port().size() == 8
    assert {vehicle.get_output_port(i).get_name(): vehicle.get_output_port(i).size()
            for i in range(vehicle.num_output_ports())} == OUTPUTS  # fmt: skip
    # Only the applied thrust (no lag) feeds through; the motion is state.
    for name in OUTPUTS:
        assert vehicle.HasDirectFeedthrough(0, vehicle.GetOutputPort(name).get_index()) == (
            name == "thrust"
        )
    context = fixed_context(vehicle, thrust_command=np.zeros(8))
    out = {name: vehicle.GetOutputPort(name).Eval(context) for name in OUTPUTS}
    assert_allclose(out["p_WU"], p0)
    assert_allclose(out["v_WU"], v0, atol=1e-15)
    assert_allclose(out["R_WB"].reshape(3, 3), R0, atol=1e-15)
    assert_allclose(out["w_WB"], w0, atol=1e-15)
    assert_allclose(out["nu_B"], np.concatenate([R0.T @ v0, R0.T @ w0]), atol=1e-15)


def test_derivatives_at_rest_are_the_thrust_wrench_through_the_mass_matrix() -> None:
    config = HoveringAuv()
    R0 = RotationMatrix(RollPitchYaw(0.0, 0.0, 0.7)).matrix()  # upright: no restoring moment
    vehicle = marine_vehicle(config, np.zeros(3), np.zeros(3), R0)
    thrust = np.array([10.0, -5.0, 3.0, 20.0, 15.0, -30.0, 7.0, 1.0])
    context = fixed_context(vehicle, thrust_command=thrust)
    x_dot = vehicle.EvalTimeDerivatives(context).CopyToVector()
    assert_allclose(x_dot[:7], 0.0, atol=1e-15)  # no velocity: no motion of p or q
    M = config.vehicle_model().M
    assert_allclose(M @ x_dot[7:], config.allocator().A @ thrust, atol=1e-12)


def test_commanded_thrust_is_saturated_inside_the_model() -> None:
    config = HoveringAuv()
    vehicle = marine_vehicle(config, np.zeros(3), np.zeros(3), np.eye(3))
    command = np.array([1000.0, -1000.0, 0.0, 50.0, 0.0, 0.0, -80.0, 0.0])
    context = fixed_context(vehicle, thrust_command=command)
    applied = np.array([77.55, -77.55, 0.0, 50.0, 0.0, 0.0, -77.55, 0.0])
    assert_allclose(vehicle.GetOutputPort("thrust").Eval(context), applied)
    x_dot = vehicle.EvalTimeDerivatives(context).CopyToVector()
    assert_allclose(
        config.vehicle_model().M @ x_dot[7:], config.allocator().A @ applied, atol=1e-12
    )


def test_thrust_lag_is_first_order() -> None:
    config = HoveringAuv(thrust_time_constant=0.1)
    vehicle = marine_vehicle(config, np.zeros(3), np.zeros(3), np.eye(3))
    command = np.array([10.0, 10.0, 10.0, 10.0, 5.0, 5.0, 5.0, 5.0]) * np.array(
        [1, -1, 1, -1, 1, 1, 1, 1]
    )
    (out,) = simulate(vehicle, config, 0.25, command)
    assert_allclose(out["thrust"], command * (1.0 - math.exp(-2.5)), rtol=1e-6)


@pytest.mark.slow
def test_neutral_vehicle_at_rest_neither_drifts_nor_turns_over_60_s() -> None:
    config = HoveringAuv()
    R0 = RotationMatrix(RollPitchYaw(0.0, 0.0, 1.2)).matrix()
    vehicle = marine_vehicle(config, np.array([1.0, 2.0, -3.0]), np.zeros(3), R0)
    (out,) = simulate(vehicle, config, 60.0)
    assert_allclose(out["p_WU"], [1.0, 2.0, -3.0], atol=1e-12)
    assert np.linalg.norm(log_so3(out["R_WB"].reshape(3, 3) @ R0.T)) < 1e-12
    assert_allclose(out["nu_B"], 0.0, atol=1e-12)


@pytest.mark.slow
def test_buoyancy_restores_a_tilted_vehicle_to_upright() -> None:
    config = HoveringAuv()
    model = config.vehicle_model()
    roll, pitch = 0.5, -0.4
    R0 = RotationMatrix(RollPitchYaw(roll, pitch, 0.3)).matrix()
    vehicle = marine_vehicle(config, np.zeros(3), np.zeros(3), R0)
    # At release, ω̇_B = M_rot⁻¹ τ with the buoyancy's moment τ = (z_BG e_z) × (B k_B) about G
    # (k_B = R_WBᵀ e_z, the world's up in the body), which turns k_B back towards e_z.
    context = fixed_context(vehicle, thrust_command=np.zeros(8))
    w_dot = vehicle.EvalTimeDerivatives(context).CopyToVector()[10:13]
    k_B = R0[2]
    expected = np.linalg.solve(
        model.M[3:, 3:], config.buoyant_force * 0.05 * np.cross([0, 0, 1], k_B)
    )
    assert_allclose(w_dot, expected, rtol=1e-12)
    samples = simulate(vehicle, config, 60.0, samples=600)
    tilt = np.array([math.acos(np.clip(s["R_WB"].reshape(3, 3)[2, 2], -1, 1)) for s in samples])
    # It rocks about upright (√(B z_BG / M_rot) ≈ 3 rad/s) with a decaying envelope; roll has
    # quadratic damping only, so the envelope falls like 1/t rather than exponentially.
    envelope = tilt.reshape(6, 100).max(axis=1)
    assert np.all(np.diff(envelope) < 0.0)
    assert envelope[-1] < 0.01 < 0.5 < math.acos(R0[2, 2])


def energies(
    config: HoveringAuv, samples: list[dict[str, np.ndarray]]
) -> tuple[np.ndarray, np.ndarray]:
    model = config.vehicle_model()
    kinetic = np.array([model.kinetic_energy(s["nu_B"]) for s in samples])
    potential = np.array(
        [model.potential_energy(s["p_WU"], s["R_WB"].reshape(3, 3)) for s in samples]
    )
    return kinetic, potential


@pytest.mark.parametrize("restoring", [False, True])
def test_damping_removes_energy_without_thrust(restoring: bool) -> None:
    # Without restoring moments (CB at G) the kinetic energy ½ νᵀMν must fall; with them,
    # kinetic plus potential energy. C(ν) does no work, so only D(ν) changes either.
    config = HoveringAuv(center_of_buoyancy=[0.0, 0.0, 0.05 if restoring else 0.0])
    R0 = RotationMatrix(RollPitchYaw(0.3, 0.2, -0.1)).matrix()
    vehicle = marine_vehicle(
        config, np.zeros(3), np.array([0.5, -0.3, 0.2]), R0, np.array([1.0, -2.0, 1.5])
    )
    samples = simulate(vehicle, config, 5.0, samples=50)
    kinetic, potential = energies(config, samples)
    total = kinetic + (potential if restoring else 0.0)
    initial = config.vehicle_model().kinetic_energy(
        np.concatenate([R0.T @ [0.5, -0.3, 0.2], R0.T @ [1.0, -2.0, 1.5]])
    )
    assert np.all(np.diff(total) < 0.0)
    assert kinetic[-1] < 0.01 * initial


def test_without_damping_the_energy_is_conserved() -> None:
    # The check that the energy tests can fail: with D = 0 the Coriolis terms (rigid body
    # and added mass) and the restoring forces conserve kinetic plus potential energy.
    config = HoveringAuv(linear_damping=[0.0] * 6, quadratic_damping=[0.0] * 6)
    R0 = RotationMatrix(RollPitchYaw(0.3, 0.2, -0.1)).matrix()
    vehicle = marine_vehicle(
        config, np.zeros(3), np.array([0.5, -0.3, 0.2]), R0, np.array([1.0, -2.0, 1.5])
    )
    kinetic, potential = energies(config, simulate(vehicle, config, 5.0, samples=10))
    total = kinetic + potential
    assert np.ptp(total) < 1e-6 * kinetic[0]


def test_quaternion_off_the_unit_sphere_is_pulled_back() -> None:
    config = HoveringAuv()
    R0 = RotationMatrix(RollPitchYaw(0.3, 0.2, -0.1)).matrix()
    vehicle = marine_vehicle(config, np.zeros(3), np.zeros(3), R0, np.array([1.0, -2.0, 1.5]))
    builder = DiagramBuilder()
    builder.AddSystem(vehicle)
    source = builder.AddSystem(ConstantVectorSource(np.zeros(8)))
    builder.Connect(source.get_output_port(), vehicle.get_input_port())
    simulator = Simulator(builder.Build())
    configure_simulator(simulator, accurate(config), 0.5)
    context = vehicle.GetMyMutableContextFromRoot(simulator.get_mutable_context())
    x = context.get_continuous_state_vector().CopyToVector()
    x[3:7] *= 1.05  # as if the integrator had drifted
    context.SetContinuousState(x)
    assert_allclose(vehicle.GetOutputPort("R_WB").Eval(context).reshape(3, 3), R0, atol=1e-15)
    simulator.AdvanceTo(5.0)
    q = context.get_continuous_state_vector().CopyToVector()[3:7]
    # |q|² − 1 decays like e^(−2λt) near 1 (λ = 1): from 0.1025 to about 5e-6 in 5 s.
    assert abs(q @ q - 1.0) < 1e-4
    R = vehicle.GetOutputPort("R_WB").Eval(context).reshape(3, 3)
    assert_allclose(R.T @ R, np.eye(3), atol=1e-14)


def smooth_thrust(config: HoveringAuv, t: float) -> np.ndarray:
    """Thrusts that turn and move the vehicle: the allocation of a sinusoidal body wrench."""
    wrench = [
        60 * math.sin(0.7 * t), 40 * math.cos(0.5 * t), 30 * math.sin(0.9 * t),
        8 * math.sin(1.1 * t), 6 * math.cos(0.8 * t), 10 * math.sin(0.6 * t) + 5,
    ]  # fmt: skip
    return config.allocator().A_pinv @ wrench


class SmoothThrust(LeafSystem):
    """:func:`smooth_thrust` as a source (output ``thrust_command``)."""

    def __init__(self, config: HoveringAuv) -> None:
        super().__init__()
        self._config = config
        self.DeclareVectorOutputPort("thrust_command", 8, self._calc)

    def _calc(self, context: Context, output: BasicVector) -> None:
        output.set_value(smooth_thrust(self._config, context.get_time()))


def cross_check_config(time_constant: float) -> HoveringAuv:
    # Added mass off (SpatialInertia holds one scalar mass); G off the body origin so that the
    # rigid-body Coriolis terms of M_RB's off-diagonal blocks are exercised; buoyancy ≠ weight.
    return dataclasses.replace(
        HoveringAuv(),
        added_mass=np.zeros((6, 6)).tolist(),
        center_of_gravity=[0.01, -0.02, -0.03],
        buoyancy=31.02 * 9.81 + 2.0,
        thrust_time_constant=time_constant,
    )


P0, V0, W0 = np.array([1.0, 2.0, 3.0]), np.array([0.1, -0.2, 0.05]), np.array([0.3, 0.1, -0.2])
R0_CROSS = exp_so3(np.array([0.2, -0.1, 0.5]))
DURATION = 10.0


def multibody_final(config: HoveringAuv, held: float | None) -> tuple[np.ndarray, ...]:
    """p, R, v of the MultibodyPlant model after 10 s of :func:`smooth_thrust`, held over
    periods ``held`` (a ZeroOrderHold) if given, integrated by RK5 at accuracy 1e-10."""
    system = MultibodyVehicle(config)
    builder = DiagramBuilder()
    builder.AddSystem(system)
    source = builder.AddSystem(SmoothThrust(config))
    if held is not None:
        hold = builder.AddSystem(ZeroOrderHold(held, 8))
        builder.Connect(source.get_output_port(), hold.get_input_port())
        source = hold
    builder.Connect(source.get_output_port(), system.GetInputPort("thrust_command"))
    simulator = Simulator(builder.Build())
    ApplySimulatorConfig(SimulatorConfig(integration_scheme="runge_kutta5", accuracy=1e-10),
                         simulator)  # fmt: skip
    root = simulator.get_mutable_context()
    system.set_initial_state(root, P0, R0_CROSS, V0, W0)
    simulator.AdvanceTo(DURATION)
    X, V = system.pose(root), system.spatial_velocity(root)
    return X.translation(), X.rotation().matrix(), V.translational()


def assert_close_to(final: tuple[np.ndarray, ...], reference: tuple[np.ndarray, ...],
                    tolerance: float) -> None:  # fmt: skip
    (p, R, v), (p_mb, R_mb, v_mb) = final, reference
    assert np.linalg.norm(p_mb - P0) > 1.5 and np.linalg.norm(log_so3(R_mb @ R0_CROSS.T)) > 0.5
    assert np.linalg.norm(p - p_mb) < tolerance
    assert np.linalg.norm(log_so3(R @ R_mb.T)) < tolerance
    assert np.linalg.norm(v - v_mb) < tolerance


@pytest.mark.slow
@pytest.mark.parametrize("time_constant", [0.0, 0.05])
def test_leaf_system_agrees_with_the_multibody_plant_to_a_micrometre(time_constant: float) -> None:
    # runge_kutta5: the continuous LeafSystem under Drake's error-controlled RK5 at the
    # deployed accuracy, the thrust smooth in time.
    config = cross_check_config(time_constant)
    leaf = marine_vehicle(config, P0, V0, R0_CROSS, W0)
    builder = DiagramBuilder()
    builder.AddSystem(leaf)
    source = builder.AddSystem(SmoothThrust(config))
    builder.Connect(source.get_output_port(), leaf.GetInputPort("thrust_command"))
    simulator = Simulator(builder.Build())
    configure_simulator(simulator, accurate(config), 0.5)  # the default accuracy
    simulator.AdvanceTo(DURATION)
    context = leaf.GetMyContextFromRoot(simulator.get_context())
    final = tuple(leaf.GetOutputPort(n).Eval(context) for n in ("p_WU", "R_WB", "v_WU"))
    final = final[0], final[1].reshape(3, 3), final[2]
    assert_close_to(final, multibody_final(config, None), 1e-6)


@pytest.mark.slow
@pytest.mark.parametrize("time_constant", [0.0, 0.05])
def test_the_fixed_step_agrees_with_the_multibody_plant(time_constant: float) -> None:
    # runge_kutta3 as deployed (SteppedHoveringAuv): the thrust held over each controller
    # period h = 0.02 s and one VehicleDynamics.step per period, against the MultibodyPlant
    # under the same held thrust at accuracy 1e-10. RK3's global error, O(h³), is what
    # remains: 1.2e-5 m over these 10 s (1.4e-5 m with the lag); holding the thrust instead
    # of following it moves the vehicle 1.5e-2 m, so the hold is what both models integrate.
    config = cross_check_config(time_constant)
    h = config.controller_period(0.5)
    dynamics = VehicleDynamics(config.vehicle_model(), config.allocator(), time_constant)
    lag_states = dynamics.num_thrusters if dynamics.lag else 0
    x = vehicle_initial_state(P0, V0, R0_CROSS, W0, lag_states).tolist()
    for j in range(round(DURATION / h)):
        x = dynamics.step(x, smooth_thrust(config, j * h).tolist(), h)
    R = rotation_from_quaternion(np.array(x[3:7]))
    final = np.array(x[:3]), R, R @ x[7:10]
    assert_close_to(final, multibody_final(config, h), 3e-5)


def test_multibody_vehicle_refuses_added_mass() -> None:
    with pytest.raises(ValueError, match=r"^config\.added_mass: must be zero"):
        MultibodyVehicle(HoveringAuv())


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(initial_position=np.zeros(2)), r"^initial_position: must be 3 finite numbers"),
        (
            dict(initial_velocity=np.array([0, np.nan, 0])),
            r"^initial_velocity: must be 3 finite numbers",
        ),
        (
            dict(initial_R_WB=2 * np.eye(3)),
            r"^initial_R_WB: must be a rotation matrix, got \[\[2\.0",
        ),
        (dict(initial_R_WB=np.diag([1.0, 1.0, -1.0])), r"^initial_R_WB: must be a rotation matrix"),
    ],
)
def test_bad_initial_state_names_the_parameter(kwargs: dict, message: str) -> None:
    args = dict(initial_position=np.zeros(3), initial_velocity=np.zeros(3), initial_R_WB=np.eye(3))
    with pytest.raises(ValueError, match=message):
        MarineVehicle(HoveringAuv(), **{**args, **kwargs})
