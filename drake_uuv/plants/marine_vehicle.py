"""A thruster-driven 6-DOF marine vehicle as a continuous-time Drake system (Fossen's model)."""

from collections.abc import Callable

import numpy as np
from pydrake.systems.framework import BasicVector, Context, ContinuousState, LeafSystem

from drake_uuv.models.marine_vehicle import MarineVehicleModel, rotation_from_quaternion
from drake_uuv.models.so3 import quaternion_from_matrix
from drake_uuv.models.vehicle_dynamics import VehicleDynamics
from drake_uuv.scenario.plants import HoveringAuv

# Slices of the state [p_WU (3), q_WB (4), ν_B (6), applied thrust (n, with a lag)].
_P, _Q, _V, _W, _NU = slice(0, 3), slice(3, 7), slice(7, 10), slice(10, 13), slice(7, 13)


def vehicle_initial_state(
    initial_position: np.ndarray,
    initial_velocity: np.ndarray,
    initial_R_WB: np.ndarray,
    initial_angular_velocity: np.ndarray | None = None,
    num_lag_states: int = 0,
) -> np.ndarray:
    """``[p_WU, q_WB, ν_B, 0 (num_lag_states)]`` of a vehicle at the given world-frame state.

    Raises ValueError naming the parameter if a vector is not 3 finite numbers or
    ``initial_R_WB`` is not a rotation matrix.
    """
    w0_W = np.zeros(3) if initial_angular_velocity is None else initial_angular_velocity
    for name, value in (
        ("initial_position", initial_position),
        ("initial_velocity", initial_velocity),
        ("initial_angular_velocity", w0_W),
    ):
        if np.shape(value) != (3,) or not np.all(np.isfinite(value)):
            raise ValueError(f"{name}: must be 3 finite numbers, got {value!r}")
    R0 = np.asarray(initial_R_WB, dtype=float)
    if (
        R0.shape != (3, 3)
        or not np.allclose(R0.T @ R0, np.eye(3), atol=1e-9)
        or np.linalg.det(R0) < 0.0
    ):
        raise ValueError(f"initial_R_WB: must be a rotation matrix, got {R0.tolist()!r}")
    return np.concatenate(
        [
            np.asarray(initial_position, dtype=float),
            quaternion_from_matrix(R0),
            R0.T @ np.asarray(initial_velocity, dtype=float),
            R0.T @ np.asarray(w0_W, dtype=float),
            np.zeros(num_lag_states),
        ]
    )


def declare_vehicle_outputs(
    system: LeafSystem, state: Callable[[Context], np.ndarray], prerequisites: set
) -> None:
    """Declares ``p_WU``, ``v_WU``, ``R_WB``, ``w_WB``, ``nu_B`` on ``system``, computed from
    the state ``[p_WU, q_WB, ν_B, …]`` that ``state(context)`` returns (see ``MarineVehicle``)."""

    def position(context: Context, output: BasicVector) -> None:
        output.set_value(state(context)[_P])

    def velocity(context: Context, output: BasicVector) -> None:
        x = state(context)
        output.set_value(rotation_from_quaternion(x[_Q]) @ x[_V])

    def attitude(context: Context, output: BasicVector) -> None:
        output.set_value(rotation_from_quaternion(state(context)[_Q]).ravel())

    def angular_velocity(context: Context, output: BasicVector) -> None:
        x = state(context)
        output.set_value(rotation_from_quaternion(x[_Q]) @ x[_W])

    def body_velocity(context: Context, output: BasicVector) -> None:
        output.set_value(state(context)[_NU])

    for name, size, calc in (
        ("p_WU", 3, position),
        ("v_WU", 3, velocity),
        ("R_WB", 9, attitude),
        ("w_WB", 3, angular_velocity),
        ("nu_B", 6, body_velocity),
    ):
        system.DeclareVectorOutputPort(name, size, calc, prerequisites)


