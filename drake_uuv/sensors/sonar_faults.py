"""The sonar's faults and limits: which pings return nothing, and the multipath excess.

Every fault applies to a ping's own geometry: its true range, where its pan-tilt pointed and
the target it missed (:func:`~drake_uuv.sensors.sonar_kernels.measure` judges them per run).
"""

import math
from dataclasses import dataclass
from typing import Self

import numpy as np
from numpy.linalg import _umath_linalg

from drake_uuv.scenario.schema import SonarConfig


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

    def search_radii(self, P_prior: np.ndarray) -> np.ndarray:
        """The radius the pan-tilts scan, per run: ``search_sigma`` σ of the predicted
        position's largest standard deviation (``P_prior`` (B, 6, 6), one covariance per run).

        A covariance whose eigenvalues cannot be found (NaN) gives NaN for its run only."""
        with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
            top = _eigvalsh(np.ascontiguousarray(P_prior[:, :3, :3]))[:, -1]
            return self.search_sigma * np.sqrt(np.where(top < 0.0, 0.0, top))


def _eigvalsh(A: np.ndarray) -> np.ndarray:
    """The eigenvalues of each symmetric matrix of a stack, ascending (its lower triangle, as
    ``np.linalg.eigvalsh``), NaN for a matrix whose eigenvalues do not converge: the gufunc
    ``np.linalg.eigvalsh`` calls, which raises for the whole stack instead."""
    return _umath_linalg.eigvalsh_lo(A, signature="d->d")
