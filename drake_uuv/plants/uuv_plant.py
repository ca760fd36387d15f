"""The UUV of the paper: a discrete double integrator with a rotating attitude, eq. (1)–(2)."""

import numpy as np
from pydrake.systems.framework import BasicVector, Context, DiscreteValues, LeafSystem

from drake_uuv.plants.double_integrator import double_integrator
from drake_uuv.so3 import (
    matrix_from_quaternion,
    norm,
    quaternion_from_matrix,
    quaternion_from_rotation_vector,
    quaternion_multiply,
)


class UuvPlant(LeafSystem):
    """Kinematic UUV: ``X(k+1) = A X(k) + B R(k) u1(k)``, ``R(k+1) = Exp(u2(k) t) R(k)``.

    ``u1`` is a body-frame acceleration. The paper *left*-multiplies by ``Exp(u2 t)``, so ``u2``
    acts as a world-frame angular velocity (a body rate would be ``Rᵀ u2``); we keep the
    paper's equation and name the port ``w_W`` accordingly.

    The attitude is held as a unit quaternion renormalised every step, so ``R_WB`` stays
    orthonormal to machine precision over any run length.

    .. pydrake_system::

        name: UuvPlant
        input_ports:
        - u1_B
        - w_W
        output_ports:
        - state
        - R_WB

    - ``u1_B`` (3): commanded acceleration in the body frame [m/s²].
    - ``w_W`` (3): angular velocity command ``u2`` [rad/s], world frame (see above).
    - ``state`` (6): ``[p_WU, v_WU]``, position and velocity of the vehicle in the world.
    - ``R_WB`` (9): attitude ``R`` (body to world), row-major.
    """

    def __init__(
        self,
        time_step: float,
        initial_position: np.ndarray,
        initial_velocity: np.ndarray,
        initial_R_WB: np.ndarray,
    ) -> None:
        super().__init__()
        self._time_step = float(time_step)
        self._A, self._B = double_integrator(self._time_step)
        self._u1_port = self.DeclareVectorInputPort("u1_B", 3)
        self._w_port = self.DeclareVectorInputPort("w_W", 3)
        initial = np.concatenate(
            [initial_position, initial_velocity, quaternion_from_matrix(np.asarray(initial_R_WB))]
        )
        # State: [p (3), v (3), quaternion of R_WB (4)].
        self._state_index = self.DeclareDiscreteState(initial)
        self.DeclarePeriodicDiscreteUpdateEvent(self._time_step, 0.0, self._update)
        self.DeclareVectorOutputPort(
            "state", 6, self._calc_state, prerequisites_of_calc={self.xd_ticket()}
        )
        self.DeclareVectorOutputPort(
            "R_WB", 9, self._calc_attitude, prerequisites_of_calc={self.xd_ticket()}
        )

    def _update(self, context: Context, discrete_state: DiscreteValues) -> None:
        x = context.get_discrete_state(self._state_index).get_value()
        quaternion = x[6:]
        R = matrix_from_quaternion(quaternion)
        a_W = R @ self._u1_port.Eval(context)
        next_quaternion = quaternion_multiply(
            quaternion_from_rotation_vector(self._w_port.Eval(context) * self._time_step),
            quaternion,
        )
        next_x = np.empty(10)
        next_x[:6] = self._A @ x[:6] + self._B @ a_W
        next_x[6:] = next_quaternion / norm(next_quaternion)
        discrete_state.set_value(self._state_index, next_x)

    def _calc_state(self, context: Context, output: BasicVector) -> None:
        output.set_value(context.get_discrete_state(self._state_index).get_value()[:6])

    def _calc_attitude(self, context: Context, output: BasicVector) -> None:
        quaternion = context.get_discrete_state(self._state_index).get_value()[6:]
        output.set_value(matrix_from_quaternion(quaternion).ravel())
