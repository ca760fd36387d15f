"""A thruster-driven 6-DOF marine vehicle as a continuous-time Drake system (Fossen's model)."""

from collections.abc import Callable

import numpy as np
from pydrake.systems.framework import BasicVector, Context, ContinuousState, LeafSystem

from drake_uuv.models.marine_vehicle import MarineVehicleModel
from drake_uuv.models.so3 import quaternion_from_matrix
from drake_uuv.models.vehicle_dynamics import VehicleDynamics
from drake_uuv.models.vehicle_kernels import attitude_runs
from drake_uuv.primitives.batch import batch_size_field, tiled
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
    system: LeafSystem,
    state: Callable[[Context], np.ndarray],
    prerequisites: set,
    batch_size: int = 1,
) -> None:
    """Declares ``p_WU``, ``v_WU``, ``R_WB``, ``w_WB``, ``nu_B`` on ``system``, computed from
    the state ``[p_WU, q_WB, ν_B, …]`` of each of ``batch_size`` runs that ``state(context)``
    returns row-major (see ``MarineVehicle``)."""
    B = batch_size

    def runs(context: Context) -> np.ndarray:
        return np.array(state(context), dtype=float).reshape(B, -1)

    def position(context: Context, output: BasicVector) -> None:
        output.set_value(runs(context)[:, _P].ravel())

    def rotations(x: np.ndarray) -> np.ndarray:
        R = np.empty((B, 9))
        attitude_runs(x, R)
        return R

    def world_vector(body: slice) -> Callable[[Context, BasicVector], None]:
        # numpy's matrix product over the stack: each run's bits are those of R @ v alone
        # (the product these outputs always had; a sum in numba rounds differently).
        def calc(context: Context, output: BasicVector) -> None:
            x = runs(context)
            R = rotations(x).reshape(B, 3, 3)
            output.set_value((R @ x[:, body, None]).ravel())

        return calc

    def attitude(context: Context, output: BasicVector) -> None:
        output.set_value(rotations(runs(context)).ravel())

    def body_velocity(context: Context, output: BasicVector) -> None:
        output.set_value(runs(context)[:, _NU].ravel())

    for name, size, calc in (
        ("p_WU", 3, position),
        ("v_WU", 3, world_vector(_V)),
        ("R_WB", 9, attitude),
        ("w_WB", 3, world_vector(_W)),
        ("nu_B", 6, body_velocity),
    ):
        system.DeclareVectorOutputPort(name, size * B, calc, prerequisites)


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

    Sizes are per run: with ``batch_size`` B every port and the continuous state hold B runs
    row-major (:mod:`drake_uuv.primitives.batch`), each from the given initial state; the
    derivative of every run is one compiled kernel (``vehicle_kernels.derivative_runs``).
    Drake's error-controlled integrators choose one step for the whole state, so under
    ``runge_kutta5`` the runs of a batch share their steps: each run's derivative is its
    own, its trajectory agrees with the run alone only to the integrator's accuracy.
    """

    def __init__(
        self,
        config: HoveringAuv,
        *,
        initial_position: np.ndarray,
        initial_velocity: np.ndarray,
        initial_R_WB: np.ndarray,
        initial_angular_velocity: np.ndarray | None = None,
        batch_size: int = 1,
    ) -> None:
        super().__init__()
        self.batch_size = B = batch_size_field(batch_size)
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
        self.DeclareContinuousState(BasicVector(tiled(x0, B)))
        self._thrust_port = self.DeclareVectorInputPort("thrust_command", self._n * B)
        state_only = {self.xc_ticket()}
        declare_vehicle_outputs(self, self._state, state_only, B)
        thrust_prerequisites = state_only if self._lag else {self._thrust_port.ticket()}
        self.DeclareVectorOutputPort("thrust", self._n * B, self._calc_thrust, thrust_prerequisites)

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
        """The thrusts acting on the hull now (B·n): the lag state, or the saturated command."""
        if self._lag:
            return self._state(context).reshape(self.batch_size, -1)[:, 13:].ravel()
        f_max = self._dynamics.max_thrust
        return np.clip(self._thrust_port.Eval(context), -f_max, f_max)

    def DoCalcTimeDerivatives(self, context: Context, derivatives: ContinuousState) -> None:
        B = self.batch_size
        x = self._state(context).reshape(B, -1)
        command = np.array(self._thrust_port.Eval(context), dtype=float).reshape(B, -1)
        x_dot = self._dynamics.derivative_runs(x, command)
        derivatives.get_mutable_vector().SetFromVector(x_dot.ravel())

    def _calc_thrust(self, context: Context, output: BasicVector) -> None:
        output.set_value(self.applied_thrust(context))
