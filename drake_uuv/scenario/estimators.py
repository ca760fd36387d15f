"""The estimator slot's variants: one dataclass each, chosen in YAML by its tag.

``estimator: !Ekf {gate_probability: 0.99}`` selects the EKF; every variant shares the fields
of :class:`EstimatorOptions`. The factory that builds the system of each variant is
:func:`drake_uuv.estimators.make_estimator`.
"""

import functools
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from drake_uuv.models.divergence import DivergenceTest
from drake_uuv.models.filters import SECOND_ORDER_TERMS, RangeUpdate, ekf_update, iekf_update
from drake_uuv.models.handover import (
    HandoverPolicy,
    HandoverRule,
    ThresholdHandover,
)
from drake_uuv.models.information import EstimatorPlanningModel, PlannedMeasurement
from drake_uuv.models.particle_filter import KERNELS, ParticleFilterParameters
from drake_uuv.models.unscented import ukf_range_update
from drake_uuv.scenario.validation import (
    check_between,
    check_choice,
    check_positive,
    check_probability,
    check_spd,
    check_vector,
    fail,
)

NOISE_MODELS = ("derived", "paper_printed")
HANDOVERS = ("rule", "threshold")
VEHICLE_MOTIONS = ("commanded", "navigation")
ERROR_MODELS = ("modelled", "ideal")


def _identity(n: int) -> list[list[float]]:
    return np.eye(n).tolist()


@dataclass
class EstimatorOptions:
    """Fields every estimator has."""

    # Mean m and variance Γ of the noise of Y = ½(d1² − d2²). "derived": the exact moments of
    # the paper's Y, v̄ = d̄1 v1 − d̄2 v2 + ½(v1² − v2²) (mean ½(η1 − η2), variance
    # η1 d̄1² + η2 d̄2² + ½(η1² + η2²)); "paper_printed": the paper's printed formula, which is
    # not consistent with its own Y (kept to measure the difference). The sonar publishes m
    # and Γ with it; the paper's KF and any linear start use them.
    noise_model: str = "derived"
    # x̂(0|−1) = [q̂, ϑ̂] and P(0|−1). The paper sets every unstated initial value to zero.
    initial_estimate: list[float] = field(default_factory=lambda: [0.0] * 6)
    initial_covariance: list[list[float]] = field(default_factory=lambda: _identity(6))
    # Reject a measurement whose NIS exceeds the χ² quantile of this probability; None: no gate.
    gate_probability: float | None = None
    # [m²/s⁴] per axis, added to the target's W in the filter's process noise B W Bᵀ: what the
    # vehicle does not follow of its commanded acceleration R u1, which the filter takes as
    # known (0 for the paper's kinematic vehicle, which follows it exactly; a real vehicle's
    # is measured by the run metric model_acceleration_rmse: variance ≈ rmse²/3 per axis).
    added_acceleration_variance: float = 0.0
    # How the filter accounts for the vehicle's own motion: "commanded" (the paper's: it
    # predicts with the commanded acceleration R u1, exact for the kinematic vehicle) or
    # "navigation" (it predicts the target and takes the vehicle's state, known as the paper
    # assumes, from its navigation: exact for a vehicle that does not move as commanded).
    vehicle_motion: str = "commanded"
    # What the filter believes of the navigation and the sonars' timing: "modelled" (their
    # errors as the scenario states them: attitude noise into the measurement noise, DVL noise
    # into the process noise, each range at its own ping time, the biases' error floors in
    # the covariance) or "ideal" (perfect navigation, both ranges at the tick they arrive:
    # what ignoring them costs). The same with perfect navigation and the paper's timing.
    error_model: str = "modelled"

    def validate(self, name: str) -> None:
        check_choice(f"{name}.noise_model", self.noise_model, NOISE_MODELS)
        check_vector(f"{name}.initial_estimate", self.initial_estimate, 6)
        check_spd(f"{name}.initial_covariance", self.initial_covariance, 6)
        check_probability(f"{name}.gate_probability", self.gate_probability)
        check_positive(
            f"{name}.added_acceleration_variance", self.added_acceleration_variance, strict=False
        )
        check_choice(f"{name}.vehicle_motion", self.vehicle_motion, VEHICLE_MOTIONS)
        check_choice(f"{name}.error_model", self.error_model, ERROR_MODELS)

    def planning_model(self) -> EstimatorPlanningModel:
        """What an attitude planner assumes of this estimator: the paper's ``Y``."""
        return EstimatorPlanningModel(PlannedMeasurement.RANGE_DIFFERENCE)

    def filter_acceleration_covariance(self, W: list[list[float]]) -> np.ndarray:
        """The acceleration covariance of the filter's process noise: ``W + σ² I``."""
        return np.asarray(W, dtype=float) + self.added_acceleration_variance * np.eye(3)


