"""What the raw-range filters share: the paper's linear KF as a start, and the hand-over."""

import math
from typing import Any

import numpy as np
from pydrake.systems.framework import Context, DiscreteValues

from drake_uuv.estimators.base import FilteredEstimate, MeasurementUpdate, RelativeStateEstimator
from drake_uuv.models.filters import HandoverPolicy, range_difference_update
from drake_uuv.models.handover import HandoverRule, prior_share_predict, prior_share_update
from drake_uuv.models.measurement import VALID, range_difference_noise
from drake_uuv.scenario import Scenario

# The start-phase state (discrete-state group 2): [phase, linear updates done].
LINEAR_PHASE, RANGE_PHASE = 1.0, 0.0


class LinearStartEstimator(RelativeStateEstimator):
    """Base of the filters on the two raw ranges that begin as the paper's linear KF.

    Subclasses supply :meth:`range_update`, the update on the raw ranges (EKF, UKF, particle
    filter). Until the hand-over, updates are the paper's KF on ``Y = ½(z1² − z2²)`` built
    from the per-sonar sample means ``z`` of all ``f`` samples, its noise mean and variance from
    the sonar's :func:`~drake_uuv.models.measurement.range_difference_noise` with the variances
    ``η/f`` of the means (one noise model). ``Y`` is exactly linear in ``q``, so this start
    converges from any prior without a linearisation point; it needs both ranges (a step with
    one sonar only predicts). After the hand-over, updates use :meth:`range_update` with the
    sonars that returned, ``R = diag(η/f)``.

    The hand-over, one way, after the linear update at which ``handover`` says so:

    * :class:`~drake_uuv.models.handover.HandoverRule` (the default): once the prior's share
      of the KF's covariance is small and the cross-range angle ``√tr(P⊥)/d`` is below its
      tolerance (see :mod:`drake_uuv.models.handover` for the rule and its measurements). The
      prior's share ``S = Φ P0 Φᵀ`` is discrete state, advanced beside the KF.
    * :class:`~drake_uuv.models.filters.HandoverPolicy`: the absolute
      ``trace(P_qq) ≤ threshold`` of the first raw-range EKF.

    Discrete state: groups 0 and 1 as in the base class; group 2 ``[phase, linear updates]``
    (:data:`LINEAR_PHASE` 1, :data:`RANGE_PHASE` 0; an update counts when it was applied:
    VALID, not gated); group 3 the prior's share ``S`` (36, row-major; ``P0`` at the start).

    Measurement ports (the common ports follow, see the base class):

    - ``range_samples`` (2f): sonar 1's f samples then sonar 2's [m]; NaN without a return.
    - ``b_W`` (3): world sonar baseline ``q_s = R_WB b``.

    A subclass declares its own state and ports, then calls :meth:`_declare_ports`.
    """

    def __init__(
        self,
        time_step: float,
        acceleration_covariance: np.ndarray,
        initial_estimate: np.ndarray,
        initial_covariance: np.ndarray,
        noise_variances: np.ndarray,
        samples_per_step: int = 1,
        noise_model: str = "derived",
        handover: HandoverRule | HandoverPolicy | None = None,
        gate_probability: float | None = None,
        vehicle_motion: str = "commanded",
    ) -> None:
        super().__init__(
            time_step,
            acceleration_covariance,
            initial_estimate,
            initial_covariance,
            gate_probability,
            vehicle_motion,
        )
        if isinstance(samples_per_step, bool) or int(samples_per_step) != samples_per_step:
            raise ValueError(f"samples_per_step: must be an integer ≥ 1, got {samples_per_step!r}")
        if samples_per_step < 1:
            raise ValueError(f"samples_per_step: must be an integer ≥ 1, got {samples_per_step!r}")
        eta = np.asarray(noise_variances, dtype=float).reshape(-1)
        if eta.shape != (2,) or not np.all(np.isfinite(eta)) or np.any(eta <= 0.0):
            raise ValueError(f"noise_variances: must be two numbers > 0, got {noise_variances!r}")
        self._f = int(samples_per_step)
        self._mean_variances = eta / self._f
        self._R = np.diag(self._mean_variances)  # the per-sonar means' covariance
        self._noise_model = noise_model
        range_difference_noise(noise_model, self._mean_variances, np.ones(2))  # Fail early.
        self._policy = handover if handover is not None else self.default_handover()
        phase = LINEAR_PHASE if self._policy.linear_start else RANGE_PHASE
        self._start_index = self.DeclareDiscreteState(np.array([phase, 0.0]))
        P0 = np.asarray(initial_covariance, dtype=float)
        self._prior_share_index = self.DeclareDiscreteState(P0.ravel())

    @staticmethod
    def scenario_arguments(scenario: Scenario) -> dict[str, Any]:
        """The constructor arguments every raw-range filter takes from ``scenario`` (its
        estimator section and the sonar), for a subclass's ``from_scenario``."""
        e = scenario.estimator
        return dict(
            time_step=scenario.time_step,
            acceleration_covariance=e.filter_acceleration_covariance(
                scenario.target.acceleration_covariance
            ),
            initial_estimate=np.asarray(e.initial_estimate),
            initial_covariance=np.asarray(e.initial_covariance),
            noise_variances=np.asarray(scenario.sonar.noise_variances),
            samples_per_step=scenario.sonar.samples_per_step,
            noise_model=e.noise_model,
            handover=e.handover_rule(),
            gate_probability=e.gate_probability,
            vehicle_motion=e.vehicle_motion,
        )

    def default_handover(self) -> HandoverRule | HandoverPolicy:
        """The hand-over used when none is given: :class:`HandoverRule` ``()``."""
        return HandoverRule()

    def _declare_ports(self) -> None:
        """Declares the measurement inputs, then the base class's common ports."""
        self._samples_port = self.DeclareVectorInputPort("range_samples", 2 * self._f)
        self._b_W_port = self.DeclareVectorInputPort("b_W", 3)
        self._declare_common_ports([self._samples_port, self._b_W_port])

    @property
    def handover(self) -> HandoverRule | HandoverPolicy:
        return self._policy

    @property
    def start_state_index(self) -> int:
        """The discrete-state group ``[phase, linear updates done]``."""
        return self._start_index

    @property
    def prior_share_index(self) -> int:
        """The discrete-state group of the prior's share ``S`` of the KF covariance (36)."""
        return self._prior_share_index

    def in_linear_phase(self, context: Context) -> bool:
        """Whether this step's update is the linear start's."""
        return context.get_discrete_state(self._start_index).get_value()[0] == LINEAR_PHASE

    def range_update(
        self,
        context: Context,
        x_prior: np.ndarray,
        P_prior: np.ndarray,
        z: np.ndarray,
        q_s: np.ndarray,
        sonars: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, float]:
        """The update on the raw ranges ``z`` (per-sonar means) of the ``sonars`` that returned:
        ``(x, P, nis)``."""
        raise NotImplementedError

    def _means(self, context: Context, status: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The per-sonar sample means and which sonars returned a usable range."""
        samples = self._samples_port.Eval(context).reshape(2, self._f)
        valid = (np.asarray(status) == VALID) & np.all(np.isfinite(samples), axis=1)
        return samples.mean(axis=1), valid

    def _linear_measurement(self, z: np.ndarray) -> tuple[float, float, float]:
        """``(Y, m, Γ)`` of the linear start from the per-sonar means."""
        m, gamma = range_difference_noise(self._noise_model, self._mean_variances, z * z)
        return 0.5 * (z[0] * z[0] - z[1] * z[1]), float(m), float(gamma)

    def measurement_update(
        self, context: Context, x_prior: np.ndarray, P_prior: np.ndarray, status: np.ndarray
    ) -> MeasurementUpdate | None:
        z, valid = self._means(context, status)
        if not valid.any():
            return None
        q_s = self._b_W_port.Eval(context)
        if self.in_linear_phase(context):
            if not valid.all():
                return None  # Y needs both ranges; predict until both return.
            Y, m, gamma = self._linear_measurement(z)
            x, P, nis = range_difference_update(x_prior, P_prior, Y, m, gamma, q_s)
            return MeasurementUpdate(x, P, nis, 1)
        sonars = np.flatnonzero(valid)
        x, P, nis = self.range_update(context, x_prior, P_prior, z, q_s, sonars)
        return MeasurementUpdate(x, P, nis, int(sonars.size))

    def advance_extra_state(
        self, context: Context, filtered: FilteredEstimate, discrete_state: DiscreteValues
    ) -> None:
        phase, done = context.get_discrete_state(self._start_index).get_value()
        if phase != LINEAR_PHASE:
            return  # groups 2 and 3 keep their values
        S = context.get_discrete_state(self._prior_share_index).get_value().reshape(6, 6)
        if filtered.status == VALID and math.isfinite(filtered.nis):
            done += 1
            q_s = self._b_W_port.Eval(context)
            z, _ = self._means(context, self._status_port.Eval(context))
            S = prior_share_update(S, filtered.P, q_s, self._linear_measurement(z)[2])
            if self._due(filtered, int(done), q_s, S):
                phase = RANGE_PHASE
        discrete_state.set_value(self._start_index, np.array([phase, done]))
        discrete_state.set_value(self._prior_share_index, prior_share_predict(S, self._A).ravel())

    def _due(self, filtered: FilteredEstimate, done: int, q_s: np.ndarray, S: np.ndarray) -> bool:
        if isinstance(self._policy, HandoverPolicy):
            return self._policy.handover_due(filtered.P, done)
        return self._policy.handover_due(
            filtered.P,
            done,
            x=filtered.x,
            q_s=q_s,
            prior_covariance=S,
            noise_std=np.sqrt(self._mean_variances),
        )
