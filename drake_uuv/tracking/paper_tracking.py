"""The paper's tracking law holding the target at ``q*`` in the body frame."""

import numpy as np
from pydrake.systems.framework import BasicVector, Context, LeafSystem

from drake_uuv.models.tracking_laws import (
    paper_gain_matrix,
    paper_gains,
    paper_tracking_command,
    reference_rotations,
    rotate,
    rotate_back,
    saturate_norm,
)
from drake_uuv.primitives.batch import batch_size_field, per_run
from drake_uuv.scenario.tracking import PaperTracking
from drake_uuv.tracking.base import TrackingSetting
from drake_uuv.tracking.caution import CautiousLoop


class PaperTrackingController(LeafSystem):
    """``u1 = −(2α/t²)(Rᵀ q̂ − q*) − (2/t) Rᵀ ϑ̂`` (paper §III-B,
    :func:`~drake_uuv.models.tracking_laws.paper_tracking_command`).

    Substituting it into the model gives ``ϑ(k+1) = −ϑ(k) + …``: the position error contracts
    for α in (1 − 1/√2, 1 + 1/√2), but the relative velocity is never damped and flips sign
    every step. The metrics report the resulting velocities and accelerations.

    .. pydrake_system::

        name: PaperTrackingController
        input_ports:
        - x_TU_hat
        - R_WB_nav
        output_ports:
        - u1_B
        - u1_W

    - ``x_TU_hat`` (6): the filtered relative state ``[q̂, ϑ̂]``.
    - ``R_WB_nav`` (9, row-major): the current attitude ``R``, as the navigation knows it.
    - ``u1_B`` (3): the body-frame acceleration command [m/s²].
    - ``u1_W`` (3): the same acceleration in the world frame, ``R u1`` with the navigated
      ``R`` (the filter's input: the acceleration the vehicle believes it applies).

    ``q*`` is fixed in ``reference_frame``: the body (the paper's), the world, or the body's
    heading (:func:`~drake_uuv.models.tracking_laws.reference_rotation`); the law then uses
    ``Rᵀ R_WF q*`` in place of q*. With ``max_acceleration`` the command is scaled down to that
    norm (direction kept); the law is static, so there is nothing to wind up. The cautious
    loop's options (:mod:`~drake_uuv.tracking.caution`: the command scaled by the covariance,
    held until the hand-over, within the plant's top speed) add the ports they read,
    ``P_TU``, ``estimator_phase``, ``v_WU_nav``, only when on.

    Sizes are per run: with ``batch_size`` B every port holds B runs row-major
    (:mod:`drake_uuv.primitives.batch`); each run is limited alone (a mask, not a branch), and
    the gain is the same for every run.

    ``config`` (:class:`~drake_uuv.scenario.PaperTracking`) gives α, q*, its frame and the
    limit; the ``setting`` the period t.
    """

    def __init__(
        self, config: PaperTracking, *, setting: TrackingSetting, batch_size: int = 1
    ) -> None:
        super().__init__()
        self.batch_size = B = batch_size_field(batch_size)
        self._time_step = setting.time_step
        self._alpha = float(config.alpha)
        self._k_p, self._k_v = paper_gains(self._time_step, config.alpha)
        self._q_star = np.asarray(config.desired_relative_position, dtype=float)
        reference_rotations(np.eye(3), config.reference_frame)  # Fail early on a bad frame.
        self._frame = config.reference_frame
        self._max_acceleration = config.max_acceleration
        self._x_hat_port = self.DeclareVectorInputPort("x_TU_hat", 6 * B)
        self._attitude_port = self.DeclareVectorInputPort("R_WB_nav", 9 * B)
        self._u1_port = self.DeclareVectorOutputPort("u1_B", 3 * B, self._calc_u1)
        self.DeclareVectorOutputPort("u1_W", 3 * B, self._calc_u1_W)
        self._caution = CautiousLoop(self, config, setting=setting, batch_size=B)

    @property
    def gain(self) -> np.ndarray:
        """The law as a 3×6 world-frame gain ``K = [(2α/t²) I, (2/t) I]`` on ``x̂ − [R q*, 0]``."""
        return paper_gain_matrix(self._time_step, self._alpha)

    def _u1(self, context: Context) -> np.ndarray:
        """``u1`` (B×3), each run limited alone (``|R u1| = |u1|``)."""
        B = self.batch_size
        R_WB = per_run(self._attitude_port.Eval(context), B, 3, 3)
        q_star_B = self._q_star  # the paper's: q* in the body frame
        if self._frame != "body":
            q_star_B = rotate_back(R_WB, rotate(reference_rotations(R_WB, self._frame), q_star_B))
        u1 = paper_tracking_command(
            per_run(self._x_hat_port.Eval(context), B), R_WB, q_star_B, self._k_p, self._k_v
        )
        # The cautious loop works on world axes (P_TU's); off, the paper's numbers untouched.
        if self._caution.scales:
            u1 = rotate_back(R_WB, self._caution.scale_factors(context) * rotate(R_WB, u1))
        u1 = saturate_norm(u1, self._max_acceleration)
        if self._caution.limits:
            u1 = rotate_back(R_WB, self._caution.limited(context, rotate(R_WB, u1)))
        return u1

    def _calc_u1(self, context: Context, output: BasicVector) -> None:
        output.set_value(self._u1(context).ravel())

    def _calc_u1_W(self, context: Context, output: BasicVector) -> None:
        B = self.batch_size
        R_WB = per_run(self._attitude_port.Eval(context), B, 3, 3)
        output.set_value(rotate(R_WB, per_run(self._u1_port.Eval(context), B)).ravel())
