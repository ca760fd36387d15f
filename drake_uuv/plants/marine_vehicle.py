"""A thruster-driven 6-DOF marine vehicle as a continuous-time Drake system (Fossen's model)."""

import numpy as np
from pydrake.systems.framework import BasicVector, Context, ContinuousState, LeafSystem

from drake_uuv.models.marine_vehicle import (
    QUATERNION_NORM_GAIN,
    MarineVehicleModel,
    rotation_from_quaternion,
    rotation_rows,
)
from drake_uuv.models.so3 import quaternion_from_matrix
from drake_uuv.scenario.plants import HoveringAuv

# Slices of the continuous state [p_WU (3), q_WB (4), ν_B (6), applied thrust (n, with a lag)].
_P, _Q, _V, _W, _NU = slice(0, 3), slice(3, 7), slice(7, 10), slice(10, 13), slice(7, 13)


class MarineVehicle(LeafSystem):
    """Fossen's ``M ν̇ + C(ν) ν + D(ν) ν + g(η) = A f`` driven by n thrusters.

    The equations and the frame conventions (world z up, body x forward, y left, z up, origin
    U) are those of ``drake_uuv/models/marine_vehicle.py``; the thrust map ``A`` is
    ``drake_uuv/models/thrust_allocation.py``'s. Continuous state: position ``p_WU``, the
    attitude quaternion ``q_WB`` (w, x, y, z), the body velocity ``ν = [v_B, ω_B]`` and, when
    ``thrust_time_constant > 0``, the applied thrusts of the first-order lag
    ``ḟ = (sat(f_cmd) − f) / T``. The commanded thrust is saturated at ``±max_thrust`` inside
    the model, so a controller that asks for more gets the limit. The quaternion is kept on
    the unit sphere by the stabilising term of ``quaternion_derivative``, and every output
    normalises it before use.

    Integrate with an explicit scheme (``configure_simulator`` in
    ``drake_uuv/plants/hovering_auv.py``): the dynamics are not stiff (the fastest damping
    rate, ``2 D_quad |ν| / M`` in roll at 3 rad/s, is about 16 s⁻¹).

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
        self._model = config.vehicle_model()
        self._A = config.allocator().A
        self._n = self._A.shape[1]
        self._max_thrust = float(config.max_thrust)
        self._time_constant = float(config.thrust_time_constant)
        self._lag = self._time_constant > 0.0
        self._M, self._M_inv = self._model.M, self._model.M_inv
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
        x0 = np.concatenate(
            [
                np.asarray(initial_position, dtype=float),
                quaternion_from_matrix(R0),
                R0.T @ np.asarray(initial_velocity, dtype=float),
                R0.T @ np.asarray(w0_W, dtype=float),
                np.zeros(self._n if self._lag else 0),
            ]
        )
        self.DeclareContinuousState(BasicVector(x0))
        self._thrust_port = self.DeclareVectorInputPort("thrust_command", self._n)
        state_only = {self.xc_ticket()}
        self.DeclareVectorOutputPort("p_WU", 3, self._calc_position, state_only)
        self.DeclareVectorOutputPort("v_WU", 3, self._calc_velocity, state_only)
        self.DeclareVectorOutputPort("R_WB", 9, self._calc_attitude, state_only)
        self.DeclareVectorOutputPort("w_WB", 3, self._calc_angular_velocity, state_only)
        self.DeclareVectorOutputPort("nu_B", 6, self._calc_body_velocity, state_only)
        thrust_prerequisites = state_only if self._lag else {self._thrust_port.ticket()}
        self.DeclareVectorOutputPort("thrust", self._n, self._calc_thrust, thrust_prerequisites)

    @property
    def model(self) -> MarineVehicleModel:
        """The ``MarineVehicleModel`` this system integrates."""
        return self._model

    @property
    def num_thrusters(self) -> int:
        return self._n

    def _state(self, context: Context) -> np.ndarray:
        return context.get_continuous_state_vector().CopyToVector()

    def applied_thrust(self, context: Context) -> np.ndarray:
        """The thrusts acting on the hull now: the lag state, or the saturated command."""
        if self._lag:
            return self._state(context)[13:]
        command = self._thrust_port.Eval(context)
        return np.clip(command, -self._max_thrust, self._max_thrust)

    def DoCalcTimeDerivatives(self, context: Context, derivatives: ContinuousState) -> None:
        # Scalar work on Python floats: numpy's per-call overhead on 3- and 4-vectors would
        # dominate this function, which runs a few times per integration step.
        state = self._state(context)
        x = state.tolist()
        qw, qx, qy, qz = x[3:7]
        u, v, w, p, q, r = x[7:13]
        R = rotation_rows(x[3:7])
        command = self._thrust_port.Eval(context)
        f_max = self._max_thrust
        if abs(command).max() > f_max:
            command = np.clip(command, -f_max, f_max)
        if self._lag:
            thrust = np.array(x[13:])
            thrust_dot = ((command - thrust) / self._time_constant).tolist()
        else:
            thrust, thrust_dot = command, []
        bias = self._model._bias(x[7:13], (self._M @ state[_NU]).tolist(), R[2])
        nu_dot = self._M_inv @ (self._A @ thrust - bias)
        # q̇ = ½ q ⊗ [0, ω_B] + λ (1 − |q|²) q (see quaternion_derivative).
        k = QUATERNION_NORM_GAIN * (1.0 - (qw * qw + qx * qx + qy * qy + qz * qz))
        derivatives.get_mutable_vector().SetFromVector(
            np.array(
                [
                    R[0][0] * u + R[0][1] * v + R[0][2] * w,
                    R[1][0] * u + R[1][1] * v + R[1][2] * w,
                    R[2][0] * u + R[2][1] * v + R[2][2] * w,
                    0.5 * (-qx * p - qy * q - qz * r) + k * qw,
                    0.5 * (qw * p + qy * r - qz * q) + k * qx,
                    0.5 * (qw * q + qz * p - qx * r) + k * qy,
                    0.5 * (qw * r + qx * q - qy * p) + k * qz,
                    *nu_dot.tolist(),
                    *thrust_dot,
                ]
            )
        )

    def _calc_position(self, context: Context, output: BasicVector) -> None:
        output.set_value(self._state(context)[_P])

    def _calc_velocity(self, context: Context, output: BasicVector) -> None:
        x = self._state(context)
        output.set_value(rotation_from_quaternion(x[_Q]) @ x[_V])

    def _calc_attitude(self, context: Context, output: BasicVector) -> None:
        output.set_value(rotation_from_quaternion(self._state(context)[_Q]).ravel())

    def _calc_angular_velocity(self, context: Context, output: BasicVector) -> None:
        x = self._state(context)
        output.set_value(rotation_from_quaternion(x[_Q]) @ x[_W])

    def _calc_body_velocity(self, context: Context, output: BasicVector) -> None:
        output.set_value(self._state(context)[_NU])

    def _calc_thrust(self, context: Context, output: BasicVector) -> None:
        output.set_value(self.applied_thrust(context))