@dataclass
class PaperKf(EstimatorOptions):
    """The paper's linear Kalman filter on ``Y = ½(d1² − d2²)`` (its equation 9)."""


@dataclass
class RawRangeOptions(EstimatorOptions):
    """Fields of the filters on the two raw ranges, which start as the paper's linear KF.

    The linear start hands over to the raw ranges once (``handover``):

    - ``rule`` (the default): the prior's share of the KF's position covariance is at most
      ``handover_prior_share`` (the estimate rests on the measurements, not on the prior) and
      every cross-range angle √tr(P⊥)/d is at most ``handover_angle`` [rad] (a linearisation
      at the estimate holds); it scales with the noise and the range, so it holds in every
      regime (see ``drake_uuv/models/handover.py`` for the rule and its measurements);
    - ``threshold``: the first raw-range EKF's ``trace(P_qq) ≤
      linear_start_position_variance`` [m²], which a far or noisy target never reaches.

    ``linear_start_max_steps`` forces the hand-over after that many linear updates (None:
    never; 0: no linear start). The ``particle_*`` fields shape the particle cloud of the
    particle filter, and of a Gaussian filter's particle bridge.
    """

    handover: str = "rule"
    handover_prior_share: float = 0.1
    handover_angle: float | None = 0.25
    linear_start_position_variance: float = 0.5
    linear_start_max_steps: int | None = None
    particle_count: int = 5000
    # Resample when the effective sample size falls below this fraction of the count.
    particle_resample_threshold: float = 0.5
    # The regularisation kernel's bandwidth, times the Gaussian kernel's optimal one (0: none).
    particle_bandwidth_scale: float = 1.0
    # The coordinates the kernel moves particles in: cartesian, or range_bearing (about the
    # cloud's mean direction: a particle moves along the shell the ranges pin it to, and in
    # range only by the cloud's spread in range; see drake_uuv/models/range_bearing.py).
    # far_standoff (14 m), seeds 0-999: the Cartesian kernel leaves the cloud too narrow
    # across the line of sight (mean NEES 6.79 at 5000 particles, 6.48 at 10 000);
    # range_bearing gives 6.34 at 5000 and 6.18 at 10 000, in the band [5.79, 6.22]. 1000
    # seeds at 5000 particles (docs/results/robustness.md, rows pf and pf2): paper 6.19 ->
    # 6.18, the LQR world-frame law 6.38 -> 6.20 (into the band), noisy_sonar 6.14 -> 6.07.
    particle_kernel: str = "cartesian"
    # A due hand-over waits while the tick's raw ranges contradict the Gaussian it would start
    # from: their NIS under it beyond the χ² quantile of 1 − this (None: no such gate).
    # far_standoff, seed 137: NIS 22 at the hand-over, then one particle kept its weight.
    handover_range_gate: float | None = 1e-3
    # Recovery: when the summed NIS of the last recovery_window ticks with ranges of the
    # filter's own update (a Gaussian filter's raw-range update, with late ranges every range
    # that arrived at each tick; the particle filter's particle phase) exceeds the χ² quantile
    # of 1 − recovery_probability for their summed dimensions, the run returns to the linear
    # start (which converges from any prior), from its estimate with the covariance widened
    # by the window's mean NIS per dimension plus the initial covariance. None: no recovery.
    # 10 ticks at 1e-9 (a sum above 83.5 for 20 dimensions), over 1000 seeds: in the paper's
    # regime no EKF or UKF run restarts (1e-4 restarted 2.6 % of the EKF's); with noisy
    # sonars (σ = 1 m) the EKF restarts 2 runs and the UKF 1, each about 10 m off, and none
    # is lost (at 1e-6 the EKF restarted 3, one of them late and mildly off, at 5.8 m, and
    # its linear start at σ = 1 m ended it 12 m off). Every run the realistic scenario's EKF
    # and UKF lost without it (17 of 1000 on the kinematic plant) restarts and is kept. The
    # particle filter, 1000 seeds each: no restart in the paper's regime or at σ = 1 m; the
    # runs it lost to a wrong solution of the two ranges (σ = 0.5 m seed 382, 28 m seed 947)
    # restart once and end within 1 m. With late ranges (each range that arrived at a tick,
    # weighed once along the window), under the LQR world-frame law at σ = 0.5 m with pings
    # and ranges late, it loses 1 run of 1000 where it lost 3 (none with the tracking hold).
    recovery_window: int | None = 10
    recovery_probability: float = 1e-9

    def validate(self, name: str) -> None:
        super().validate(name)
        check_choice(f"{name}.handover", self.handover, HANDOVERS)
        if self.handover_range_gate is not None:
            check_probability(f"{name}.handover_range_gate", self.handover_range_gate)
        check_positive(f"{name}.handover_prior_share", self.handover_prior_share)
        if self.handover_angle is not None:
            check_positive(f"{name}.handover_angle", self.handover_angle)
        check_positive(
            f"{name}.linear_start_position_variance", self.linear_start_position_variance
        )
        if self.linear_start_max_steps is not None and self.linear_start_max_steps < 0:
            fail(f"{name}.linear_start_max_steps", "must be ≥ 0", self.linear_start_max_steps)
        if isinstance(self.particle_count, bool) or not isinstance(self.particle_count, int):
            fail(f"{name}.particle_count", "must be an integer", self.particle_count)
        if not 10 <= self.particle_count <= 10_000_000:
            fail(f"{name}.particle_count", "must be in [10, 1e7]", self.particle_count)
        if not 0.0 <= self.particle_resample_threshold <= 1.0:
            fail(f"{name}.particle_resample_threshold", "must be in [0, 1]",
                 self.particle_resample_threshold)  # fmt: skip
        check_positive(
            f"{name}.particle_bandwidth_scale", self.particle_bandwidth_scale, strict=False
        )
        check_choice(f"{name}.particle_kernel", self.particle_kernel, KERNELS)
        if self.recovery_window is not None and (
            isinstance(self.recovery_window, bool)
            or not isinstance(self.recovery_window, int)
            or not 1 <= self.recovery_window <= 1000
        ):
            fail(f"{name}.recovery_window", "must be an integer in [1, 1000] or null",
                 self.recovery_window)  # fmt: skip
        if not (isinstance(self.recovery_probability, float | int)
                and 0.0 < self.recovery_probability < 0.5):  # fmt: skip
            fail(f"{name}.recovery_probability", "must be in (0, 0.5)", self.recovery_probability)

    def handover_policy(self) -> HandoverPolicy:
        """The hand-over these fields describe."""
        if self.handover == "threshold":
            return ThresholdHandover(
                position_variance_threshold=self.linear_start_position_variance,
                max_linear_steps=self.linear_start_max_steps,
            )
        return HandoverRule(**self.rule_fields())

    def rule_fields(self) -> dict[str, Any]:
        """The :class:`~drake_uuv.models.handover.HandoverRule` fields of ``handover: rule``
        (a subclass with more of the rule's fields adds them)."""
        return dict(
            angle_tolerance=self.handover_angle,
            prior_share=self.handover_prior_share,
            max_linear_steps=self.linear_start_max_steps,
        )

    def range_update(self) -> RangeUpdate | None:
        """The Gaussian update on the raw ranges (None: the filter carries particles only)."""
        return None

    def carries_particles(self) -> bool:
        """Whether the filter carries a particle cloud: it has no Gaussian update, or its
        Gaussian update has the particle bridge."""
        return self.range_update() is None or self.handover_policy().particle_bridge

    def divergence_test(self) -> DivergenceTest | None:
        """The windowed NIS test that sends a run back to its linear start (None: off)."""
        if self.recovery_window is None:
            return None
        return DivergenceTest(self.recovery_window, float(self.recovery_probability))

    def planning_model(self) -> EstimatorPlanningModel:
        """The raw ranges, after a linear start the planner mirrors by its threshold (none when
        ``linear_start_max_steps`` is 0)."""
        start = None if self.linear_start_max_steps == 0 else self.linear_start_position_variance
        return EstimatorPlanningModel(PlannedMeasurement.RANGES, start)

    def particle_parameters(self) -> ParticleFilterParameters:
        """The particle cloud's parameters these fields describe."""
        return ParticleFilterParameters(
            count=self.particle_count,
            resample_threshold=self.particle_resample_threshold,
            bandwidth_scale=self.particle_bandwidth_scale,
            kernel=self.particle_kernel,
        )


