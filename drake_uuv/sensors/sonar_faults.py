"""The sonar's faults and limits: which pings return nothing, and the multipath excess.

Every fault applies to a ping's own geometry (:class:`~drake_uuv.sensors.sonar_timing.
PingGeometry`): its true range, where its pan-tilt pointed and the target it missed.
"""

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Self

import numpy as np

from drake_uuv.models.measurement import DROPPED, OUT_OF_BEAM, OUT_OF_RANGE, VALID
from drake_uuv.models.so3 import norm
from drake_uuv.scenario.schema import SonarConfig
from drake_uuv.sensors.sonar_timing import PingGeometry


@dataclass
class SonarFaults:
    """Sensor realism beyond the paper; the defaults switch every effect off.

    - ``max_range`` [m]: no return from a target farther than this.
    - ``beam_half_angle`` [rad]: each pan-tilt sonar points at the estimator's *predicted*
      target position (known before the step's measurement, so there is no algebraic loop);
      a target further off that axis gives no return. Within one step (hundreds of pings at
      the sonar's rate) the pan-tilt scans the prediction's ``search_sigma``-σ region, so the
      acceptance cone is the wider of the beam and that region's angular radius: a target
      lost while the estimate drifts is found again once the uncertainty covers it.
    - ``dropout_probability`` (per sonar): a return lost, independently each step.
    - ``outlier_probability``, ``outlier_scale`` [m]: a multipath return, longer by an
      exponentially distributed excess of mean ``outlier_scale`` (all f samples of that step).
    """

    max_range: float | None = None
    beam_half_angle: float | None = None
    dropout_probability: tuple[float, float] = (0.0, 0.0)
    outlier_probability: float = 0.0
    outlier_scale: float = 1.0
    search_sigma: float = 3.0

    @property
    def random_faults(self) -> bool:
        return max(self.dropout_probability) > 0.0 or self.outlier_probability > 0.0

    @classmethod
    def from_config(cls, config: SonarConfig) -> Self:
        """The fault model of a sonar section (all off in the paper scenario)."""
        s = config
        half_angle = s.beam_half_angle_deg
        return cls(
            max_range=s.max_range,
            beam_half_angle=None if half_angle is None else math.radians(half_angle),
            dropout_probability=tuple(s.dropout_probability),
            outlier_probability=s.outlier_probability,
            outlier_scale=s.outlier_scale,
            search_sigma=s.search_sigma,
        )

    def search_radius(self, P_prior: np.ndarray) -> float:
        """The radius the pan-tilts scan: ``search_sigma`` σ of the predicted position's
        largest standard deviation (``P_prior`` 6×6)."""
        return self.search_sigma * math.sqrt(max(np.linalg.eigvalsh(P_prior[:3, :3])[-1], 0.0))


def pointing_attitude(ping: PingGeometry) -> np.ndarray:
    """The attitude by which the pan-tilt turns the predicted direction into its body frame:
    the vehicle's navigated attitude at the ping (``R_WB_nav``, the truth with
    ``!PerfectNavigation``)."""
    return ping.R_point


def beam_axis(ping: PingGeometry, baseline_B: np.ndarray) -> np.ndarray:
    """The world direction the ping's pan-tilt points along.

    The vehicle aims from the sonar at the predicted target, ``−(q_prior + offset)`` with
    the offset ``± ½ R_point b`` it believes; the pan-tilt turns that into the body frame by
    ``R_point`` (:func:`pointing_attitude`) and the true attitude carries it back to the
    world: ``R_WB R_pointᵀ (−(q_prior ± ½ R_point b))``. Pointing by the true attitude, the
    axis is the predicted direction itself (computed as such: the same bits).
    """
    R_point = pointing_attitude(ping)
    if R_point is ping.R_WB or np.array_equal(R_point, ping.R_WB):
        return -(ping.q_prior + ping.offset_W)
    return ping.R_WB @ (R_point.T @ -ping.q_prior - ping.sign * 0.5 * baseline_B)


def geometry_status(
    faults: SonarFaults,
    pings: Sequence[PingGeometry | None],
    true_ranges: np.ndarray,
    baseline_B: np.ndarray,
) -> np.ndarray:
    """OUT_OF_RANGE / OUT_OF_BEAM per sonar from each ping's true and pointed-at target
    (VALID, 0, for a sonar without a ping)."""
    status = np.zeros(2)
    if faults.max_range is not None:
        status[true_ranges > faults.max_range] = OUT_OF_RANGE
    if faults.beam_half_angle is None:
        return status
    for i, ping in enumerate(pings):
        if ping is None or status[i] != VALID:
            continue
        to_target = -ping.p_TS_W  # from the sonar to the true target
        axis = beam_axis(ping, baseline_B)  # from the sonar to the predicted target
        distance = norm(axis)
        radius = ping.search_radius
        half_angle = max(
            faults.beam_half_angle,
            math.pi if radius >= distance else math.asin(radius / distance),
        )
        cos_angle = (to_target @ axis) / (norm(to_target) * distance + 1e-300)
        if cos_angle < math.cos(half_angle):
            status[i] = OUT_OF_BEAM
    return status


def random_faults(
    faults: SonarFaults, status: np.ndarray, uniform: np.ndarray, exponential: np.ndarray
) -> np.ndarray:
    """Marks dropped returns DROPPED in ``status`` (in place) and returns each sonar's
    multipath excess [m]: ``uniform`` (4) holds the dropout then the outlier draws per
    sonar, ``exponential`` (2) the excesses of mean 1."""
    dropped = uniform[:2] < faults.dropout_probability
    status[(status == VALID) & dropped] = DROPPED
    outlier = uniform[2:] < faults.outlier_probability
    return np.where(outlier, faults.outlier_scale * exponential, 0.0)
