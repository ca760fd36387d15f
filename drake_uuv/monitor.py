"""A Simulator monitor that stops a run whose estimator has broken down, saying which and when."""

import math
from collections import deque
from operator import itemgetter

import numpy as np
from pydrake.systems.framework import Context, EventStatus, LeafSystem

from drake_uuv.estimators.base import RelativeStateEstimator

try:  # the gufunc behind np.linalg.cholesky, without its per-call checks (same LAPACK call)
    from numpy.linalg import _umath_linalg

    def _cholesky_fails(P: np.ndarray) -> bool:
        """Whether ``np.linalg.cholesky(P)`` would raise, for a finite square ``P``.

        The gufunc fills its result with NaN exactly when it would raise.
        """
        with np.errstate(invalid="ignore"):
            L = _umath_linalg.cholesky_lo(P, signature="d->d")
        return math.isnan(L[0, 0])

except (ImportError, AttributeError):  # pragma: no cover - other numpy layouts

    def _cholesky_fails(P: np.ndarray) -> bool:
        try:
            np.linalg.cholesky(P)
        except np.linalg.LinAlgError:
            return True
        return False


_SUCCEEDED = EventStatus.Succeeded()
# P's row-major entries above the diagonal and their mirror images below it.
_ABOVE = itemgetter(*[6 * i + j for i in range(6) for j in range(i + 1, 6)])
_BELOW = itemgetter(*[6 * j + i for i in range(6) for j in range(i + 1, 6)])
# 42 numbers smaller than this in magnitude have a finite sum in any order.
_SAFE_MAGNITUDE = 1e300


def _plainly_finite_and_symmetric(x_hat: np.ndarray, P: np.ndarray) -> bool:
    """A cheap sufficient test (on Python floats: a handful of numpy calls cost more than the
    arithmetic) that the finiteness and symmetry checks of
    :meth:`EstimatorHealthMonitor.problem` pass: every entry finite and of magnitude below
    :data:`_SAFE_MAGNITUDE`, and P exactly symmetric. False says nothing: the full checks
    then decide."""
    values = P.ravel().tolist()
    x = x_hat.tolist()
    if not math.isfinite(sum(values) + sum(x)):  # a NaN or an infinity, or a huge sum
        return False
    low, high = min(min(values), min(x)), max(max(values), max(x))
    return -_SAFE_MAGNITUDE < low and high < _SAFE_MAGNITUDE and _ABOVE(values) == _BELOW(values)


class SimulationFailure(RuntimeError):
    """A run stopped by the monitor; the message names the check, the step and the value."""