@dataclass
class GaussianRangeOptions(RawRangeOptions):
    """Fields of the Gaussian filters on the raw ranges (EKF, IEKF, UKF).

    With ``particle_bridge`` (and ``handover: rule``), where the rule's prior is forgotten but
    its Gaussian test fails (noise large against the range: σ = 0.5 or 1 m at 2.8 m), the
    filter carries its posterior on ``particle_count`` particles until the Gaussian test holds
    on their mean and covariance, and goes back to particles when a cross-range angle exceeds
    ``particle_fallback_factor × handover_angle``. Without it the filter stays the paper's KF
    until the Gaussian test holds, which at σ = 1 m is never.
    """

    particle_bridge: bool = True
    particle_fallback_factor: float = 1.2

    def validate(self, name: str) -> None:
        super().validate(name)
        if not isinstance(self.particle_bridge, bool):
            fail(f"{name}.particle_bridge", "must be true or false", self.particle_bridge)
        if not self.particle_fallback_factor >= 1.0:
            fail(f"{name}.particle_fallback_factor", "must be ≥ 1", self.particle_fallback_factor)
        if self.particle_bridge and self.handover == "rule" and self.handover_angle is None:
            fail(f"{name}.handover_angle",
                 "must be set with particle_bridge (the bridge leaves the particles on it)",
                 None)  # fmt: skip

    def rule_fields(self) -> dict[str, Any]:
        return dict(
            super().rule_fields(),
            particle_bridge=self.particle_bridge,
            fallback_factor=self.particle_fallback_factor,
        )


