"""The linear start of a raw-range filter: the paper's KF on the range difference of the means.

A component of :class:`~drake_uuv.estimators.range_filter.RangeFilter`. A range is nearly
linear in ``q`` only once the position error is small against the range (second-order error
``σ⊥²/(2d)``). From the paper's prior (``x̂ = 0``, ``P = I``, true ``|q| ≈ 3 m``) an EKF
linearises where both lines of sight are ±q_s, its two Jacobian rows antiparallel, and it can
lock onto the mirror solution (the ranges are symmetric about any plane through the
baseline). ``Y = ½(z1² − z2²)`` is *exactly* linear in ``q``, so the paper's KF converges from
any prior without a linearisation point, and its covariance is exact for its second moments.
So a raw-range filter begins as that KF, on ``Y`` built from the per-sonar sample means ``z``
of all ``f`` samples, its noise mean and variance from the sonar's own
:func:`~drake_uuv.models.measurement.range_difference_noise` with the variances ``η/f`` of the
means (one noise model), until its hand-over policy says otherwise. It needs both ranges: a
step with one sonar only predicts.

It also keeps the prior's share ``S = Φ P0 Φᵀ`` of the KF's covariance (``Φ`` the KF's error
transition since step 0), which :class:`~drake_uuv.models.handover.HandoverRule` tests.
"""

import numpy as np
from pydrake.systems.framework import Context, DiscreteValues

from drake_uuv.estimators.base import (
    Estimate,
    FilteredEstimate,
    MeasurementUpdate,
    Ranges,
    RelativeStateEstimator,
)
from drake_uuv.models.filters import range_difference_update
from drake_uuv.models.handover import prior_share_predict, prior_share_update
from drake_uuv.models.measurement import range_difference_noise


class LinearStart:
    """The paper's KF on the means' ``Y``, declared on ``host`` with its state ``S`` (36,
    row-major; ``P0`` at the start)."""

    def __init__(
        self,
        host: RelativeStateEstimator,
        noise_model: str,
        mean_variances: np.ndarray,
        initial_covariance: np.ndarray,
    ) -> None:
        range_difference_noise(noise_model, mean_variances, np.ones(2))  # Fail early.
        self._host = host
        self._noise_model = noise_model
        self._mean_variances = mean_variances
        P0 = np.asarray(initial_covariance, dtype=float)
        self._prior_share_index = host.DeclareDiscreteState(P0.ravel())

    def measurement(self, ranges: Ranges, x: np.ndarray) -> tuple[float, float, float]:
        """``(Y, m, Γ)`` of the per-sonar means, with the error model's noise at ``x``."""
        z = ranges.z
        variances = ranges.variances(self._mean_variances)
        m, gamma = range_difference_noise(self._noise_model, variances, z * z)
        gamma = float(gamma)
        if not ranges.exact:
            gamma += ranges.difference_variance(x)
        return 0.5 * (z[0] * z[0] - z[1] * z[1]), float(m), gamma

    def update(self, prior: Estimate, ranges: Ranges) -> MeasurementUpdate | None:
        """The KF's update on ``Y``; None unless both sonars returned."""
        if not ranges.valid.all():
            return None  # Y needs both ranges; predict until both return.
        Y, m, gamma = self.measurement(ranges, prior.x)
        x, P, nis = range_difference_update(prior.x, prior.P, Y, m, gamma, ranges.q_s)
        return MeasurementUpdate(x, P, nis, 1, gamma)

    def prior_share(self, context: Context) -> np.ndarray:
        """``S`` of this step's prior (6×6)."""
        return context.get_discrete_state(self._prior_share_index).get_value().reshape(6, 6)

    def set_prior_share(self, context: Context, S: np.ndarray) -> None:
        """Sets ``S`` of this step's prior."""
        context.SetDiscreteState(self._prior_share_index, np.asarray(S, dtype=float).ravel())

    def advance(
        self,
        context: Context,
        filtered: FilteredEstimate,
        updates: list[tuple[np.ndarray, float]],
        discrete_state: DiscreteValues,
    ) -> np.ndarray:
        """Through this tick's linear updates ``(q_s, Γ)`` and the prediction: writes the next
        ``S`` and returns the updated one, which the hand-over tests. (With late ranges the
        updates happened at their ping times within the window; ``S`` takes them at the tick,
        with the tick's covariance: an approximation good enough for the hand-over's test.)"""
        S = self.prior_share(context)
        for q_s, gamma in updates:
            S = prior_share_update(S, filtered.P, q_s, gamma)
        A, _, _ = self._host.model
        discrete_state.set_value(self._prior_share_index, prior_share_predict(S, A).ravel())
        return S
