"""What an estimator exchanges with the rest of the loop and with its variants: its setting,
the ranges of an instant, estimates and updates."""

import math
from dataclasses import dataclass, field

import numpy as np

from drake_uuv.models.measurement import VALID
from drake_uuv.models.navigation_noise import (
    NavigationErrors,
    difference_attitude_variance,
    range_attitude_covariance,
)
from drake_uuv.models.timing import PingSchedule


@dataclass(frozen=True)
class EstimatorSetting:
    """What every estimator gets from the rest of the scenario (the builder passes it).

    - ``time_step`` t [s] of the loop.
    - ``acceleration_covariance``: W (3×3) of the target's random walk [m²/s⁴]
      (``target.acceleration_covariance``).
    - ``noise_variances``: η1, η2 of the two sonars' range noise [m²]
      (``sonar.noise_variances``).
    - ``samples_per_step``: f, range samples per sonar and step (``sonar.samples_per_step``).
    - ``baseline_B``: b = ᵇp_s1 − ᵇp_s2 in the body frame [m] (``sonar.baseline``): the world
      baseline ``q_s = R_WB b`` of a step follows from the attitude.
    - ``ping_schedule``: when each sonar pings and when its range arrives
      (``sonar.ping_offsets``, ``sonar.latency``); None: the paper's timing.
    - ``navigation_errors``: the navigation's error figures (``navigation.error_figures()``).
    - ``sound_speed_error``: ε, the ranges' scale error (``sonar.sound_speed_error``), taken as
      the size of an unknown scale.
    """

    time_step: float
    acceleration_covariance: np.ndarray
    noise_variances: np.ndarray
    samples_per_step: int = 1
    baseline_B: np.ndarray = field(default_factory=lambda: np.array([-1.0, 1.0, 0.0]))
    ping_schedule: PingSchedule | None = None
    navigation_errors: NavigationErrors = field(default_factory=NavigationErrors)
    sound_speed_error: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.time_step) and self.time_step > 0.0):
            raise ValueError(f"time_step: must be > 0, got {self.time_step!r}")
        W = np.asarray(self.acceleration_covariance, dtype=float)
        if W.shape != (3, 3) or not np.all(np.isfinite(W)):
            raise ValueError(f"acceleration_covariance: must be a finite 3×3 matrix, got {W!r}")
        eta = np.asarray(self.noise_variances, dtype=float).reshape(-1)
        if eta.shape != (2,) or not np.all(np.isfinite(eta)) or np.any(eta <= 0.0):
            raise ValueError(f"noise_variances: must be two numbers > 0, got {eta.tolist()!r}")
        f = self.samples_per_step
        if isinstance(f, bool) or int(f) != f or f < 1:
            raise ValueError(f"samples_per_step: must be an integer ≥ 1, got {f!r}")
        b = np.asarray(self.baseline_B, dtype=float)
        if b.shape != (3,) or not np.all(np.isfinite(b)):
            raise ValueError(f"baseline_B: must be 3 finite numbers, got {self.baseline_B!r}")
        object.__setattr__(self, "acceleration_covariance", W)
        object.__setattr__(self, "noise_variances", eta)
        object.__setattr__(self, "samples_per_step", int(f))
        object.__setattr__(self, "baseline_B", b)
        if self.ping_schedule is None:
            object.__setattr__(self, "ping_schedule", PingSchedule(self.time_step))
        elif self.ping_schedule.time_step != self.time_step:
            raise ValueError(
                f"ping_schedule: its time step must be {self.time_step!r}, got "
                f"{self.ping_schedule.time_step!r}"
            )


@dataclass
class Estimate:
    """Relative state estimates ``[q, ϑ]`` of a batch of runs and their covariances: ``x``
    (B, 6), ``P`` (B, 6, 6)."""

    x: np.ndarray
    P: np.ndarray


