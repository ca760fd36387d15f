"""The scenario: every number of a run, as nested dataclasses.

``Scenario()`` is the paper's §IV simulation. Four sections are *slots* whose value is one of
several variant dataclasses, chosen in YAML by a tag, as RussTedrake/manipulation's
``station.py`` chooses model drivers::

    plant: !KinematicUuv {}
    estimator: !Ekf {gate_probability: 0.99}
    attitude: !TrajectoryAttitude {max_angular_rate: 0.8}
    tracking: !LqrTracking {max_acceleration: 7}

The variants live in :mod:`~drake_uuv.scenario.plants`, :mod:`~drake_uuv.scenario.estimators`,
:mod:`~drake_uuv.scenario.attitude` and :mod:`~drake_uuv.scenario.tracking`; each checks its
own fields in ``validate(name)``.
"""

# No `from __future__ import annotations`: Drake's yaml loader needs the real field types.
import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from drake_uuv.scenario.attitude import AttitudeConfig, TrajectoryAttitude
from drake_uuv.scenario.estimators import EstimatorConfig, MarginalizedParticleFilter, PaperKf
from drake_uuv.scenario.navigation import NavigationConfig, PerfectNavigation
from drake_uuv.scenario.plants import KinematicUuv, PlantConfig
from drake_uuv.scenario.tracking import PaperTracking, TrackingConfig
from drake_uuv.scenario.validation import (
    check_between,
    check_positive,
    check_spd,
    check_vector,
    fail,
)


@dataclass
class UuvConfig:
    """Initial state of the vehicle (world frame W, body frame B), whatever the plant."""

    initial_position: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    initial_velocity: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    # Roll-pitch-yaw [rad] of R_WB(0); the paper's R(0) = I.
    initial_rpy: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])

    def validate(self, name: str) -> None:
        check_vector(f"{name}.initial_position", self.initial_position, 3)
        check_vector(f"{name}.initial_velocity", self.initial_velocity, 3)
        check_vector(f"{name}.initial_rpy", self.initial_rpy, 3)


@dataclass
class TargetConfig:
    """The non-cooperative target: a random walk in acceleration."""

    initial_position: list[float] = field(default_factory=lambda: [1.0, 2.0, 2.0])
    initial_velocity: list[float] = field(default_factory=lambda: [0.02, 0.1, 0.1])
    # W, covariance of the target's acceleration [m²/s⁴].
    acceleration_covariance: list[list[float]] = field(
        default_factory=lambda: [[0.004, 0.0, 0.0], [0.0, 0.001, 0.0], [0.0, 0.0, 0.001]]
    )

    def validate(self, name: str) -> None:
        check_vector(f"{name}.initial_position", self.initial_position, 3)
        check_vector(f"{name}.initial_velocity", self.initial_velocity, 3)
        check_spd(f"{name}.acceleration_covariance", self.acceleration_covariance, 3)


@dataclass
class SonarConfig:
    """Two monostatic sonars at ±½ baseline about the body origin."""

    # b = ᵇp_s1 − ᵇp_s2 in the body frame [m].
    baseline: list[float] = field(default_factory=lambda: [-1.0, 1.0, 0.0])
    # η1, η2: range noise variances [m²].
    noise_variances: list[float] = field(default_factory=lambda: [0.01, 0.01])
    # f: range samples per sonar and step (the first forms Y; all estimate d̄²).
    samples_per_step: int = 1
    # Faults and limits, all off by default (the paper assumes every return arrives).
    # No return beyond this range [m]; None: unlimited.
    max_range: float | None = None
    # Each pan-tilt sonar points at the predicted target; no return beyond this angle [deg].
    beam_half_angle_deg: float | None = None
    # Within a step the pan-tilt scans this many σ of the predicted position (0: no scan).
    search_sigma: float = 3.0
    # Per sonar, the probability that a step's return is lost.
    dropout_probability: list[float] = field(default_factory=lambda: [0.0, 0.0])
    # Per sonar and step, the probability of a multipath return, longer by an exponentially
    # distributed excess of mean outlier_scale [m].
    outlier_probability: float = 0.0
    outlier_scale: float = 1.0
    # Timing, all zero by default (the paper: both sonars ping at the step's tick, and their
    # ranges reach the estimator at once). When each sonar pings, seconds after the tick
    # (each in [0, time_step)): two sonars on one hull alternate, or they interfere.
    ping_offsets: list[float] = field(default_factory=lambda: [0.0, 0.0])
    # Seconds from a ping to the estimator: the echo's travel and its processing.
    latency: float = 0.0
    # ε: every measured range is scaled by (1 + ε), the error of the sound speed assumed
    # (about 1500 m/s in seawater, varying by a few percent with temperature, salinity, depth).
    sound_speed_error: float = 0.0

    def validate(self, name: str) -> None:
        baseline = check_vector(f"{name}.baseline", self.baseline, 3)
        if np.linalg.norm(baseline) < 1e-3:
            fail(f"{name}.baseline", "must be non-zero (|b| ≥ 1 mm)", self.baseline)
        eta = check_vector(f"{name}.noise_variances", self.noise_variances, 2)
        if np.any(eta <= 1e-12):
            fail(f"{name}.noise_variances", "must be > 0 (at least 1e-12 m²)", self.noise_variances)
        if not 1 <= self.samples_per_step <= 10_000:
            fail(f"{name}.samples_per_step", "must be in [1, 10000]", self.samples_per_step)
        if self.max_range is not None:
            check_positive(f"{name}.max_range", self.max_range)
        half_angle = self.beam_half_angle_deg
        if half_angle is not None and not 0.0 < half_angle <= 180.0:
            fail(f"{name}.beam_half_angle_deg", "must be in (0, 180]", half_angle)
        check_positive(f"{name}.search_sigma", self.search_sigma, strict=False)
        dropout = check_vector(f"{name}.dropout_probability", self.dropout_probability, 2)
        if np.any((dropout < 0.0) | (dropout >= 1.0)):
            fail(f"{name}.dropout_probability", "must be in [0, 1)", self.dropout_probability)
        if not 0.0 <= self.outlier_probability < 1.0:
            fail(f"{name}.outlier_probability", "must be in [0, 1)", self.outlier_probability)
        check_positive(f"{name}.outlier_scale", self.outlier_scale)
        offsets = check_vector(f"{name}.ping_offsets", self.ping_offsets, 2)
        if np.any(offsets < 0.0):
            fail(f"{name}.ping_offsets", "must be ≥ 0 each", self.ping_offsets)
        check_positive(f"{name}.latency", self.latency, strict=False)
        if not -0.1 < self.sound_speed_error < 0.1:
            fail(f"{name}.sound_speed_error", "must be in (−0.1, 0.1)", self.sound_speed_error)


