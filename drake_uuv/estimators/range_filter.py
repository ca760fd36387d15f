"""The filters on the two raw ranges, composed: linear start, hand-over, Gaussian update, particles.

The paper's ``Y = ½(d1² − d2²)`` keeps only ``q_sᵀ q``; the two ranges also carry the
distance. A :class:`RangeFilter` uses them directly, with all ``f`` samples: the per-sonar
sample means ``z_i`` are sufficient, with covariance ``R = diag(η1/f, η2/f)``, and
``h(x) = [|q + ½ q_s|, |q − ½ q_s|]``. It is composed of:

- the **linear start** (:class:`~drake_uuv.estimators.linear_start.LinearStart`): the
  paper's KF on the means' ``Y``, which converges from any prior;
- a **hand-over policy** (:class:`~drake_uuv.models.handover.HandoverPolicy`: the rule that
  scales with range and noise, or the absolute threshold), which picks each step's
  :class:`~drake_uuv.models.handover.Phase` after every applied update;
- a **Gaussian update** on the raw ranges (:class:`~drake_uuv.models.filters.RangeUpdate`:
  EKF, iterated EKF or UKF), or none;
- a **particle cloud** (:class:`~drake_uuv.estimators.particle_cloud.ParticleCloud`), for a
  filter without a Gaussian update (the particle filter) and for a Gaussian filter's bridge
  where its Gaussian is too wide.

The variants (``!Ekf``, ``!Iekf``, ``!Ukf``, ``!ParticleFilter``) differ only in the pieces
their config dataclass names (``range_update()``, ``handover_policy()``,
``particle_parameters()``).
"""

import math

import numpy as np
from pydrake.systems.framework import Context, DiscreteValues

from drake_uuv.estimators.base import RelativeStateEstimator
from drake_uuv.estimators.contract import (
    Estimate,
    EstimatorSetting,
    FilteredEstimate,
    MeasurementUpdate,
    Ranges,
)
from drake_uuv.estimators.linear_start import LinearStart
from drake_uuv.estimators.particle_cloud import ParticleCloud
from drake_uuv.estimators.timed_step import StepOutcome, gaussian_step
from drake_uuv.models.handover import HandoverPolicy, Phase, PhaseEvidence, Transition
from drake_uuv.models.measurement import VALID
from drake_uuv.primitives.signal import Signal
from drake_uuv.scenario.estimators import RawRangeOptions


