"""What the raw-range filters share: the paper's linear KF as a start, the hand-over, and
the particle cloud a filter carries where a Gaussian cannot describe the posterior."""

import math
from typing import Any

import numpy as np
from pydrake.common import RandomDistribution
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, DiscreteValues, ValueProducer

from drake_uuv.estimators.base import FilteredEstimate, MeasurementUpdate, RelativeStateEstimator
from drake_uuv.models.filters import HandoverPolicy, range_difference_update
from drake_uuv.models.handover import HandoverRule, prior_share_predict, prior_share_update
from drake_uuv.models.measurement import VALID, range_difference_noise
from drake_uuv.models.particle_filter import (
    STATE_SIZE,
    ParticleFilterParameters,
    initial_particles,
    pf_predict,
    pf_update,
    weighted_moments,
)
from drake_uuv.primitives.random_input import declare_random_input
from drake_uuv.scenario import Scenario

# The start-phase state (discrete-state group 2): [phase, linear updates done]. A step's
# update is the linear KF's, the subclass's Gaussian range update, or the particles'.
LINEAR_PHASE, RANGE_PHASE, PARTICLE_PHASE = 1.0, 0.0, 2.0

# The uniform draw of the random port becomes a generator seed with this many bits (a double
# in [0, 1) carries 53).
_SEED_BITS = 53