@dataclass
class LinearizedRangeOptions(GaussianRangeOptions):
    """Fields of the filters that linearise the ranges (EKF, IEKF)."""

    # Such a filter drops the ranges' second-order term: the rule also requires
    # tr(P⊥)/(2d) ≤ handover_second_order · σ/√f (None: no such test).
    handover_second_order: float | None = 1.0

    def validate(self, name: str) -> None:
        super().validate(name)
        if self.handover_second_order is not None:
            check_positive(f"{name}.handover_second_order", self.handover_second_order)

    def rule_fields(self) -> dict[str, Any]:
        return dict(super().rule_fields(), second_order_tolerance=self.handover_second_order)


@dataclass
class Ekf(LinearizedRangeOptions):
    """Extended Kalman filter on both raw ranges, all f samples.

    ``second_order`` keeps terms of the ranges' second-order expansion that the EKF drops
    (Gelb's truncated second-order filter): ``mean`` predicts each range as
    ``d + tr(P⊥)/(2d)``, the mean range of the Gaussian ``N(x̂, P)``, so the estimate moves to
    the posterior's mean inside the curved range shell instead of onto it; ``variance`` adds
    that term's variance ``½ tr(H''P H''P)`` to the ranges' noise; ``full`` both; ``none`` the
    first-order EKF. The first-order EKF's innovations are unbiased, its estimate is not (it
    sits on the range shell, the truth's mean inside it by ``tr(P⊥)/(2d)``).

    ``linearisation_correlation`` multiplies the variance term: the quadratic term is a function
    of the estimate's error, which persists from update to update, so over the updates a
    filter averages it does not average out as an independent noise would. 7 steps is the
    error's integrated autocorrelation time (null direction 8.1 steps, line of sight 6.4; 50
    runs under the LQR world-frame law). Mean NEES over 200 runs (seeds 0–199, band
    [5.53, 6.49]) of the first-order EKF → ``full`` → ``full`` with 7 steps:

    - paper scenario: 6.32 → 5.86 (with 7), position RMSE 0.237 → 0.238 m;
    - under the LQR world-frame law (≤ 3 m/s²): 9.47 → 7.43 → 5.99, RMSE 0.433 → 0.422 m;
    - ``far_standoff``: 10.86 → 5.81 (with 7), RMSE 1.19 → 1.25 m (5 % above: the price of an
      honest covariance where the ranges bend most);
    - ``noisy_sonar``: 6.57 → 6.20 (with 7), RMSE 1.025 → 1.006 m.

    Over 1000 seeds (band [5.79, 6.22]), first-order → ``full`` with 7: LQR world-frame law
    9.32 → 5.96, paper 6.29 → 5.84, ``far_standoff`` 11.0 → 5.83, ``noisy_sonar`` 6.46 → 6.14,
    no run lost (the robustness study's ``ekf2`` rows).

    With late ranges it is not yet a default: in ``realistic`` on the kinematic plant (seeds
    0-199, the EKF with its 20 000-particle bridge, recovery and hold on) ``full`` with 7 steps
    gives NEES 7.76 but position RMSE 0.638 m (1.57× the per-run bound) against the
    first-order EKF's 10.3 and 0.474 m (1.17×), and ``full`` with 1 step 8.28 and 0.465 m
    (1.15×); without the sonars' timing the same loop was at 7.3 and 1.08× its bound with 7.
    The defaults are the textbook EKF's.
    """

    second_order: str = "none"
    # The second-order term's variance counts this many updates' worth at each (see above;
    # 1: Gelb's, independent from update to update; unused without the variance term).
    linearisation_correlation: float = 1.0

    def validate(self, name: str) -> None:
        super().validate(name)
        check_choice(f"{name}.second_order", self.second_order, SECOND_ORDER_TERMS)
        check_between(
            f"{name}.linearisation_correlation", self.linearisation_correlation, 1.0, 1000.0
        )

    def range_update(self) -> RangeUpdate:
        if self.second_order == "none":
            return ekf_update
        return functools.partial(
            ekf_update,
            second_order=self.second_order,
            correlation_steps=self.linearisation_correlation,
        )