@dataclass
class AnalysisConfig:
    """Post-run analysis: figures, metrics and statistics (no effect on the simulation: the
    information-seeking planner has its own window, ``attitude.excitation_window``)."""

    # N: window length [steps] of the persistent-excitation figure and metric, the extreme
    # eigenvalues of Σ_{m=k}^{k+N−1} q_s(m) q_s(m)ᵀ (paper eq. 10).
    pe_window: int = 24

    def validate(self, name: str) -> None:
        if not 1 <= self.pe_window <= 10**6:
            fail(f"{name}.pe_window", "must be in [1, 1e6]", self.pe_window)


@dataclass
class Scenario:
    """One closed-loop run. ``Scenario()`` is the paper's §IV simulation."""

    time_step: float = 0.5
    steps: int = 500
    random_seed: int = 0
    # First step k of the steady-state window over which metrics are taken.
    steady_state_start: int = 200
    uuv: UuvConfig = field(default_factory=UuvConfig)
    target: TargetConfig = field(default_factory=TargetConfig)
    sonar: SonarConfig = field(default_factory=SonarConfig)
    plant: PlantConfig = field(default_factory=KinematicUuv)
    navigation: NavigationConfig = field(default_factory=PerfectNavigation)
    estimator: EstimatorConfig = field(default_factory=PaperKf)
    attitude: AttitudeConfig = field(default_factory=TrajectoryAttitude)
    tracking: TrackingConfig = field(default_factory=PaperTracking)
    analysis: AnalysisConfig = field(default_factory=AnalysisConfig)

    def validate(self) -> None:
        """Checks every field; raises :class:`ScenarioError` on the first bad one."""
        check_between("time_step", self.time_step, 1e-4, 1e3)
        if not 1 <= self.steps <= 10**8:
            fail("steps", "must be in [1, 1e8]", self.steps)
        if self.random_seed < 0 or self.random_seed >= 2**32:
            fail("random_seed", "must be in [0, 2**32)", self.random_seed)
        if not 0 <= self.steady_state_start < self.steps:
            fail(
                "steady_state_start", f"must be in [0, steps={self.steps})", self.steady_state_start
            )
        for name in SECTIONS:
            getattr(self, name).validate(name)
        t = self.time_step
        if max(self.sonar.ping_offsets) >= t:
            fail("sonar.ping_offsets", f"must be < time_step = {t:g} each", self.sonar.ping_offsets)
        if self.sonar.latency > 10.0 * t:
            fail("sonar.latency", f"must be ≤ 10 time steps = {10.0 * t:g} s", self.sonar.latency)
        late = max(self.sonar.ping_offsets) > 0.0 or self.sonar.latency > 0.0
        if (
            late
            and isinstance(self.estimator, MarginalizedParticleFilter)
            and self.estimator.error_model == "modelled"
        ):
            # Its cloud takes each tick's ranges at the tick only (no window of late ranges).
            fail(
                "sonar.ping_offsets",
                "must be zero, with sonar.latency, for the marginalised particle filter with "
                "error_model: modelled (use ParticleFilter, or estimator.error_model=ideal)",
                self.sonar.ping_offsets,
            )


def describe(scenario: "Scenario") -> str:
    """A short title: each slot's variant, and the paper law's α or the noise model.

    E.g. ``KinematicUuv, PaperKf (derived), TrajectoryAttitude, PaperTracking α = 1.2``.
    """
    tracking = scenario.tracking
    alpha = f" α = {tracking.alpha:g}" if isinstance(tracking, PaperTracking) else ""
    return ", ".join(
        [
            type(scenario.plant).__name__,
            f"{type(scenario.estimator).__name__} ({scenario.estimator.noise_model})",
            type(scenario.attitude).__name__,
            type(tracking).__name__ + alpha,
        ]
    )


def scenario_as_dict(scenario: "Scenario") -> dict[str, Any]:
    """The scenario as plain data (JSON-ready), each slot with its variant named first:
    ``{"estimator": {"variant": "Ekf", "noise_model": "derived", …}, …}``.

    ``dataclasses.asdict`` alone loses the variant: ``!Ekf`` and ``!Iekf`` have the same
    fields, so two scenarios that differ only in a variant would look equal.
    """
    data = dataclasses.asdict(scenario)
    for slot in SLOTS:
        data[slot] = {"variant": type(getattr(scenario, slot)).__name__, **data[slot]}
    return data


#: The slots: sections whose value is one of several variant dataclasses, chosen by YAML tag.
SLOTS = ("plant", "navigation", "estimator", "attitude", "tracking")
#: The sections of a scenario, in the order they are validated.
SECTIONS = (
    "uuv", "target", "sonar", "plant", "navigation", "estimator", "attitude", "tracking",
    "analysis",
)  # fmt: skip
