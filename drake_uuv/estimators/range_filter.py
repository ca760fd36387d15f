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

import dataclasses

import numpy as np
from pydrake.systems.framework import Context, DiscreteValues, State

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
from drake_uuv.models.divergence import DivergenceTest
from drake_uuv.models.filter_runs import range_difference_update_runs
from drake_uuv.models.handover import HandoverPolicy, Phase, PhaseEvidence
from drake_uuv.models.measurement import VALID
from drake_uuv.models.raw_range_runs import ekf_update_runs, range_update_runs
from drake_uuv.models.statistics import chi2_ppf
from drake_uuv.primitives.batch import per_run, tiled
from drake_uuv.primitives.signal import Signal
from drake_uuv.scenario.estimators import RawRangeOptions

# The phases as plain integers for the masks (an enum member's lookup costs more than its use).
_RANGE, _LINEAR, _PARTICLE = int(Phase.RANGE), int(Phase.LINEAR), int(Phase.PARTICLE)


class RangeFilter(RelativeStateEstimator):
    """A filter on both raw ranges that starts as the paper's KF (see the module notes).

    Each step's update is the phase's: :attr:`Phase.LINEAR` the linear start's (both ranges
    needed), :attr:`Phase.RANGE` the Gaussian update on the ranges of the sonars that
    returned (NIS with as many degrees of freedom), :attr:`Phase.PARTICLE` the particles'
    reweighting. After each applied update the policy gives the next phase
    (:meth:`~drake_uuv.models.handover.HandoverPolicy.next_phases`); a new particle phase
    draws its particles from the step's filtered Gaussian, or, for a filter that lost the
    target, from the step's prior widened by NIS/2 and weighed by the step's ranges. A step
    without a return only predicts. Timing, prediction, the NIS gate and the ports are those
    of :class:`~drake_uuv.estimators.base.RelativeStateEstimator`.

    With ``batch_size`` B each run has its own phase: the phases are per-run masks of one
    computation, never a branch for the batch (with late ranges too: the particle cloud steps
    the runs in its phase, each through its own window).

    Discrete state (per run, B runs row-major): the base's groups 0 and 1 (with particles,
    the predicted cloud's mean and covariance); ``[phase, linear updates applied]``; the
    linear start's prior share ``S``. With particles, the cloud's particles and log weights
    are abstract state (:meth:`ParticleCloud.arrays`), and the outputs are published
    (:mod:`~drake_uuv.estimators.outputs`).

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
        - estimator_recovery (with recovery)

    - ``estimator_phase`` (2): this step's phase and the linear updates applied before it
      (logged: a run that never leaves its linear start is warned of).
    - ``estimator_recovery`` (4, with ``recovery_window``): the run's returns to its linear
      start so far, and the last one's reason: its window's summed NIS, the χ² threshold
      that sum exceeded and the window's summed dimensions (NaN before the first). A run in
      the Gaussian phase whose last ``recovery_window`` NIS (applied or gated updates) sum
      above the threshold (:class:`~drake_uuv.models.divergence.DivergenceTest`) goes back to
      the linear start from its estimate, its covariance widened by the window's mean NIS
      per dimension plus the initial covariance; the linear start's prior share is then all
      of it, so the hand-over rule waits until the data outweigh that prior again.
    - ``particle_seed`` (1, random uniform in [0, 1), only with particles): seeds the step's
      draw, resampling, regularisation and process noise.
    - The other ports are the base class's (with ``vehicle_motion: navigation``, ``p_WU_nav``
      and ``v_WU_nav`` in place of ``u1_W``); sizes per run, B runs row-major.
    """

    #: Logged beside the slot's signals: the phase of each step.
    extra_signals = (
        Signal(
            "estimator_phase", "estimator", (2,),
            "a raw-range filter's phase (0 Gaussian, 1 linear start, 2 particles) and its "
            "linear updates so far",
        ),
    )  # fmt: skip

    #: The particle phase's cloud (a subclass may carry another: the marginalised one).
    cloud_type: type[ParticleCloud] = ParticleCloud

    def __init__(
        self, config: RawRangeOptions, *, setting: EstimatorSetting, batch_size: int = 1
    ) -> None:
        # The particle cloud is abstract state (shared, not copied, while it does not change).
        particles = isinstance(config, RawRangeOptions) and config.carries_particles()
        super().__init__(config, setting=setting, batch_size=batch_size, abstract_state=particles)
        B = self.batch_size
        self._mean_variances = setting.noise_variances / setting.samples_per_step
        self._noise_std = np.sqrt(self._mean_variances)
        self._R = np.diag(self._mean_variances)
        self._policy: HandoverPolicy = config.handover_policy()
        update = config.range_update()
        self._gaussian = update is not None
        self._gaussian_update = None if update is None else range_update_runs(update)
        if not self._gaussian and not self._policy.linear_start:
            raise ValueError(
                "handover: a filter without a Gaussian update draws its particles from the "
                f"linear start, max_linear_steps must not be 0, got {self._policy!r}"
            )
        self._start = LinearStart(
            self, config.noise_model, self._mean_variances, self.initial_estimate.P
        )
        phase = Phase.LINEAR if self._policy.linear_start else Phase.RANGE
        self._phase_index = self.DeclareDiscreteState(tiled([float(phase), 0.0], B))
        self.declare_state_output("estimator_phase", self._phase_index, 2)
        self._cloud = None
        if particles:
            self._cloud = self.cloud_type(self, config.particle_parameters(), self._R, batch_size=B)
        self._dof_linear = np.ones(B, dtype=np.intp)
        gate = config.handover_range_gate
        # The gate's χ² quantile by the number of valid ranges (none: no gate).
        self._range_gate = (
            None
            if gate is None
            else np.array([np.inf, chi2_ppf(1.0 - gate, 1), chi2_ppf(1.0 - gate, 2)])
        )
        self._divergence = config.divergence_test()
        if self._divergence is not None:
            self._window_index = self.DeclareDiscreteState(self._divergence.empty(B).ravel())
            self._recovery_index = self.DeclareDiscreteState(
                tiled([0.0, np.nan, np.nan, np.nan], B)
            )
            self.declare_state_output("estimator_recovery", self._recovery_index, 4)
            self.extra_signals = (*type(self).extra_signals, _RECOVERY_SIGNAL)
            self._restart_P = self.initial_estimate.P

    @property
    def policy(self) -> HandoverPolicy:
        return self._policy

    @property
    def divergence(self) -> DivergenceTest | None:
        """The windowed NIS test that sends a diverged run back to its linear start (None:
        no recovery)."""
        return self._divergence

    @property
    def cloud(self) -> ParticleCloud | None:
        """The particle cloud, or None for a filter that never carries particles."""
        return self._cloud

    @property
    def start(self) -> LinearStart:
        return self._start

    def _phase_state(self, context: Context) -> np.ndarray:
        value = context.get_discrete_state(self._phase_index).get_value()
        return per_run(value, self.batch_size)

    def phases(self, context: Context) -> np.ndarray:
        """This step's phase of each run (B, the :class:`Phase` values as integers)."""
        return self._phase_state(context)[:, 0].astype(np.intp)

    def phase(self, context: Context, run: int = 0) -> Phase:
        """This step's phase of run ``run``."""
        return Phase(int(self._phase_state(context)[run, 0]))

    def set_phase(
        self, context: Context, phase: Phase | np.ndarray, linear_updates: int | np.ndarray = 0
    ) -> None:
        """Sets this step's phase and the count of linear updates applied before it (each a
        value for every run, or one per run)."""
        B = self.batch_size
        value = np.empty((B, 2))
        value[:, 0] = np.asarray(phase, dtype=float)
        value[:, 1] = linear_updates
        context.SetDiscreteState(self._phase_index, value.ravel())

    def linear_updates(self, context: Context, run: int = 0) -> int:
        """Linear updates applied before this step (run ``run``)."""
        return int(self._phase_state(context)[run, 1])

    def measurement_update(
        self, context: Context, prior: Estimate, ranges: Ranges
    ) -> MeasurementUpdate | None:
        phases = self.phases(context)
        valid = ranges.valid
        returned = valid[:, 0] | valid[:, 1]
        linear = (phases == _LINEAR) & valid[:, 0] & valid[:, 1]
        gaussian = (phases == _RANGE) & returned
        particle = (phases == _PARTICLE) & returned
        x, P = prior.x, prior.P
        nis = gamma = None
        # Each update copies the runs outside its mask, so they chain: a run's posterior is
        # its own phase's. (A mask that holds no run skips its call: the same numbers.)
        if linear.any():
            Y, m, gamma = self._start.measurement(ranges, x)
            x, P, nis = range_difference_update_runs(x, P, Y, m, gamma, ranges.q_s, linear)
        if gaussian.any():
            R = ranges.covariance(self._R, prior.x)
            x, P, nis_g = self._gaussian_update(x, P, ranges.z, ranges.q_s, R, valid, gaussian)
            nis = nis_g if nis is None else np.where(gaussian, nis_g, nis)
        if particle.any():
            x_p, P_p, nis_p, _ = self._cloud.posterior(context)
            B = self.batch_size
            x = np.where(particle[:, np.newaxis], np.reshape(x_p, (B, 6)), x)
            P = np.where(particle[:, np.newaxis, np.newaxis], np.reshape(P_p, (B, 6, 6)), P)
            nis_p = np.reshape(nis_p, (B,))
            nis = np.where(particle, nis_p, np.nan if nis is None else nis)
        if nis is None:
            return None
        dof = np.where(phases == _LINEAR, self._dof_linear, valid.sum(axis=1))
        return MeasurementUpdate(x, P, nis, dof, linear | gaussian | particle, gamma)

    def needs_both_ranges(self, context: Context) -> np.ndarray:
        return self.phases(context) == _LINEAR

    def filtered_estimate(self, context: Context) -> FilteredEstimate | None:
        """With late ranges, each run in the particle phase takes the cloud's own: stepped
        through the window's ranges at their ping times, then this tick's; the other runs
        the base's (None when no run is in the particle phase)."""
        if self.window is None:
            return None
        particle = self.phases(context) == _PARTICLE
        if not particle.any():
            return None
        x, P, nis, _ = self._cloud.posterior(context)
        status = np.where(np.isfinite(nis), float(VALID), self.arrival_status(context))
        # The particle runs' innovations are those of the ranges that arrived at this tick (the
        # particle filter's divergence test reads them; a Gaussian filter's bridge does not).
        innovation_nis, innovation_dof = self._cloud.innovations(context)
        if particle.all():
            return FilteredEstimate(
                x, P, status, nis, innovation_nis=innovation_nis, innovation_dof=innovation_dof
            )
        base = self._filtered_by_update(context)
        return FilteredEstimate(
            np.where(particle[:, np.newaxis], x, base.x),
            np.where(particle[:, np.newaxis, np.newaxis], P, base.P),
            np.where(particle, status, base.status),
            np.where(particle, nis, base.nis),
            innovation_nis=np.where(particle, innovation_nis, base.innovation_nis),
            innovation_dof=np.where(particle, innovation_dof, base.innovation_dof),
        )

    def step_belief(self, context: Context, x: np.ndarray, P: np.ndarray, step) -> StepOutcome:
        """In the particle phase the particles take the ranges: the Gaussian summary only
        predicts (it serves the prior outputs)."""
        return gaussian_step(self, context, x, P, step, self.phases(context) != _PARTICLE)

    def _linear_updates(
        self, context: Context, filtered: FilteredEstimate, ranges: Ranges, linear: np.ndarray
    ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """This tick's applied linear updates as ``(q_s (B, 3), Γ (B), runs (B))``."""
        if self.window is not None:
            return [
                (u.q_s, u.gamma, u.new & (u.status == VALID) & linear)
                for o in self.window_outcomes(context) for u in o.updates if u.gamma is not None
            ]  # fmt: skip
        runs = linear & filtered.applied & ranges.valid[:, 0] & ranges.valid[:, 1]
        if not runs.any():
            return []
        return [(ranges.q_s, self._start.measurement(ranges, filtered.x)[2], runs)]

    def advance_state(self, context: Context, filtered: FilteredEstimate, state: State) -> None:
        self.advance(context, filtered, state.get_mutable_discrete_state(), state)

    def advance(
        self,
        context: Context,
        filtered: FilteredEstimate,
        discrete_state: DiscreteValues,
        state: State | None = None,
    ) -> None:
        """The periodic update (``state``: the whole next state, the cloud's with it; None
        for a filter without particles)."""
        if state is None and self._cloud is not None:
            raise ValueError("state: a filter with particles advances its whole State")
        phases = self.phases(context)
        done = self._phase_state(context)[:, 1]
        applied = filtered.applied
        linear = phases == _LINEAR
        ranges = self.ranges(context)
        updates = self._linear_updates(context, filtered, ranges, linear)
        S = self._start.advance(context, filtered.P, updates, linear, discrete_state)
        done = done + (linear & applied)
        # After an applied update the policy decides (particles hand over only to a Gaussian
        # update: without one they stay).
        asked = applied & ((phases != _PARTICLE) | self._gaussian)
        evidence = PhaseEvidence(
            x=filtered.x, P=filtered.P, nis=filtered.nis, linear_updates=done, prior_share=S,
            q_s=ranges.q_s, noise_std=self._noise_std, gaussian=self._gaussian,
            particles=self._cloud is not None,
        )  # fmt: skip
        following, redraw = self._policy.next_phases(phases, evidence)
        following = np.where(asked, following, phases)
        if self._range_gate is not None:
            leaving = (phases == _LINEAR) & (following != _LINEAR)
            if leaving.any():
                wait = self._ranges_contradict(filtered, ranges, leaving)
                following = np.where(wait, _LINEAR, following)
        redraw &= asked
        restart = np.zeros(self.batch_size, dtype=bool)
        if self._divergence is not None:
            restart, scale = self._diverged(context, phases, filtered, discrete_state)
            following = np.where(restart, _LINEAR, following)
            redraw &= ~restart
            done = np.where(restart, 0.0, done)
            if restart.any():
                filtered = self._restarted(filtered, restart, scale)
                self._start.restart(discrete_state, filtered.P, restart)
        phase_state = np.empty((self.batch_size, 2))
        phase_state[:, 0] = following
        phase_state[:, 1] = done
        discrete_state.set_value(self._phase_index, phase_state.ravel())
        to_particles = following == _PARTICLE
        if self.window is None:
            # The Gaussian prediction of every run (the cloud writes its runs' over it).
            if not to_particles.all():
                super().advance(context, filtered, discrete_state)
        else:
            # The anchor moved on by the Gaussian steps, of the runs that were not on
            # particles and do not go to them: a run leaving its particles keeps the anchor
            # the cloud wrote.
            gaussian = ~to_particles & (phases != _PARTICLE)
            # A restarting run's anchor moves on too (a run leaving its particles: the cloud's
            # moments, predicted), whichever runs share its batch.
            moved = gaussian.any() or restart.any()
            outcome = self.anchor_advance(context) if moved else None
            if outcome is not None:
                self.write_prediction(discrete_state, outcome.x, outcome.P, runs=gaussian)
            if restart.any():
                # A restart widens the anchor: the linear start steps again through the
                # window's ranges from there.
                anchor = self.anchor(context) if outcome is None else outcome
                widened = self._widened(anchor.P, scale)
                self.write_prediction(discrete_state, anchor.x, widened, runs=restart)
        if to_particles.any():
            self._advance_particles(context, filtered, state, phases, redraw, to_particles)
        elif (
            self.window is not None and self._cloud is not None and self._cloud.live(context).any()
        ):
            # No run keeps particles: none of the clouds is live from now on.
            self._cloud.advance_window(context, state, to_particles, to_particles, None, None)

    def _ranges_contradict(
        self, filtered: FilteredEstimate, ranges: Ranges, runs: np.ndarray
    ) -> np.ndarray:
        """Whether each of ``runs``' arrived raw ranges of this tick lie beyond the hand-over
        gate under its filtered Gaussian (B): the NIS an EKF update there would have
        (``ν = z − d(x̂)``, ``S = H P Hᵀ + R`` over the valid ranges) against the χ² quantile
        of their count. A Gaussian the ranges contradict is a poor start for the ranges' own
        update: a cloud drawn from it and weighed by them keeps a handful of particles."""
        _, _, nis = ekf_update_runs(
            filtered.x, filtered.P, ranges.z, ranges.q_s, self._R, ranges.valid, runs
        )
        return runs & (nis > self._range_gate[ranges.valid.sum(axis=1)])

    def _diverged(
        self,
        context: Context,
        phases: np.ndarray,
        filtered: FilteredEstimate,
        discrete_state: DiscreteValues,
    ) -> tuple[np.ndarray, np.ndarray]:
        """The runs whose update has diverged by this tick (B) and each one's window mean NIS
        per dimension (B). Each run in its filter's own phase (a Gaussian filter's Gaussian
        phase, the particle filter's particle phase) with an update at this tick adds the
        tick's summed NIS and dimensions to its window (every update,
        applied or gated: a diverged filter gates its ranges; with late ranges, every range
        that arrived at the tick, each counted once); a run in its linear start, or
        restarting, empties it, and the particle bridge pauses it. Writes the windows and, for a
        restart, the record ``[restarts so far, the window's summed NIS, the threshold it
        exceeded, its summed dimensions]``."""
        B, test = self.batch_size, self._divergence
        n = test.window
        windows = per_run(context.get_discrete_state(self._window_index).get_value(), B)
        # The filter's own update: a Gaussian filter's (its bridge's particles are not
        # tested), the particle filter's particle phase.
        tested = phases == (_RANGE if self._gaussian else _PARTICLE)
        nis, dof = filtered.innovation_nis, filtered.innovation_dof
        new = tested & (dof > 0) & np.isfinite(nis)
        windows = test.pushed(windows, nis, dof, new)
        diverged, total, threshold = test.diverged(windows)
        restart = new & diverged
        summed_dof = windows[:, n:].sum(axis=1)
        if restart.any():
            record = per_run(context.get_discrete_state(self._recovery_index).get_value(), B)
            fresh = np.stack([record[:, 0] + 1.0, total, threshold, summed_dof], axis=1)
            record = np.where(restart[:, np.newaxis], fresh, record)
            discrete_state.set_value(self._recovery_index, record.ravel())
        # The linear start (and a restart) empties the window; the bridge's particles pause
        # it (their ticks add nothing): a run that swings between the two keeps its evidence.
        kept = (phases != _LINEAR) & ~restart
        windows = np.where(kept[:, np.newaxis], windows, np.nan)
        discrete_state.set_value(self._window_index, windows.ravel())
        with np.errstate(invalid="ignore", divide="ignore"):
            scale = np.where(restart, total / summed_dof, 1.0)
        return restart, scale

    def _restarted(
        self, filtered: FilteredEstimate, restart: np.ndarray, scale: np.ndarray
    ) -> FilteredEstimate:
        """``filtered`` with each restarting run's covariance widened by its window's mean NIS
        per dimension ``scale`` (so its innovations become typical) plus the initial
        covariance (so the linear start does not begin overconfident)."""
        widened = self._widened(filtered.P, scale)
        return dataclasses.replace(
            filtered, P=np.where(restart[:, np.newaxis, np.newaxis], widened, filtered.P)
        )

    def _widened(self, P: np.ndarray, scale: np.ndarray) -> np.ndarray:
        """``P`` (B, 6, 6) scaled by each run's ``scale`` (B), plus the initial covariance."""
        return P * scale[:, np.newaxis, np.newaxis] + self._restart_P

    def _advance_particles(
        self,
        context: Context,
        filtered: FilteredEstimate,
        state: State,
        phases: np.ndarray,
        redraw: np.ndarray,
        runs: np.ndarray,
    ) -> None:
        """The cloud's periodic update of the runs that carry particles after this step
        (``runs``), writing their predictions: a run already on particles moves them on; a
        run entering the particle phase draws them from ``N(draw_x, draw_P)``: its filtered
        Gaussian (with late ranges, its belief at the new anchor), or, for a filter that lost
        the target (``redraw``), its prior widened by NIS/2, the draw weighed by the step's
        ranges (with late ranges, by the window's)."""
        drawn = phases != _PARTICLE
        scale = np.where(redraw, filtered.nis / 2.0, 1.0)[:, np.newaxis, np.newaxis]
        if self.window is not None:
            # Drawn at the new anchor from the Gaussian filter's belief there.
            outcome = self.anchor_advance(context)
            anchor = self.anchor(context) if outcome is None else outcome
            draw_x, draw_P = anchor.x, anchor.P * scale
        else:
            # A run that lost the target redraws from its prior, widened until this
            # innovation is typical; the others from their filtered Gaussian.
            prior = self.prior(context)
            lost = redraw[:, np.newaxis]
            draw_x = np.where(lost, prior.x, filtered.x)
            draw_P = np.where(lost[:, :, np.newaxis], prior.P, filtered.P) * scale
        if self.window is not None:  # each run through its window: a draw weighed as it steps
            self._cloud.advance_window(context, state, runs, drawn, draw_x, draw_P)
            return
        self._cloud.advance(
            context, filtered, state, (draw_x, draw_P), redraw, drawn=drawn, runs=runs
        )


_RECOVERY_SIGNAL = Signal(
    "estimator_recovery", "estimator", (4,),
    "a Gaussian range filter's returns to its linear start so far, and the last one's "
    "reason: its window's summed NIS, the χ² threshold it exceeded, the summed dimensions",
)  # fmt: skip
