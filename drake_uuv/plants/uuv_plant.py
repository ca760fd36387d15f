"""The UUV of the paper: a discrete double integrator with a rotating attitude, eq. (1)–(2)."""

import numpy as np
from pydrake.systems.framework import Context, DiscreteValues, LeafSystem

from drake_uuv.plants.double_integrator import double_integrator
from drake_uuv.so3 import exp_so3


class UuvPlant(LeafSystem):
    """Kinematic UUV: ``X(k+1) = A X(k) + B R(k) u1(k)``, ``R(k+1) = Exp(u2(k) t) R(k)``.

    ``u1`` is a body-frame acceleration. The paper *left*-multiplies by ``Exp(u2 t)``, so ``u2``
    acts as a world-frame angular velocity (a body rate would be ``Rᵀ u2``); we keep the
    paper's equation and name the port ``w_W`` accordingly.

    The attitude is held as the rotation matrix itself and re-orthonormalised every step with
    one Newton step of the polar decomposition, ``R ← R (3I − RᵀR) / 2``, which squares the
    orthogonality error each step: ``R_WB`` stays orthonormal to machine precision over any
    run length. Both outputs are Drake state output ports (no Python call per step).

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
        # State groups: [p_WU, v_WU] (6) and R_WB row-major (9).
        self._motion_index = self.DeclareDiscreteState(
            np.concatenate([initial_position, initial_velocity])
        )
        self._attitude_index = self.DeclareDiscreteState(np.asarray(initial_R_WB).ravel())
        self.DeclarePeriodicDiscreteUpdateEvent(self._time_step, 0.0, self._update)
        self.DeclareStateOutputPort("state", self._motion_index)
        self.DeclareStateOutputPort("R_WB", self._attitude_index)

    def _update(self, context: Context, discrete_state: DiscreteValues) -> None:
        x = context.get_discrete_state(self._motion_index).get_value()
        R = context.get_discrete_state(self._attitude_index).get_value().reshape(3, 3)
        a_W = R @ self._u1_port.Eval(context)
        R_next = exp_so3(self._w_port.Eval(context) * self._time_step) @ R
        R_next = 1.5 * R_next - 0.5 * (R_next @ (R_next.T @ R_next))
        discrete_state.set_value(self._motion_index, self._A @ x + self._B @ a_W)
        discrete_state.set_value(self._attitude_index, R_next.ravel())
