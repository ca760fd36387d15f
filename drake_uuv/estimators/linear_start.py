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
    MeasurementUpdate,
    Ranges,
    RelativeStateEstimator,
)
from drake_uuv.models.filter_runs import (
    congruence_runs,
    noise_model_code,
    prior_share_update_runs,
    range_difference_noise_runs,
    range_difference_update_runs,
)
from drake_uuv.primitives.batch import per_run, tiled


class LinearStart:
    """The paper's KF on the means' ``Y``, declared on ``host`` with its state ``S`` (36 a
    run, row-major; ``P0`` at the start). Every value holds the host's B runs."""

    def __init__(
        self,
        host: RelativeStateEstimator,
        noise_model: str,
        mean_variances: np.ndarray,
        initial_covariance: np.ndarray,
    ) -> None:
        self._host = host
        self._noise_model = noise_model_code(noise_model)  # Fail early.
        self._mean_variances = mean_variances
        self._B = host.batch_size
        self._dof = np.ones(self._B, dtype=np.intp)
        P0 = np.asarray(initial_covariance, dtype=float)
        self._prior_share_index = host.DeclareDiscreteState(tiled(P0, self._B))

    def measurement(
        self, ranges: Ranges, x: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(Y, m, Γ)`` (B each) of the per-sonar means, with the error model's noise at
        ``x`` (B, 6)."""
        z = ranges.z
        variances = ranges.variances(self._mean_variances)
        squared = z * z
        m, gamma = range_difference_noise_runs(self._noise_model, variances, squared)
        if not ranges.exact:
            gamma += ranges.difference_variance(x)
        return 0.5 * (squared[:, 0] - squared[:, 1]), m, gamma

    def update(
        self, prior: Estimate, ranges: Ranges, runs: np.ndarray | None = None
    ) -> MeasurementUpdate:
        """The KF's update on ``Y`` of the runs in ``runs`` (B; default all) whose sonars both
        returned (the others keep their prior: Y needs both ranges)."""
        both = ranges.valid[:, 0] & ranges.valid[:, 1]
        if runs is not None:
            both &= runs
        Y, m, gamma = self.measurement(ranges, prior.x)
        x, P, nis = range_difference_update_runs(prior.x, prior.P, Y, m, gamma, ranges.q_s, both)
        return MeasurementUpdate(x, P, nis, self._dof, both, gamma)

    def prior_share(self, context: Context) -> np.ndarray:
        """``S`` of this step's priors (B, 6, 6)."""
        value = context.get_discrete_state(self._prior_share_index).get_value()
        return per_run(value, self._B, 6, 6)

    def set_prior_share(self, context: Context, S: np.ndarray) -> None:
        """Sets ``S`` of this step's priors ((B, 6, 6), or (6, 6) for every run)."""
        S = np.broadcast_to(np.asarray(S, dtype=float), (self._B, 6, 6))
        context.SetDiscreteState(self._prior_share_index, S.ravel())

    def advance(
        self,
        context: Context,
        P_filtered: np.ndarray,
        updates: list[tuple[np.ndarray, np.ndarray, np.ndarray]],
        linear: np.ndarray,
        discrete_state: DiscreteValues,
    ) -> np.ndarray:
        """Through this tick's linear updates, each ``(q_s (B, 3), Γ (B), runs (B))``, and the
        prediction of the runs in ``linear`` (B): writes the next ``S`` and returns the updated
        one (B, 6, 6), which the hand-over tests (the other runs' ``S`` stays). (With late
        ranges the updates happened at their ping times within the window; ``S`` takes them at
        the tick, with the tick's covariance: an approximation good enough for the hand-over's
        test.)"""
        S = self.prior_share(context)
        for q_s, gamma, runs in updates:
            S = prior_share_update_runs(S, P_filtered, q_s, gamma, runs)
        A, _, _ = self._host.model
        discrete_state.set_value(self._prior_share_index, congruence_runs(S, A, linear).ravel())
        return S

    def restart(self, discrete_state: DiscreteValues, P: np.ndarray, runs: np.ndarray) -> None:
        """The runs in ``runs`` (B) start again from a prior of covariance ``P`` (B, 6, 6),
        filtered at this tick: their next ``S`` is all of it, predicted (``A P Aᵀ``)."""
        A, _, _ = self._host.model
        S = per_run(discrete_state.get_mutable_value(self._prior_share_index), self._B, 6, 6)
        S[runs] = congruence_runs(P, A, runs)[runs]