class RangeFilter(RelativeStateEstimator):
    """A filter on both raw ranges that starts as the paper's KF (see the module notes).

    Each step's update is the phase's: :attr:`Phase.LINEAR` the linear start's (both ranges
    needed), :attr:`Phase.RANGE` the Gaussian update on the ranges of the sonars that
    returned (NIS with as many degrees of freedom), :attr:`Phase.PARTICLE` the particles'
    reweighting. After each applied update the policy gives the next phase
    (:meth:`~drake_uuv.models.handover.HandoverPolicy.next_phase`); a new particle phase
    draws its particles from the step's filtered Gaussian, or, for a filter that lost the
    target, from the step's prior widened by NIS/2 and weighed by the step's ranges. A step
    without a return only predicts. Timing, prediction, the NIS gate and the ports are those
    of :class:`~drake_uuv.estimators.base.RelativeStateEstimator`.

    Discrete state: the base's groups 0 and 1 (with particles, the predicted cloud's mean and
    covariance); ``[phase, linear updates applied]``; the linear start's prior share ``S``;
    with particles, the cloud's particles and log weights.

    .. pydrake_system::

        name: RangeFilter
        input_ports:
        - range_samples
        - sonar_status
        - R_WB_nav
        - u1_W
        - particle_seed (with particles)
        output_ports:
        - x_TU_hat
        - P_TU
        - x_TU_prior
        - P_TU_prior
        - measurement_status
        - nis
        - estimator_phase

    - ``estimator_phase`` (2): this step's phase and the linear updates applied before it
      (logged: a run that never leaves its linear start is warned of).
    - ``particle_seed`` (1, random uniform in [0, 1), only with particles): seeds the step's
      draw, resampling, regularisation and process noise.
    - The other ports are the base class's (with ``vehicle_motion: navigation``, ``p_WU_nav``
      and ``v_WU_nav`` in place of ``u1_W``).
    """

    #: Logged beside the slot's signals: the phase of each step.
    extra_signals = (
        Signal(
            "estimator_phase", "estimator", (2,),
            "a raw-range filter's phase (0 Gaussian, 1 linear start, 2 particles) and its "
            "linear updates so far",
        ),
    )  # fmt: skip

    def __init__(self, config: RawRangeOptions, *, setting: EstimatorSetting) -> None:
        super().__init__(config, setting=setting)
        self._mean_variances = setting.noise_variances / setting.samples_per_step
        self._noise_std = np.sqrt(self._mean_variances)
        self._R = np.diag(self._mean_variances)
        self._policy: HandoverPolicy = config.handover_policy()
        self._gaussian_update = config.range_update()
        if self._gaussian_update is None and not self._policy.linear_start:
            raise ValueError(
                "handover: a filter without a Gaussian update draws its particles from the "
                f"linear start, max_linear_steps must not be 0, got {self._policy!r}"
            )
        self._start = LinearStart(
            self, config.noise_model, self._mean_variances, self.initial_estimate.P
        )
        phase = Phase.LINEAR if self._policy.linear_start else Phase.RANGE
        self._phase_index = self.DeclareDiscreteState(np.array([float(phase), 0.0]))
        self.DeclareStateOutputPort("estimator_phase", self._phase_index)
        self._cloud = None
        if self._gaussian_update is None or self._policy.particle_bridge:
            self._cloud = ParticleCloud(self, config.particle_parameters(), self._R)

    @property
    def policy(self) -> HandoverPolicy:
        return self._policy

    @property
    def cloud(self) -> ParticleCloud | None:
        """The particle cloud, or None for a filter that never carries particles."""
        return self._cloud

    @property
    def start(self) -> LinearStart:
        return self._start

    def phase(self, context: Context) -> Phase:
        """This step's phase."""
        return Phase(int(context.get_discrete_state(self._phase_index).get_value()[0]))

    def set_phase(self, context: Context, phase: Phase, linear_updates: int = 0) -> None:
        """Sets this step's phase and the count of linear updates applied before it."""
        context.SetDiscreteState(self._phase_index, np.array([float(phase), linear_updates]))

    def linear_updates(self, context: Context) -> int:
        """Linear updates applied before this step."""
        return int(context.get_discrete_state(self._phase_index).get_value()[1])

    def measurement_update(
        self, context: Context, prior: Estimate, ranges: Ranges
    ) -> MeasurementUpdate | None:
        if not ranges.valid.any():
            return None
        phase = self.phase(context)
        if phase is Phase.LINEAR:
            return self._start.update(prior, ranges)
        sonars = ranges.sonars
        if phase is Phase.PARTICLE:
            x, P, nis, _ = self._cloud.posterior(context)
        else:
            R = ranges.covariance(self._R, prior.x)
            x, P, nis = self._gaussian_update(
                prior.x, prior.P, ranges.z, ranges.q_s, R, sonars=sonars
            )
        return MeasurementUpdate(x, P, nis, int(sonars.size))

    def needs_both_ranges(self, context: Context) -> bool:
        return self.phase(context) is Phase.LINEAR

    def filtered_estimate(self, context: Context) -> FilteredEstimate | None:
        """With late ranges in the particle phase, the cloud's own: stepped through the
        window's ranges at their ping times, then this tick's."""
        if self.window is None or self.phase(context) is not Phase.PARTICLE:
            return None
        x, P, nis, _ = self._cloud.posterior(context)
        status = VALID if math.isfinite(nis) else self.arrival_status(context)
        return FilteredEstimate(x, P, status, nis)

    def step_belief(self, context: Context, x: np.ndarray, P: np.ndarray, step) -> StepOutcome:
        """In the particle phase the particles take the ranges: the Gaussian summary only
        predicts (it serves the prior outputs)."""
        particles = self.phase(context) is Phase.PARTICLE
        return gaussian_step(self, context, x, P, step, with_ranges=not particles)

    def _linear_updates(
        self, context: Context, filtered: FilteredEstimate, ranges: Ranges
    ) -> list[tuple[np.ndarray, float]]:
        """This tick's applied linear updates as ``(q_s, Γ)``."""
        if self.window is not None:
            return [
                (u.q_s, u.gamma) for o in self.window_outcomes(context) for u in o.updates
                if u.new and u.status == VALID and u.gamma is not None
            ]  # fmt: skip
        if filtered.applied and ranges.valid.all():
            return [(ranges.q_s, self._start.measurement(ranges, filtered.x)[2])]
        return []

    def advance(
        self, context: Context, filtered: FilteredEstimate, discrete_state: DiscreteValues
    ) -> None:
        phase = self.phase(context)
        timed = self.window is not None
        done = self.linear_updates(context)
        transition = Transition(phase)
        if phase is Phase.LINEAR:
            ranges = self.ranges(context)
            updates = self._linear_updates(context, filtered, ranges)
            S = self._start.advance(context, filtered, updates, discrete_state)
            if filtered.applied:
                done += 1
                transition = self._policy.next_phase(
                    phase, self._evidence(filtered, done, S, ranges)
                )
        elif filtered.applied and (
            phase is not Phase.PARTICLE or self._gaussian_update is not None
        ):
            # (Particles hand over only to a Gaussian update: without one they stay.)
            S = self._start.prior_share(context)
            evidence = self._evidence(filtered, done, S, self.ranges(context))
            transition = self._policy.next_phase(phase, evidence)
        discrete_state.set_value(self._phase_index, np.array([float(transition.phase), done]))
        if transition.phase is not Phase.PARTICLE:
            if not (timed and phase is Phase.PARTICLE):
                super().advance(context, filtered, discrete_state)
            return
        # The cloud writes the prediction: the Gaussian one is not computed.
        if timed:
            self._advance_window_particles(context, filtered, discrete_state, phase, transition)
            return
        if phase is Phase.PARTICLE:
            self._cloud.advance(context, filtered, discrete_state)
        elif transition.redraw_from_prior:
            # The ranges contradict the Gaussian's prior: redraw from that prior, widened until
            # this innovation is typical, and weigh the draw by this step's ranges.
            prior = self.prior(context)
            draw = (prior.x, prior.P * (filtered.nis / 2.0))
            self._cloud.advance(context, filtered, discrete_state, draw, weigh_draw=True)
        else:
            self._cloud.advance(context, filtered, discrete_state, (filtered.x, filtered.P))

    def _advance_window_particles(
        self,
        context: Context,
        filtered: FilteredEstimate,
        discrete_state: DiscreteValues,
        phase: Phase,
        transition: Transition,
    ) -> None:
        """With late ranges: the cloud moves its anchor on, or is drawn at the new anchor from
        the Gaussian filter's belief there (widened by NIS/2 for a filter that lost the
        target)."""
        if phase is Phase.PARTICLE:
            self._cloud.advance_window(context, discrete_state)
            return
        outcome = self.anchor_advance(context)
        anchor = self.anchor(context) if outcome is None else outcome
        scale = filtered.nis / 2.0 if transition.redraw_from_prior else 1.0
        self._cloud.advance_window(context, discrete_state, (anchor.x, anchor.P * scale))

    def _evidence(
        self, filtered: FilteredEstimate, done: int, S: np.ndarray, ranges: Ranges
    ) -> PhaseEvidence:
        return PhaseEvidence(
            x=filtered.x,
            P=filtered.P,
            nis=filtered.nis,
            linear_updates=done,
            prior_share=S,
            q_s=ranges.q_s,
            noise_std=self._noise_std,
            gaussian=self._gaussian_update is not None,
            particles=self._cloud is not None,
        )