class EstimatorHealthMonitor:
    """Checks the estimator's outputs after every step (``Simulator.set_monitor``).

    It fails the run, rather than let NaNs or a meaningless estimate flow into the log, when:

    - ``x_TU_hat`` or ``P_TU`` is not finite;
    - ``P`` is not symmetric (relative asymmetry above ``symmetry_tolerance``) or not
      positive definite (its Cholesky factorisation fails);
    - the innovations blow up: the *median* NIS of the last ``nis_window`` updates exceeds
      ``nis_limit`` (a consistent filter's median NIS is about 0.5 for a scalar measurement,
      1.4 for two). The median ignores isolated outliers, which a gate may or may not reject;
      it trips only when most innovations are far larger than the filter predicts.

    A failed check stops the Simulator (``EventStatus.Failed``, which ``AdvanceTo`` raises as
    a ``RuntimeError``) and is recorded in :attr:`failure`, the one line that says which check
    and when; :meth:`reset` clears it.
    """

    def __init__(
        self,
        estimator: LeafSystem,
        time_step: float,
        nis_window: int = 20,
        nis_limit: float = 100.0,
        symmetry_tolerance: float = 1e-9,
    ) -> None:
        self._estimator = estimator
        self._time_step = time_step
        self._x_hat = estimator.GetOutputPort("x_TU_hat")
        self._P = estimator.GetOutputPort("P_TU")
        self._nis = estimator.GetOutputPort("nis")
        # The package's estimators publish their filtered estimate's fields on these ports:
        # read it once (no port evaluated for the monitor alone, nothing copied).
        self._filtered = (
            estimator.filtered if isinstance(estimator, RelativeStateEstimator) else None
        )
        self._recent_nis: deque[float] = deque(maxlen=nis_window)
        self._nis_sum = 0.0
        self._nis_limit = nis_limit
        self._symmetry_tolerance = symmetry_tolerance
        # An exactly symmetric P (asymmetry 0) passes the symmetry check.
        self._exact_symmetry_passes = symmetry_tolerance >= 0.0
        #: Why the monitor stopped the run (``"<problem> at step k=… (t=… s)"``), or None.
        self.failure: str | None = None

    def reset(self) -> None:
        """Forgets the NIS history and any failure (call before each run)."""
        self._recent_nis.clear()
        self._nis_sum = 0.0
        self.failure = None

    def problem(self, context: Context) -> str | None:
        """A one-line description of what is wrong with the estimator, or None."""
        x_hat, P, nis = self._outputs(context)
        if not (self._exact_symmetry_passes and _plainly_finite_and_symmetric(x_hat, P)):
            problem = self._finiteness_or_symmetry_problem(x_hat, P)
            if problem is not None:
                return problem
        if _cholesky_fails(P):
            smallest = float(np.linalg.eigvalsh(0.5 * (P + P.T))[0])
            return f"estimator covariance P is not positive definite (eigenvalue {smallest:.3e})"
        if math.isfinite(nis):
            self._nis_sum += nis
            if len(self._recent_nis) == self._recent_nis.maxlen:
                self._nis_sum -= self._recent_nis[0]
            self._recent_nis.append(nis)
            # The median exceeds the limit only if half the window does, so the mean exceeds
            # half the limit: a cheap test first, the median only then.
            full = len(self._recent_nis) == self._recent_nis.maxlen
            if full and self._nis_sum > 0.5 * self._nis_limit * len(self._recent_nis):
                median = float(np.median(self._recent_nis))
                if median > self._nis_limit:
                    return (
                        f"estimator innovations blew up: median NIS {median:.3g} over the last "
                        f"{len(self._recent_nis)} updates (a consistent filter gives about 0.5)"
                    )
        return None

    def _finiteness_or_symmetry_problem(self, x_hat: np.ndarray, P: np.ndarray) -> str | None:
        # NaN and ±Inf survive a sum, so one scalar test covers all 42 numbers.
        if not math.isfinite(float(x_hat.sum()) + float(P.sum())):
            return f"estimator output is not finite: x_hat={np.array2string(x_hat, precision=3)}"
        # The diagonal of an SPD matrix bounds every entry: |P_ij| ≤ √(P_ii P_jj) ≤ max P_ii.
        scale = max(float(P.trace()), 1e-300)
        # P − Pᵀ is exactly antisymmetric in floating point, so its largest entry is its
        # largest |entry|.
        asymmetry = float((P - P.T).max()) / scale
        if asymmetry > self._symmetry_tolerance:
            return f"estimator covariance P is not symmetric (relative asymmetry {asymmetry:.2e})"
        return None

    def _outputs(self, context: Context) -> tuple[np.ndarray, np.ndarray, float]:
        """The estimator's ``x_TU_hat``, ``P_TU`` (6×6) and ``nis`` at ``context``."""
        if self._filtered is not None:
            filtered = self._filtered(context)
            return filtered.x, filtered.published_P, float(filtered.nis)
        P = self._P.Eval(context).reshape(6, 6)
        return self._x_hat.Eval(context), P, float(self._nis.Eval(context)[0])

    def __call__(self, root_context: Context) -> EventStatus:
        # Only at the outer ticks: a plant with continuous state makes the simulator step
        # between them, where the estimator has nothing new (and evaluating it costs a filter
        # update on a measurement nobody takes).
        time = root_context.get_time()
        if abs(time - round(time / self._time_step) * self._time_step) > 1e-9 * max(time, 1.0):
            return _SUCCEEDED
        context = self._estimator.GetMyContextFromRoot(root_context)
        problem = self.problem(context)
        if problem is None:
            return _SUCCEEDED
        k = round(root_context.get_time() / self._time_step)
        self.failure = f"{problem} at step k={k} (t={root_context.get_time():g} s)"
        # No system pointer: pydrake crashes formatting a Python system's name into the error.
        return EventStatus.Failed(None, self.failure)
