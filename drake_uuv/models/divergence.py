"""When a Gaussian filter has diverged: a χ² test on the NIS of its last updates.

A consistent filter's normalised innovations squared are independent χ² draws with the
innovations' dimensions, so the sum over a window of updates is χ² with the summed
dimensions. A window, not one NIS, separates a filter that has lost the target (a run of large
innovations) from an outlier (one). The raw-range filters
(:class:`~drake_uuv.estimators.range_filter.RangeFilter`) use it to send a diverged run back to
its linear start (Bar-Shalom, Li and Kirubarajan, *Estimation with Applications to Tracking
and Navigation*, the time-average NIS test of filter consistency).
"""

import math
from dataclasses import dataclass

import numpy as np

from drake_uuv.models.statistics import chi2_ppf


@dataclass(frozen=True)
class DivergenceTest:
    """A Gaussian filter has diverged when its innovations say so over a window: the sum of
    the NIS of its last ``window`` updates exceeds the χ² quantile of ``1 − probability`` for
    their summed degrees of freedom (a consistent filter's NIS are independent χ² draws, so
    the sum is χ² with the summed dimensions; ``probability`` is the false-alarm rate of one
    test). A window rather than one NIS: a single large innovation is an outlier, a run of
    them a filter whose estimate or covariance no longer describes its error.

    The window is each run's last ``window`` NIS and their dimensions, oldest first, NaN
    until filled (:meth:`empty`, :meth:`pushed`); arrays carry a leading run axis and a run's
    numbers never read another's.
    """

    window: int
    probability: float

    def __post_init__(self) -> None:
        if isinstance(self.window, bool) or not isinstance(self.window, int) or self.window < 1:
            raise ValueError(f"window: must be an integer ≥ 1, got {self.window!r}")
        if not 0.0 < self.probability < 1.0:
            raise ValueError(f"probability: must be in (0, 1), got {self.probability!r}")
        table = [math.inf] + [
            chi2_ppf(1.0 - self.probability, k) for k in range(1, 2 * self.window + 1)
        ]
        object.__setattr__(self, "_thresholds", np.array(table))

    def threshold(self, dof: np.ndarray | int) -> np.ndarray:
        """The summed NIS above which a window of ``dof`` summed dimensions fails (``inf``
        for 0; tabled up to 2·window, two ranges an update, and computed beyond)."""
        dof = np.asarray(dof, dtype=np.intp)
        table = self._thresholds
        if dof.size and dof.max() >= len(table):  # rare: more than two ranges at some tick
            more = range(len(table), int(dof.max()) + 1)
            table = np.append(table, [chi2_ppf(1.0 - self.probability, k) for k in more])
        return table[dof]

    def empty(self, batch_size: int) -> np.ndarray:
        """Windows holding no update: (B, 2·window), the NIS then the dimensions."""
        return np.full((batch_size, 2 * self.window), np.nan)

    def pushed(
        self, windows: np.ndarray, nis: np.ndarray, dof: np.ndarray, new: np.ndarray
    ) -> np.ndarray:
        """The windows (B, 2·window) with each run in ``new`` (B) taking its update's ``nis``
        and ``dof`` (B) as the newest, the oldest dropped; the other runs' unchanged."""
        n = self.window
        shifted = np.empty_like(windows)
        shifted[:, : n - 1] = windows[:, 1:n]
        shifted[:, n - 1] = nis
        shifted[:, n : 2 * n - 1] = windows[:, n + 1 :]
        shifted[:, 2 * n - 1] = dof
        return np.where(new[:, np.newaxis], shifted, windows)

    def diverged(self, windows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(diverged, summed NIS, threshold)`` (B each): a full window whose summed NIS is
        above the χ² quantile of its summed dimensions (a window with a NaN never fails)."""
        n = self.window
        total = windows[:, :n].sum(axis=1)
        dof = windows[:, n:].sum(axis=1)
        full = np.isfinite(total) & np.isfinite(dof)
        threshold = self.threshold(np.where(full, dof, 0.0))
        return full & (total > threshold), total, threshold