class LinearStartEstimator(RelativeStateEstimator):
    """Base of the filters on the two raw ranges that begin as the paper's linear KF.

    Subclasses supply :meth:`range_update`, the Gaussian update on the raw ranges (EKF, UKF),
    or declare ``gaussian = False`` and update on particles only (the particle filter).
    Until the hand-over, updates are the paper's KF on ``Y = ½(z1² − z2²)`` built from the
    per-sonar sample means ``z`` of all ``f`` samples, its noise mean and variance from the
    sonar's :func:`~drake_uuv.models.measurement.range_difference_noise` with the variances
    ``η/f`` of the means (one noise model). ``Y`` is exactly linear in ``q``, so this start
    converges from any prior without a linearisation point; it needs both ranges (a step with
    one sonar only predicts). After the hand-over, updates use the raw ranges of the sonars
    that returned, ``R = diag(η/f)``.

    Phases (the first element of discrete-state group 2), after each applied update:

    * :data:`LINEAR_PHASE` → :data:`RANGE_PHASE` (the Gaussian range update) when the
      hand-over is due:

      - :class:`~drake_uuv.models.handover.HandoverRule` (the default): once the prior's
        share of the KF's covariance is small and the cross-range angle ``√tr(P⊥)/d`` is
        below its tolerance (see :mod:`drake_uuv.models.handover` for the rule and its
        measurements). The prior's share ``S = Φ P0 Φᵀ`` is discrete state, advanced beside
        the KF.
      - :class:`~drake_uuv.models.filters.HandoverPolicy`: the absolute
        ``trace(P_qq) ≤ threshold`` of the first raw-range EKF.

    * :data:`LINEAR_PHASE` → :data:`PARTICLE_PHASE` when the rule's prior is forgotten but
      its Gaussian test fails (with ``HandoverRule.particle_bridge``; always for a filter
      without a Gaussian update): particles are drawn from the KF's ``N(x̂, P)``.
    * :data:`PARTICLE_PHASE` → :data:`RANGE_PHASE` when the rule's Gaussian test holds on the
      particles' mean and covariance, and back (particles drawn from the Gaussian filter's
      ``N(x̂, P)``) when an angle exceeds ``fallback_factor`` times its tolerance
      (:meth:`~drake_uuv.models.handover.HandoverRule.fallback_due`), or drawn from the
      step's prior widened by NIS/2 and weighed by the step's ranges when the innovation is
      beyond any chance (:meth:`~drake_uuv.models.handover.HandoverRule.lost`).

    The particles are :mod:`drake_uuv.models.particle_filter`'s regularised particle filter:
    the filtered estimate of a particle step is the weighted mean and covariance of the
    predicted particles reweighted by the ranges' likelihood (a cache entry, deterministic
    in the inputs and the state); the periodic update resamples, regularises and moves each
    particle by the model with its own target acceleration. Randomness enters only through
    the random input port ``particle_seed`` (one uniform draw per step, read only in the
    periodic update, where it seeds that update's ``numpy.random.Generator``), so a run is
    reproducible from the diagram's seed.

    Discrete state: groups 0 and 1 as in the base class (with particles, the predicted
    cloud's mean and covariance); group 2 ``[phase, linear updates]`` (an update counts when
    it was applied: VALID, not gated); group 3 the prior's share ``S`` (36, row-major; ``P0``
    at the start); with particles, group 4 the predicted particles (6N, state-major: the N
    values of q_x, then of q_y, …) and group 5 their log weights (N).

    Measurement ports (the common ports follow, see the base class):

    - ``range_samples`` (2f): sonar 1's f samples then sonar 2's [m]; NaN without a return.
    - ``b_W`` (3): world sonar baseline ``q_s = R_WB b``.
    - ``particle_seed`` (1, random uniform in [0, 1), last; only with particles): seeds the
      step's draw, resampling, regularisation and process noise.

    A subclass declares its own state and ports, then calls :meth:`_declare_ports`.
    """

    #: Whether the subclass has a Gaussian range update (:meth:`range_update`).
    gaussian: bool = True

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
        particle_parameters: ParticleFilterParameters | None = None,
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
        if particle_parameters is None:
            particle_parameters = ParticleFilterParameters()
        if not isinstance(particle_parameters, ParticleFilterParameters):
            raise ValueError(
                f"particle_parameters: must be ParticleFilterParameters, got "
                f"{particle_parameters!r}"
            )
        uses_particles = not self.gaussian or (
            isinstance(self._policy, HandoverRule) and self._policy.particle_bridge
        )
        self._parameters = particle_parameters if uses_particles else None
        self._W = np.asarray(acceleration_covariance, dtype=float)
        if self._parameters is not None:
            n = self._parameters.count
            self._particles_index = self.DeclareDiscreteState(np.zeros(STATE_SIZE * n))
            self._log_weights_index = self.DeclareDiscreteState(np.full(n, -math.log(n)))

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
            particle_parameters=e.particle_parameters(),
        )

    def default_handover(self) -> HandoverRule | HandoverPolicy:
        """The hand-over used when none is given: :class:`HandoverRule` with the particle
        bridge."""
        return HandoverRule(particle_bridge=True)

    def _declare_ports(self) -> None:
        """Declares the measurement inputs, the base class's common ports, and with particles
        the random input ``particle_seed`` and the particle posterior's cache entry."""
        self._samples_port = self.DeclareVectorInputPort("range_samples", 2 * self._f)
        self._b_W_port = self.DeclareVectorInputPort("b_W", 3)
        self._declare_common_ports([self._samples_port, self._b_W_port])
        if self._parameters is None:
            return
        self._seed_port = declare_random_input(
            self, "particle_seed", 1, RandomDistribution.kUniform
        )
        n = self._parameters.count
        # The posterior log weights, shared by the filtered output and the periodic update.
        self._posterior = self.DeclareCacheEntry(
            "particle posterior",
            ValueProducer(
                allocate=AbstractValue.Make((np.zeros(6), np.eye(6), math.nan, np.zeros(n))).Clone,
                calc=self._calc_posterior,
            ),
            {
                self._samples_port.ticket(),
                self._b_W_port.ticket(),
                self._status_port.ticket(),
                self.xd_ticket(),
                *(port.ticket() for port in self._vehicle_ports),
            },
        )

    @property
    def handover(self) -> HandoverRule | HandoverPolicy:
        return self._policy

    @property
    def particle_parameters(self) -> ParticleFilterParameters | None:
        """The particles' count and kernel, or None for a filter that never uses particles."""
        return self._parameters

    @property
    def start_state_index(self) -> int:
        """The discrete-state group ``[phase, linear updates done]``."""
        return self._start_index

    @property
    def prior_share_index(self) -> int:
        """The discrete-state group of the prior's share ``S`` of the KF covariance (36)."""
        return self._prior_share_index

    @property
    def particles_index(self) -> int:
        """The discrete-state group of the predicted particles (6N, state-major)."""
        return self._particles_index

    @property
    def log_weights_index(self) -> int:
        """The discrete-state group of the particles' log weights (N)."""
        return self._log_weights_index

    def phase(self, context: Context) -> float:
        """This step's phase: :data:`LINEAR_PHASE`, :data:`RANGE_PHASE` or
        :data:`PARTICLE_PHASE`."""
        return float(context.get_discrete_state(self._start_index).get_value()[0])

    def in_linear_phase(self, context: Context) -> bool:
        """Whether this step's update is the linear start's."""
        return self.phase(context) == LINEAR_PHASE

    def particles(self, context: Context) -> np.ndarray:
        """The predicted particles of this step as a 6×N array: relative states ``Υ``.

        With ``vehicle_motion="navigation"`` the state holds them less the vehicle's state
        (``−X̄``, the target's particles negated) and this adds ``X`` of the step.
        """
        value = context.get_discrete_state(self._particles_index).get_value()
        particles = value.reshape(STATE_SIZE, self._parameters.count)
        if self._navigation:
            return particles + self._vehicle_state(context)[:, np.newaxis]
        return particles

    def range_update(
        self,
        context: Context,
        x_prior: np.ndarray,
        P_prior: np.ndarray,
        z: np.ndarray,
        q_s: np.ndarray,
        sonars: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, float]:
        """The Gaussian update on the raw ranges ``z`` (per-sonar means) of the ``sonars`` that
        returned: ``(x, P, nis)``."""
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

    def _calc_posterior(self, context: Context, value: AbstractValue) -> None:
        z, valid = self._means(context, self._status_port.Eval(context))
        log_weights = context.get_discrete_state(self._log_weights_index).get_value()
        value.set_value(
            pf_update(
                self.particles(context),
                log_weights,
                z,
                self._b_W_port.Eval(context),
                self._R,
                np.flatnonzero(valid),
            )
        )

    def measurement_update(
        self, context: Context, x_prior: np.ndarray, P_prior: np.ndarray, status: np.ndarray
    ) -> MeasurementUpdate | None:
        z, valid = self._means(context, status)
        if not valid.any():
            return None
        phase = self.phase(context)
        if phase == LINEAR_PHASE:
            if not valid.all():
                return None  # Y needs both ranges; predict until both return.
            q_s = self._b_W_port.Eval(context)
            Y, m, gamma = self._linear_measurement(z)
            x, P, nis = range_difference_update(x_prior, P_prior, Y, m, gamma, q_s)
            return MeasurementUpdate(x, P, nis, 1)
        sonars = np.flatnonzero(valid)
        if phase == PARTICLE_PHASE:
            x, P, nis, _ = self._posterior.Eval(context)
        else:
            q_s = self._b_W_port.Eval(context)
            x, P, nis = self.range_update(context, x_prior, P_prior, z, q_s, sonars)
        return MeasurementUpdate(x, P, nis, int(sonars.size))

    def advance_extra_state(
        self, context: Context, filtered: FilteredEstimate, discrete_state: DiscreteValues
    ) -> None:
        phase, done = context.get_discrete_state(self._start_index).get_value()
        applied = filtered.status == VALID and math.isfinite(filtered.nis)
        next_phase = phase
        source = None  # draw from this step's filtered estimate
        if phase == LINEAR_PHASE:
            S = context.get_discrete_state(self._prior_share_index).get_value().reshape(6, 6)
            if applied:
                done += 1
                q_s = self._b_W_port.Eval(context)
                z, _ = self._means(context, self._status_port.Eval(context))
                S = prior_share_update(S, filtered.P, q_s, self._linear_measurement(z)[2])
                next_phase = self._after_linear(filtered, int(done), q_s, S)
            discrete_state.set_value(
                self._prior_share_index, prior_share_predict(S, self._A).ravel()
            )
        elif applied and isinstance(self._policy, HandoverRule):
            q_s = self._b_W_port.Eval(context)
            if phase == PARTICLE_PHASE and self.gaussian:
                noise_std = np.sqrt(self._mean_variances)
                if self._policy.gaussian_holds(filtered.x, filtered.P, q_s, noise_std):
                    next_phase = RANGE_PHASE
            elif phase == RANGE_PHASE and self._policy.fallback_due(filtered.x, filtered.P, q_s):
                next_phase = PARTICLE_PHASE
            elif phase == RANGE_PHASE and self._policy.lost(filtered.nis):
                # The ranges contradict the Gaussian's prior: redraw from that prior, widened
                # until this innovation is typical, and weigh the draw by this step's ranges.
                next_phase = PARTICLE_PHASE
                P_prior = context.get_discrete_state(self._P_index).get_value().reshape(6, 6)
                source = (self._prior(context), P_prior * (filtered.nis / 2.0))
        # Groups 2 and 3 keep their values outside the linear phase.
        discrete_state.set_value(self._start_index, np.array([next_phase, done]))
        if next_phase == PARTICLE_PHASE:
            draw = phase != next_phase
            self._advance_particles(context, filtered, discrete_state, draw, source)

    def _after_linear(
        self, filtered: FilteredEstimate, done: int, q_s: np.ndarray, S: np.ndarray
    ) -> float:
        """The phase after an applied linear update."""
        after = RANGE_PHASE if self.gaussian else PARTICLE_PHASE
        if isinstance(self._policy, HandoverPolicy):
            return after if self._policy.handover_due(filtered.P, done) else LINEAR_PHASE
        if self.gaussian and self._policy.handover_due(
            filtered.P,
            done,
            x=filtered.x,
            q_s=q_s,
            prior_covariance=S,
            noise_std=np.sqrt(self._mean_variances),
        ):
            return RANGE_PHASE
        if self._parameters is not None and self._policy.prior_forgotten(filtered.P, done, S):
            return PARTICLE_PHASE
        return LINEAR_PHASE

    def _advance_particles(
        self,
        context: Context,
        filtered: FilteredEstimate,
        discrete_state: DiscreteValues,
        draw: bool,
        source: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> None:
        """The particles' periodic update: drawn from ``N(x̂, P)`` of this step (``draw``) or
        reweighted by this step's ranges, then resampled, regularised and predicted; groups 0
        and 1 become the predicted cloud's mean and covariance. With ``source = (x, P)`` the
        draw is from ``N(x, P)``, a prior of this step, and is weighed by this step's ranges."""
        u = float(self._seed_port.Eval(context)[0])
        rng = np.random.default_rng(int(u * 2.0**_SEED_BITS))
        count = self._parameters.count
        if draw and source is not None:
            particles = initial_particles(source[0], source[1], count, rng)
            z, valid = self._means(context, self._status_port.Eval(context))
            q_s = self._b_W_port.Eval(context)
            uniform = np.full(count, -math.log(count))
            log_weights = pf_update(particles, uniform, z, q_s, self._R, np.flatnonzero(valid))[3]
        elif draw:
            particles = initial_particles(filtered.x, filtered.P, count, rng)
            log_weights = np.full(count, -math.log(count))
        else:
            particles = self.particles(context)
            if filtered.status == VALID:
                log_weights = self._posterior.Eval(context)[3]
            else:  # no update, or one the gate rejected: the prediction's weights stand
                log_weights = context.get_discrete_state(self._log_weights_index).get_value()
        if self._navigation:  # predict the target: −X̄(k+1|k) = A (Υ(k) − X(k)) + noise
            particles = particles - self._vehicle_state(context)[:, np.newaxis]
            acceleration = np.zeros(3)
        else:
            acceleration = self._a_port.Eval(context)
        particles, log_weights, _ = pf_predict(
            particles, log_weights, acceleration, self._A, self._B, self._W, rng, self._parameters
        )
        x, P = weighted_moments(particles, np.exp(log_weights))
        discrete_state.set_value(self._x_index, x)
        discrete_state.set_value(self._P_index, P.ravel())
        discrete_state.set_value(self._particles_index, particles.ravel())
        discrete_state.set_value(self._log_weights_index, log_weights)
