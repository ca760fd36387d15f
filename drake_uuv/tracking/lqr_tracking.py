"""An LQR tracking law with reference feed-forward: relative-position holding a vehicle can fly.

The paper's law (§III-B) places the closed-loop eigenvalues of the relative double integrator
at ``1 − α`` and ``−1``: the position error contracts, but the relative velocity is never
damped, so the vehicle alternates between huge velocities every step. This law instead takes
its gain from a discrete LQR on the same model and follows the *moving* reference
``r(k) = R(k) q*`` with a feed-forward built from the attitude generator's plan.

Reference feed-forward (derivation)
-----------------------------------
The relative state ``Υ = [q, ϑ]`` obeys ``Υ(k+1) = A Υ(k) + B (a(k) − ū(k))`` with the world
acceleration ``a = R u1``. The plan gives ``r0 = R(k) q*``, ``r1 = R(k+1) q*`` and
``r2 = R(k+2) q*``. The reference state and acceleration are the unique ones that start at ``r0``
and pass through ``r1`` and ``r2`` under one constant acceleration (the discrete analogue of a
second-order fit)::

    ν(k)    = (−3 r0 + 4 r1 − r2) / (2t)
    a_ff(k) = (r0 − 2 r1 + r2) / t²
    a(k)    = a_ff(k) − K (Υ̂(k) − [r0; ν(k)])

Then ``A [r0; ν] + B a_ff = [r1; (r2 − r0)/(2t)]``: the position part lands *exactly* on the
next reference point, and the velocity part differs from the next step's ``ν(k+1)`` by
``Δ³r(k) / (2t)`` (the third forward difference of the reference positions). With perfect state
knowledge the error ``ε = Υ − [r; ν]`` obeys ``ε(k+1) = (A − BK) ε(k) + [0; Δ³r(k)/(2t)] − B ū``,
so the tracking error converges to zero for any reference whose positions are quadratic in k
and to ``O(t² |d³r/dt³|)`` for a smooth one.

No bounded law can do better in general: exact position tracking forces the velocity to obey
``ϑ(k) + ϑ(k+1) = 2 (r(k+1) − r(k)) / t``, whose solutions carry a ``(−1)^k`` mode that the
Nyquist-frequency content of the sampled reference drives *resonantly*. The paper's Algorithm 2
plan has such content (its minimal rotation whips through up to 1.5 rad per step), so exact
tracking of it would need an unbounded velocity; this is also what the paper's law, whose
velocity eigenvalue is −1, ends up doing.

Acceleration limit and wind-up
------------------------------
With ``max_acceleration`` the world acceleration is scaled down to that norm (direction kept)
and the *saturated* value is both applied (``u1_B = Rᵀ a``) and reported on ``a_W``, so the
Kalman filter predicts with the acceleration the vehicle actually had. The law is static: the
gain acts on the current estimated error and the feed-forward is recomputed from the current
plan each step, with no integrator or filter state, so there is nothing to wind up while
saturated and the law resumes exactly where the unsaturated law would be once the command
falls below the limit.

Caution
-------
The cautious loop's options (:mod:`drake_uuv.tracking.caution`) act on the feedback
``K (Υ̂ − [r; ν])`` only (scaled by the estimate's covariance: the feed-forward is the
plan's, known), and on the limited command (held until the hand-over, within the plant's top
speed); each adds the port it reads (``P_TU``, ``estimator_phase``, ``v_WU_nav``) only when on.
"""

import numpy as np
from pydrake.systems.framework import BasicVector, Context, LeafSystem

from drake_uuv.models.tracking_laws import (
    lqr_gain,
    reference_feedforward,
    reference_rotations,
    rotate,
    rotate_back,
    saturate_norm,
)
from drake_uuv.primitives.batch import batch_size_field, per_run
from drake_uuv.scenario.tracking import LqrTracking
from drake_uuv.tracking.base import TrackingSetting
from drake_uuv.tracking.caution import CautiousLoop