@dataclass
class Iekf(LinearizedRangeOptions):
    """Iterated EKF (Gauss–Newton with a backtracking step) on both raw ranges."""

    def range_update(self) -> RangeUpdate:
        return iekf_update


@dataclass
class Ukf(GaussianRangeOptions):
    """Unscented Kalman filter on both raw ranges. The scaled unscented transform with α = 1,
    β = 2, κ = 3 − n: sigma points at ±√3 σ, every weight positive.

    ``linearisation_correlation`` multiplies the linearisation error's variance (what the
    sigma points' statistical linearisation leaves of the ranges' spread), for the reason the
    EKF's does (see :class:`Ekf`). Its sigma points at ±√3 σ see the expansion's higher orders
    too, so it needs less than the EKF's 7: mean NEES over 200 runs (band [5.53, 6.49]) at
    1 (default) → 4 → 7: LQR world-frame law 6.83 → 5.81 → 5.54, paper 6.07 → 5.82 → 5.65,
    ``far_standoff`` 6.54 → 5.65 → 5.44, ``noisy_sonar`` 6.28 → 6.09 → 5.99; position RMSE
    within 2 % of 1's throughout. In ``realistic`` on the kinematic plant (late ranges, 50
    runs) 4 gave NEES 153 against 1860 with 1, neither consistent (each loses a seed).
    Over 1000 seeds (band [5.79, 6.22]; the robustness study's ``ukf2`` rows) 1 → 4: paper
    6.04 → 5.79, ``noisy_sonar`` 6.21 → 6.05, LQR world-frame law 6.80 → 5.78,
    ``far_standoff`` 6.58 → 5.66 (the last two just below the band: cautious); ``realistic``
    8.28 → 14.8 on the kinematic plant, 8.16 → 15.2 on the vehicle (200 seeds); no run lost."""

    linearisation_correlation: float = 1.0

    def validate(self, name: str) -> None:
        super().validate(name)
        check_between(
            f"{name}.linearisation_correlation", self.linearisation_correlation, 1.0, 1000.0
        )

    def range_update(self) -> RangeUpdate:
        if self.linearisation_correlation == 1.0:
            return ukf_range_update
        return functools.partial(ukf_range_update, correlation_steps=self.linearisation_correlation)