class MarineVehicle(LeafSystem):
    """Fossen's ``M ν̇ + C(ν) ν + D(ν) ν + g(η) = A f`` driven by n thrusters.

    The equations and the frame conventions (world z up, body x forward, y left, z up, origin
    U) are those of ``drake_uuv/models/marine_vehicle.py``; the thrust map ``A`` is
    ``drake_uuv/models/thrust_allocation.py``'s; the state equation is ``VehicleDynamics``
    (``drake_uuv/models/vehicle_dynamics.py``). Continuous state: position ``p_WU``, the
    attitude quaternion ``q_WB`` (w, x, y, z), the body velocity ``ν = [v_B, ω_B]`` and, when
    ``thrust_time_constant > 0``, the applied thrusts of the first-order lag
    ``ḟ = (sat(f_cmd) − f) / T``. The commanded thrust is saturated at ``±max_thrust`` inside
    the model, so a controller that asks for more gets the limit. The quaternion is kept on
    the unit sphere by the stabilising term of ``quaternion_derivative``, and every output
    normalises it before use.

    Integrate with an explicit scheme (``configure_simulator`` in
    ``drake_uuv/plants/hovering_auv.py``, by ``config.integrator``): the dynamics are not
    stiff (the fastest damping rate, ``2 D_quad |ν| / M`` in roll at 3 rad/s, is about
    16 s⁻¹).

    .. pydrake_system::

        name: MarineVehicle
        input_ports:
        - thrust_command
        output_ports:
        - p_WU
        - v_WU
        - R_WB
        - w_WB
        - nu_B
        - thrust

    - ``thrust_command`` (n): commanded thrusts [N].
    - ``p_WU``, ``v_WU`` (3 each): position and velocity of U in the world [m, m/s].
    - ``R_WB`` (9, row-major): attitude, body to world.
    - ``w_WB`` (3): angular velocity in the world frame, ``R_WB ω_B`` [rad/s].
    - ``nu_B`` (6): body velocity ``[v_B, ω_B]`` [m/s, rad/s].
    - ``thrust`` (n): applied thrusts after saturation and lag [N].
    """

    def __init__(
        self,
        config: HoveringAuv,
        *,
        initial_position: np.ndarray,
        initial_velocity: np.ndarray,
        initial_R_WB: np.ndarray,
        initial_angular_velocity: np.ndarray | None = None,
    ) -> None:
        super().__init__()
        self._dynamics = VehicleDynamics(
            config.vehicle_model(), config.allocator(), config.thrust_time_constant
        )
        self._n = self._dynamics.num_thrusters
        self._lag = self._dynamics.lag
        x0 = vehicle_initial_state(
            initial_position,
            initial_velocity,
            initial_R_WB,
            initial_angular_velocity,
            self._n if self._lag else 0,
        )
        self.DeclareContinuousState(BasicVector(x0))
        self._thrust_port = self.DeclareVectorInputPort("thrust_command", self._n)
        state_only = {self.xc_ticket()}
        declare_vehicle_outputs(self, self._state, state_only)
        thrust_prerequisites = state_only if self._lag else {self._thrust_port.ticket()}
        self.DeclareVectorOutputPort("thrust", self._n, self._calc_thrust, thrust_prerequisites)

    @property
    def model(self) -> MarineVehicleModel:
        """The ``MarineVehicleModel`` this system integrates."""
        return self._dynamics.model

    @property
    def num_thrusters(self) -> int:
        return self._n

    def _state(self, context: Context) -> np.ndarray:
        return context.get_continuous_state_vector().CopyToVector()

    def applied_thrust(self, context: Context) -> np.ndarray:
        """The thrusts acting on the hull now: the lag state, or the saturated command."""
        if self._lag:
            return self._state(context)[13:]
        f_max = self._dynamics.max_thrust
        return np.clip(self._thrust_port.Eval(context), -f_max, f_max)

    def DoCalcTimeDerivatives(self, context: Context, derivatives: ContinuousState) -> None:
        x = context.get_continuous_state_vector().CopyToVector().tolist()
        command = self._thrust_port.Eval(context).tolist()
        derivatives.get_mutable_vector().SetFromVector(self._dynamics.derivative(x, command))

    def _calc_thrust(self, context: Context, output: BasicVector) -> None:
        output.set_value(self.applied_thrust(context))