class LqrTrackingController(LeafSystem):
    """``a = sat(a_ff − K (Υ̂ − [r; ν]))``, ``u1 = Rᵀ a``, with ``r = R_WF q*``: q* fixed in the
    frame F of ``reference_frame`` (the body by default, so that r turns with R as in the
    paper; or the world, or the body's heading).

    ``K`` from :func:`lqr_gain`; the reference ``[r; ν]`` and ``a_ff`` from the attitude plan by
    :func:`reference_feedforward`; ``sat`` is :func:`saturate_norm` (see the module notes for
    the derivation, the residual and why nothing winds up). With ``feedforward=False`` the
    reference is ``[R(k) q*, 0]`` and ``a_ff = 0`` (the plan is not read): the law then lags.

    .. pydrake_system::

        name: LqrTrackingController
        input_ports:
        - x_TU_hat
        - R_WB_nav
        - R_WB_plan
        output_ports:
        - u1_B
        - u1_W

    - ``x_TU_hat`` (6): the filtered relative state ``[q̂, ϑ̂]``.
    - ``R_WB_nav`` (9, row-major): the current attitude ``R(k)``, as the navigation knows
      it.
    - ``R_WB_plan`` (18): the planned ``R(k+1)`` and ``R(k+2)``, row-major (the attitude
      generator's output of the same name).
    - ``u1_B`` (3): the body-frame acceleration command [m/s²].
    - ``u1_W`` (3): the same acceleration in the world frame, ``R u1`` with the navigated
      ``R`` (the filter's input: the acceleration the vehicle believes it applies).

    Sizes are per run: with ``batch_size`` B every port holds B runs row-major
    (:mod:`drake_uuv.primitives.batch`); each run is limited alone (a mask, not a branch), and
    the gain ``K`` is the same for every run.

    ``config`` (:class:`~drake_uuv.scenario.LqrTracking`) gives q*, its frame, the weights,
    the limit and whether to feed forward; the ``setting`` the period t.
    """

    def __init__(
        self, config: LqrTracking, *, setting: TrackingSetting, batch_size: int = 1
    ) -> None:
        super().__init__()
        self.batch_size = B = batch_size_field(batch_size)
        self._time_step = setting.time_step
        self._q_star = np.asarray(config.desired_relative_position, dtype=float)
        reference_rotations(np.eye(3), config.reference_frame)  # Fail early on a bad frame.
        self._frame = config.reference_frame
        self._K, _ = lqr_gain(
            self._time_step, config.position_weight, config.velocity_weight, config.input_weight
        )
        self._max_acceleration = config.max_acceleration
        self._feedforward = config.feedforward
        self._x_hat_port = self.DeclareVectorInputPort("x_TU_hat", 6 * B)
        self._attitude_port = self.DeclareVectorInputPort("R_WB_nav", 9 * B)
        self._plan_port = self.DeclareVectorInputPort("R_WB_plan", 18 * B)
        self.DeclareVectorOutputPort("u1_B", 3 * B, self._calc_u1)
        self._u1_W_port = self.DeclareVectorOutputPort("u1_W", 3 * B, self._calc_u1_W)
        self._caution = CautiousLoop(self, config, setting=setting, batch_size=B)

    @property
    def gain(self) -> np.ndarray:
        """The 3×6 world-frame gain ``K`` (:func:`~drake_uuv.models.tracking_laws.lqr_gain`)."""
        return self._K.copy()

    def reference(self, context: Context) -> tuple[np.ndarray, np.ndarray]:
        """``([r(k); ν(k)], a_ff(k))`` (B×6, B×3) in the world frame (``([r(k); 0], 0)``
        without the feed-forward)."""
        B = self.batch_size
        R_WB = per_run(self._attitude_port.Eval(context), B, 3, 3)
        frame, q_star = self._frame, self._q_star
        r0 = rotate(reference_rotations(R_WB, frame), q_star)
        if not self._feedforward:
            return np.concatenate([r0, np.zeros((B, 3))], axis=1), np.zeros((B, 3))
        plan = reference_rotations(per_run(self._plan_port.Eval(context), B, 2, 3, 3), frame)
        r = rotate(plan, q_star)  # B×2×3: r(k+1), r(k+2)
        return reference_feedforward(r0, r[:, 0], r[:, 1], self._time_step)

    def acceleration(self, context: Context) -> np.ndarray:
        """The applied world acceleration ``a(k)`` (B×3), after the limit (and the cautious
        loop's scaling, hold and top speed, :mod:`~drake_uuv.tracking.caution`, when on)."""
        x_reference, a_ff = self.reference(context)
        error = per_run(self._x_hat_port.Eval(context), self.batch_size) - x_reference
        # K applied run by run (a stacked product), never one product over the batch.
        feedback = (self._K @ error[:, :, np.newaxis])[:, :, 0]
        if self._caution.scales:
            feedback = self._caution.scale_factors(context) * feedback
        a = saturate_norm(a_ff - feedback, self._max_acceleration)
        return self._caution.limited(context, a) if self._caution.limits else a

    def _calc_u1(self, context: Context, output: BasicVector) -> None:
        B = self.batch_size
        R_WB = per_run(self._attitude_port.Eval(context), B, 3, 3)
        output.set_value(rotate_back(R_WB, per_run(self._u1_W_port.Eval(context), B)).ravel())

    def _calc_u1_W(self, context: Context, output: BasicVector) -> None:
        output.set_value(self.acceleration(context).ravel())