@dataclass
class ParticleFilter(RawRangeOptions):
    """Regularised particle filter on both raw ranges: with a large count, the empirical
    optimum. Its particles are drawn from the linear start's Gaussian at the hand-over, which
    needs no angle test (particles carry a curved posterior)."""

    handover_angle: float | None = None

    def validate(self, name: str) -> None:
        super().validate(name)
        if self.linear_start_max_steps == 0:
            fail(f"{name}.linear_start_max_steps",
                 "must not be 0: the particles are drawn from the linear start", 0)  # fmt: skip


@dataclass
class MarginalizedParticleFilter(ParticleFilter):
    """Marginalised (Rao-Blackwellised) particle filter on both raw ranges (Schön, Gustafsson &
    Nordlund 2005): particles carry the relative position and a Kalman filter of the velocity
    given its track, whose covariance is the same for every particle. Every option of the
    particle filter; the regularisation kernel (``particle_bandwidth_scale``) acts on each
    particle's position and velocity mean. Late ranges (``sonar.ping_offsets``,
    ``sonar.latency`` with ``error_model: modelled``) are not supported.

    In this model it is the particle filter at the same count, in cost and in accuracy. The
    target's acceleration drives both position and velocity (process noise ``B W Bᵀ``, rank
    3), so given a particle's position track its velocity follows from its first one,
    ``v' = 2 (q' − q − t²/2 a) / t − v + t a``, and each step's displacement measures it with
    covariance ``t² W / 4``: the conditional covariance is ``Σ_k = (Σ₀⁻¹ + 4k/t² W⁻¹)⁻¹``
    (tested in closed form). 100 steps after the hand-over ``tr Σ`` is below 3.8e-6 m²/s²,
    0.05 % of the posterior velocity covariance's trace in the paper scenario (0.0081) and
    0.015 % at σ = 1 m (0.025). The velocity's uncertainty rides on the cloud's spread of the
    means, as it rides on the particle filter's velocities, so marginalising removes none of
    the Monte Carlo error. (With the navigation's process noise modelled the noise has full
    rank and ``Σ`` no longer vanishes; not measured.)

    Measured: position RMSE over the 5000-particle ParticleFilter's, paired by seed (paper;
    σ = 1 m, ``noisy_sonar``). At 1000 particles over seeds 0-1999: 1.031 ± 0.002 and
    1.068 ± 0.022 (a tail: seed 1471 ends 8.4 m off, the 5000-particle filter's worst is
    2.25 m); against the 1000-particle ParticleFilter over seeds 0-999: 1.007 ± 0.004 and
    0.986 ± 0.013, the same. At 2000 particles over seeds 0-999: 1.009 ± 0.001 and
    1.021 ± 0.011; at σ = 1 m a transient excursion of the cloud trips the recovery, whose
    linear start costs metres at that noise (seed 22: 2.7 m against 1.0 m). At 3000 particles
    over seeds 0-999: 1.004 ± 0.001 and 1.004 ± 0.002, no tail (worst runs 0.33 m and
    1.75 m, the 5000-particle filter's 0.33 m and 2.25 m), mean NEES 6.30 and 6.22. So within
    2 % takes 2000 particles in the paper scenario and 3000 at σ = 1 m. Mean NEES at 1000
    particles 6.9 and 6.7 (overconfident; 6.2 and 6.1 at 5000). Kernel variants at 1000
    particles: ``particle_kernel: range_bearing`` 1.023 and 1.024 (seeds 0-499), with
    ``particle_bandwidth_scale: 1.1`` as well 1.023 and 1.032 (seeds 0-999); a scale of 1.25
    or 1.5 reaches 1.018 in the paper scenario but lets runs diverge at σ = 1 m. Mapping each
    resampled cloud affinely onto the weighted cloud's mean and unbiased covariance
    (range–bearing, scale 1.1; tried, not kept) gave 1.020 ± 0.003 and 1.031 ± 0.009 over
    seeds 0-1999: on seeds 0-999 alone it had looked within 2 % (1.016 and 1.019)."""


#: The estimator slot. The first member is the default of an untagged section.
EstimatorConfig = PaperKf | Ekf | Iekf | Ukf | ParticleFilter | MarginalizedParticleFilter