@dataclass(frozen=True)
class Ranges:
    """One step's ranges of a batch of runs, as an estimator reads them (run i in row i).

    ``samples`` (B, 2, f; sonar 1's row first; NaN without a return), ``z`` (B, 2) the
    per-sonar sample means, ``valid`` (B, 2) which sonars returned a usable range (status
    VALID and finite samples), ``status`` (B, 2) the sonar's per-sonar codes, ``q_s`` (B, 3)
    the world baseline ``R_WB b`` [m] at the ranges' instant.

    What the estimator's error model adds to the ranges' noise (None: nothing, for every
    run): ``attitude_covariance`` Σ_θ (B, 3, 3), the navigated attitude's error as a world
    rotation vector, which moves the baseline; ``extra_variance`` (B, 2), more variance per
    range (the sound-speed scale, a range carried from its own ping time to another).

    The methods broadcast over leading axes: a run's fields without the run axis (a single
    instant, as the window's steps and the particle cloud take them) work alike.
    """

    samples: np.ndarray
    z: np.ndarray
    valid: np.ndarray
    status: np.ndarray
    q_s: np.ndarray
    attitude_covariance: np.ndarray | None = None
    extra_variance: np.ndarray | None = None

    @property
    def sonars(self) -> np.ndarray:
        """The indices of the sonars that returned (a single run's ranges)."""
        return np.flatnonzero(self.valid)

    @property
    def exact(self) -> bool:
        """Whether the ranges' noise is the sonars' alone (for every run)."""
        return self.attitude_covariance is None and self.extra_variance is None

    def run(self, i: int) -> "Ranges":
        """Run i's ranges, without the run axis."""
        return Ranges(
            self.samples[i], self.z[i], self.valid[i], self.status[i], self.q_s[i],
            None if self.attitude_covariance is None else self.attitude_covariance[i],
            None if self.extra_variance is None else self.extra_variance[i],
        )  # fmt: skip

    def covariance(self, R: np.ndarray, x: np.ndarray) -> np.ndarray:
        """The two ranges' noise covariance (…, 2, 2): the sonars' ``R`` (2×2) plus the error
        model's, the attitude's part at the estimates ``x`` (…, 6)."""
        if self.exact:
            return R
        R = R + np.zeros(self.z.shape[:-1] + (2, 2))
        if self.extra_variance is not None:
            R[..., 0, 0] += self.extra_variance[..., 0]
            R[..., 1, 1] += self.extra_variance[..., 1]
        if self.attitude_covariance is not None:
            R += range_attitude_covariance(x[..., :3], self.q_s, self.attitude_covariance)
        return R

    def variances(self, eta: np.ndarray) -> np.ndarray:
        """The per-sonar variances ``η`` (2) plus the extra ones: (…, 2)."""
        if self.extra_variance is None:
            return np.broadcast_to(eta, self.z.shape)
        return eta + self.extra_variance

    def difference_variance(self, x: np.ndarray) -> np.ndarray:
        """The error model's extra variance of the paper's ``Y = q_sᵀ q`` at ``x`` (…, 6)."""
        if self.attitude_covariance is None:
            return np.zeros(self.z.shape[:-1])
        return difference_attitude_variance(x[..., :3], self.q_s, self.attitude_covariance)


@dataclass
class MeasurementUpdate:
    """A variant's proposed updates of a batch of runs: the posteriors (``x`` (B, 6), ``P``
    (B, 6, 6); the prior for a run not updated), their innovation statistic ``nis`` (B; NaN
    for a run not updated) and dimension ``dof`` (B), and ``updated`` (B) the runs updated
    (the others had no range to use)."""

    x: np.ndarray
    P: np.ndarray
    nis: np.ndarray  # normalised innovation squared νᵀ S⁻¹ ν
    dof: np.ndarray  # dimension of the innovation
    updated: np.ndarray
    # The noise variance Γ (B) of a linear update on the paper's Y (None for other updates):
    # a linear start tracks its prior's share of the covariance with it.
    gamma: np.ndarray | None = None


@dataclass
class FilteredEstimate:
    """``Υ̂(k|k)`` (B, 6), ``P(k|k)`` (B, 6, 6), each run's measurement status (B) and NIS
    (B; NaN: no update)."""

    x: np.ndarray
    P: np.ndarray
    status: np.ndarray
    nis: np.ndarray
    # What the published covariance adds to P (the error model's floors); None: nothing.
    floor: np.ndarray | None = None
    # Every update of the tick, applied or gated (with late ranges, each range that arrived
    # at it): their summed NIS and dimensions (B each; 0 and 0 without one), the evidence a
    # divergence test reads. None: not counted.
    innovation_nis: np.ndarray | None = None
    innovation_dof: np.ndarray | None = None

    @property
    def published_P(self) -> np.ndarray:
        """``P`` plus the floors: the covariance of ``x``'s error against the truth."""
        return self.P if self.floor is None else self.P + self.floor

    @property
    def applied(self) -> np.ndarray:
        """The runs whose measurement update was applied (VALID with a finite NIS), (B)."""
        return (self.status == VALID) & np.isfinite(self.nis)

    def run(self, i: int) -> "FilteredEstimate":
        """Run i's estimate as a batch of one."""
        runs = slice(i, i + 1)

        def part(value: np.ndarray | None) -> np.ndarray | None:
            return None if value is None else value[runs]

        return FilteredEstimate(
            self.x[runs], self.P[runs], self.status[runs], self.nis[runs], part(self.floor),
            part(self.innovation_nis), part(self.innovation_dof),
        )  # fmt: skip
