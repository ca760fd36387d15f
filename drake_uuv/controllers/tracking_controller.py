"""The paper's tracking law holding the target at ``q*`` in the body frame."""

import numpy as np
from pydrake.systems.framework import BasicVector, Context, LeafSystem


class TrackingController(LeafSystem):
    """``u1 = −(2α/t²)(Rᵀ q̂ − q*) − (2/t) Rᵀ ϑ̂`` (paper §III-B).

    Substituting it into the model gives ``ϑ(k+1) = −ϑ(k) + …``: the position error contracts
    for α in (1 − 1/√2, 1 + 1/√2), but the relative velocity is never damped and flips sign
    every step. The metrics report the resulting velocities and accelerations.

    .. pydrake_system::

        name: TrackingController
        input_ports:
        - x_hat
        - R_WB
        output_ports:
        - u1_B
        - a_W

    - ``x_hat`` (6): the filtered relative state ``[q̂, ϑ̂]``.
    - ``R_WB`` (9, row-major): the current attitude.
    - ``u1_B`` (3): the body-frame acceleration command [m/s²].
    - ``a_W`` (3): the same acceleration in the world frame, ``R u1`` (the filter's input).

    With ``max_acceleration`` the command is scaled down to that norm (direction kept); the law
    is static, so there is nothing to wind up.
    """

    def __init__(
        self,
        time_step: float,
        alpha: float,
        desired_relative_position_B: np.ndarray,
        max_acceleration: float | None = None,
    ) -> None:
        super().__init__()
        t = float(time_step)
        self._position_gain = 2.0 * alpha / (t * t)
        self._velocity_gain = 2.0 / t
        self._q_star = np.asarray(desired_relative_position_B, dtype=float)
        self._q_star_floats = self._q_star.tolist()
        self._neg_position_gain = -self._position_gain
        self._max_acceleration = max_acceleration
        self._x_hat_port = self.DeclareVectorInputPort("x_hat", 6)
        self._attitude_port = self.DeclareVectorInputPort("R_WB", 9)
        self._u1_port = self.DeclareVectorOutputPort("u1_B", 3, self._calc_u1)
        self.DeclareVectorOutputPort("a_W", 3, self._calc_a_W)

    def _u1(self, context: Context) -> np.ndarray:
        x_hat = self._x_hat_port.Eval(context)
        R_BW = self._attitude_port.Eval(context).reshape(3, 3).T
        # The products stay numpy (BLAS); the element-wise rest, in the same order, on floats.
        position = (R_BW @ x_hat[:3]).tolist()
        velocity = (R_BW @ x_hat[3:]).tolist()
        kp, kv, r = self._neg_position_gain, self._velocity_gain, self._q_star_floats
        u1 = np.array([kp * (position[i] - r[i]) - kv * velocity[i] for i in range(3)])
        if self._max_acceleration is not None:  # |R u1| = |u1|
            u1_norm = float(np.sqrt(u1 @ u1))
            if u1_norm > self._max_acceleration:
                u1 *= self._max_acceleration / u1_norm
        return u1

    def _calc_u1(self, context: Context, output: BasicVector) -> None:
        output.set_value(self._u1(context))

    def _calc_a_W(self, context: Context, output: BasicVector) -> None:
        R_WB = self._attitude_port.Eval(context).reshape(3, 3)
        output.set_value(R_WB @ self._u1_port.Eval(context))
