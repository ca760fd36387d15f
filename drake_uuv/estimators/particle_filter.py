"""Regularised particle filter on both raw ranges, started by the paper's linear KF."""

import math

import numpy as np
from pydrake.common import RandomDistribution
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, DiscreteValues, ValueProducer

from drake_uuv.estimators.base import FilteredEstimate
from drake_uuv.estimators.linear_start import RANGE_PHASE, LinearStartEstimator
from drake_uuv.models.filters import HandoverPolicy
from drake_uuv.models.handover import HandoverRule
from drake_uuv.models.measurement import VALID
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

# The uniform draw of the random port becomes a generator seed with this many bits (a double
# in [0, 1) carries 53).
_SEED_BITS = 53


class ParticleRangeEstimator(LinearStartEstimator):
    """A regularised particle filter on the two raw ranges (all ``f`` samples).

    The model and the steps are :mod:`drake_uuv.models.particle_filter`'s: the filtered
    estimate of step k is the weighted mean and covariance of the predicted particles
    reweighted by the ranges' likelihood (:func:`~drake_uuv.models.particle_filter.pf_update`,
    a direct-feedthrough output, deterministic in the inputs and the state); the periodic
    update resamples when the effective sample size falls below half the count,
    regularises, and moves every particle by the model with its own target acceleration
    (:func:`~drake_uuv.models.particle_filter.pf_predict`). With a large count its estimate
    is the posterior mean: the reference that shows where the Cramér–Rao bound is attainable.

    Randomness enters only through the random input port ``particle_seed`` (one uniform draw
    per step, connect a ``RandomSource`` of kUniform), read only in the periodic update, where
    it seeds the ``numpy.random.Generator`` of that update. A run is therefore reproducible
    from the diagram's seed, and the filtered output does not depend on the draw.

    Initialisation: a linear-KF start (:class:`~drake_uuv.estimators.linear_start.
    LinearStartEstimator`) with :class:`~drake_uuv.models.handover.HandoverRule`
    ``(angle_tolerance=None)`` by default: at the update where the prior's share of the KF's
    covariance has fallen below 10 %, the particles are drawn from the KF's ``N(x̂, P)``. The
    scenario's prior ``N(0, I)`` lies three standard deviations from the truth, and particles
    drawn from it at step 0, or from the KF after its first update, lost the target in 1 of
    40 paper runs (5000 particles, numpy study ``benchmarks/estimator_regimes.py
    --prior-share inf``); drawn after the hand-over, none of 40 runs diverged in any of the
    six regimes studied, at 0.98–1.07× the mean per-run bound. No Gaussian-posterior test
    applies: the particles carry the curved, or split, posterior that stops the EKF and UKF.
    The linear start is therefore required (``max_linear_steps`` must not be 0).

    In the Drake loop (40 runs per regime: σ = 0.1, 0.5, 1 m at the paper's standoff, and
    2.8, 14, 28 m with q* in the world frame) it is at 1.02–1.04× the mean per-run
    Cramér–Rao bound in every regime, mean NEES 6.2–7.0, and no run diverged; the paper's KF
    is at 1.5–3.8× and the EKF, which cannot leave its linear start at σ ≥ 0.5 m, at up to
    3.8×.

    Count: 5000 by default (:class:`~drake_uuv.models.particle_filter.
    ParticleFilterParameters`); see ``benchmarks/bench_particle_filter.py`` for the cost.

    Discrete state: groups 0–3 as in the base classes (groups 0 and 1 hold the predicted
    cloud's mean and covariance once the particles exist); group 4 the predicted particles
    (6N, state-major: the N values of q_x, then of q_y, …); group 5 their log weights (N).

    .. pydrake_system::

        name: ParticleRangeEstimator
        input_ports:
        - range_samples
        - b_W
        - sonar_status
        - u1_W
        - particle_seed
        output_ports:
        - x_TU_hat
        - P_TU
        - x_TU_prior
        - P_TU_prior
        - measurement_status
        - nis

    - ``range_samples`` (2f): sonar 1's f samples then sonar 2's [m]; NaN without a return.
    - ``b_W`` (3): world sonar baseline ``q_s = R_WB b``.
    - ``particle_seed`` (1, random uniform in [0, 1)): seeds the step's resampling,
      regularisation and process noise.
    - Common ports (``sonar_status``, ``u1_W`` or ``p_WU``, ``v_WU``, the outputs): see the
      base class.
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
        parameters: ParticleFilterParameters | None = None,
        vehicle_motion: str = "commanded",
    ) -> None:
        super().__init__(
            time_step,
            acceleration_covariance,
            initial_estimate,
            initial_covariance,
            noise_variances,
            samples_per_step,
            noise_model,
            handover,
            gate_probability,
            vehicle_motion,
        )
        if not self.handover.linear_start:
            raise ValueError(
                "handover: the particle filter draws its particles from the linear start, "
                f"max_linear_steps must not be 0, got {self.handover!r}"
            )
        if parameters is None:
            parameters = ParticleFilterParameters()
        if not isinstance(parameters, ParticleFilterParameters):
            raise ValueError(f"parameters: must be ParticleFilterParameters, got {parameters!r}")
        self._parameters = parameters
        self._W = np.asarray(acceleration_covariance, dtype=float)
        n = parameters.count
        self._particles_index = self.DeclareDiscreteState(np.zeros(STATE_SIZE * n))
        self._log_weights_index = self.DeclareDiscreteState(np.full(n, -math.log(n)))
        self._declare_ports()
        self._seed_port = declare_random_input(
            self, "particle_seed", 1, RandomDistribution.kUniform
        )
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

    def default_handover(self) -> HandoverRule:
        """:class:`HandoverRule` without the angle test: particles need no Gaussian posterior."""
        return HandoverRule(angle_tolerance=None)

    @property
    def parameters(self) -> ParticleFilterParameters:
        return self._parameters

    @property
    def particles_index(self) -> int:
        """The discrete-state group of the predicted particles (6N, state-major)."""
        return self._particles_index

    @property
    def log_weights_index(self) -> int:
        """The discrete-state group of the particles' log weights (N)."""
        return self._log_weights_index

    @classmethod
    def from_scenario(cls, scenario: Scenario) -> "ParticleRangeEstimator":
        """The filter of ``scenario.estimator`` (a :class:`~drake_uuv.scenario.ParticleFilter`)."""
        return cls(**cls.scenario_arguments(scenario), parameters=scenario.estimator.parameters())

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

    def range_update(
        self,
        context: Context,
        x_prior: np.ndarray,
        P_prior: np.ndarray,
        z: np.ndarray,
        q_s: np.ndarray,
        sonars: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, float]:
        x, P, nis, _ = self._posterior.Eval(context)
        return x, P, nis

    def advance_extra_state(
        self, context: Context, filtered: FilteredEstimate, discrete_state: DiscreteValues
    ) -> None:
        was_linear = self.in_linear_phase(context)
        super().advance_extra_state(context, filtered, discrete_state)
        if discrete_state.get_value(self.start_state_index)[0] != RANGE_PHASE:
            return
        u = float(self._seed_port.Eval(context)[0])
        rng = np.random.default_rng(int(u * 2.0**_SEED_BITS))
        count = self._parameters.count
        if was_linear:  # the hand-over: draw the particles from the KF's Gaussian
            particles = initial_particles(filtered.x, filtered.P, count, rng)
            log_weights = np.full(count, -math.log(count))
        else:
            particles = self.particles(context)
        if self._navigation:  # predict the target: −X̄(k+1|k) = A (Υ(k) − X(k)) + noise
            particles = particles - self._vehicle_state(context)[:, np.newaxis]
            acceleration = np.zeros(3)
        else:
            acceleration = self._a_port.Eval(context)
        if not was_linear:
            if filtered.status == VALID:
                log_weights = self._posterior.Eval(context)[3]
            else:  # no update, or one the gate rejected: the prediction's weights stand
                log_weights = context.get_discrete_state(self._log_weights_index).get_value()
        particles, log_weights, _ = pf_predict(
            particles, log_weights, acceleration, self._A, self._B, self._W, rng, self._parameters
        )
        x, P = weighted_moments(particles, np.exp(log_weights))
        discrete_state.set_value(self._x_index, x)
        discrete_state.set_value(self._P_index, P.ravel())
        discrete_state.set_value(self._particles_index, particles.ravel())
        discrete_state.set_value(self._log_weights_index, log_weights)
