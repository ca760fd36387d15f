"""A Simulator monitor that marks each run of a batch whose estimator has broken down, saying
which check failed and when; the other runs go on."""

import math

import numpy as np
from numba import njit
from pydrake.systems.framework import Context, EventStatus, LeafSystem

from drake_uuv.estimators.base import RelativeStateEstimator

_SUCCEEDED = EventStatus.Succeeded()
# The kernel's problem codes.
_FINE, _NOT_FINITE, _ASYMMETRIC, _INDEFINITE, _INNOVATIONS = range(5)


@njit(cache=True)
def _positive_definite(P: np.ndarray, L: np.ndarray) -> bool:  # pragma: no cover - compiled
    """Whether the Cholesky factorisation of ``P``'s lower triangle (LAPACK's potrf reads one
    triangle too) succeeds, into the work array ``L``."""
    n = P.shape[0]
    for j in range(n):
        s = P[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        if not s > 0.0:
            return False
        L[j, j] = math.sqrt(s)
        for i in range(j + 1, n):
            s = P[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            L[i, j] = s / L[j, j]
    return True


@njit(cache=True)
def _check_runs(
    x: np.ndarray,
    P: np.ndarray,
    nis: np.ndarray,
    watched: np.ndarray,
    symmetry_tolerance: float,
    nis_limit: float,
    history: np.ndarray,
    counts: np.ndarray,
    medians: np.ndarray,
) -> np.ndarray:  # pragma: no cover - compiled
    """Each watched run's problem code this step (0: none), checks in the order of
    :meth:`EstimatorHealthMonitor.problems`; the NIS history (``history`` (B, W), ``counts``
    (B,) updates seen) moves on for runs with a finite NIS, and ``medians`` receives the median
    of a run that trips the innovation check.

    One loop over runs in compiled code: numpy's dozen calls a step would cost more than the
    arithmetic for a single run, and the runs are independent.
    """
    B, n = x.shape
    W = history.shape[1]
    codes = np.zeros(B, dtype=np.int64)
    L = np.empty((n, n))
    for r in range(B):
        if not watched[r]:
            continue
        finite = True
        for i in range(n):
            if not math.isfinite(x[r, i]):
                finite = False
            for j in range(n):
                if not math.isfinite(P[r, i, j]):
                    finite = False
        if not finite:
            codes[r] = _NOT_FINITE
            continue
        trace = 0.0
        for i in range(n):
            trace += P[r, i, i]
        scale = max(trace, 1e-300)
        asymmetry = 0.0
        for i in range(n):
            for j in range(i + 1, n):
                asymmetry = max(asymmetry, abs(P[r, i, j] - P[r, j, i]))
        if asymmetry / scale > symmetry_tolerance:
            codes[r] = _ASYMMETRIC
            continue
        if not _positive_definite(P[r], L):
            codes[r] = _INDEFINITE
            continue
        value = nis[r]
        if math.isfinite(value):
            history[r, counts[r] % W] = value
            counts[r] += 1
            if counts[r] >= W:
                total = 0.0
                for i in range(W):
                    total += history[r, i]
                # The median exceeds the limit only if half the window does, so the mean
                # exceeds half the limit: a cheap test first, the median only then.
                if total > 0.5 * nis_limit * W:
                    median = np.median(history[r])
                    if median > nis_limit:
                        medians[r] = median
                        codes[r] = _INNOVATIONS
    return codes


class SimulationFailure(RuntimeError):
    """A run stopped by the monitor; the message names the check, the step and the value."""


class EstimatorHealthMonitor:
    """Checks the estimator's outputs of every run after every step (``Simulator.set_monitor``).

    A run fails, rather than let NaNs or a meaningless estimate flow into its metrics, when:

    - its ``x_TU_hat`` or ``P_TU`` is not finite;
    - its ``P`` is not symmetric (relative asymmetry above ``symmetry_tolerance``) or not
      positive definite (its Cholesky factorisation fails);
    - its innovations blow up: the *median* NIS of its last ``nis_window`` updates exceeds
      ``nis_limit`` (a consistent filter's median NIS is about 0.5 for a scalar measurement,
      1.4 for two). The median ignores isolated outliers, which a gate may or may not reject;
      it trips only when most innovations are far larger than the filter predicts.

    A failed run is recorded in :attr:`failures` (one line per run: which check and when) and
    no longer watched: it is frozen as far as the study is concerned, its metrics NaN, while
    the batch's other runs go on, their numbers untouched (each run's arithmetic is its own).
    When every run of the batch has failed the Simulator is stopped (``EventStatus.Failed``,
    which ``AdvanceTo`` raises as a ``RuntimeError``): for a single run, that is the run.
    :meth:`reset` clears the record.
    """

    def __init__(
        self,
        estimator: LeafSystem,
        time_step: float,
        nis_window: int = 20,
        nis_limit: float = 100.0,
        symmetry_tolerance: float = 1e-9,
        batch_size: int = 1,
    ) -> None:
        self._estimator = estimator
        self._time_step = time_step
        self._batch_size = int(batch_size)
        self._x_hat = estimator.GetOutputPort("x_TU_hat")
        self._P = estimator.GetOutputPort("P_TU")
        self._nis = estimator.GetOutputPort("nis")
        # The package's estimators publish their filtered estimate's fields on these ports:
        # read it once (no port evaluated for the monitor alone, nothing copied).
        self._filtered = (
            estimator.filtered if isinstance(estimator, RelativeStateEstimator) else None
        )
        self._nis_window = int(nis_window)
        self._nis_limit = float(nis_limit)
        self._symmetry_tolerance = float(symmetry_tolerance)
        self.reset()

    def reset(self) -> None:
        """Forgets the NIS histories and every failure (call before each batch)."""
        B = self._batch_size
        self._history = np.zeros((B, self._nis_window))
        self._counts = np.zeros(B, dtype=np.int64)
        self._medians = np.zeros(B)
        self._watched = np.ones(B, dtype=bool)
        #: Each run's failure (``"<problem> at step k=… (t=… s)"``), or None.
        self.failures: list[str | None] = [None] * B

    @property
    def failure(self) -> str | None:
        """The first failed run's record (a single run's failure), or None."""
        return next((f for f in self.failures if f is not None), None)

    @property
    def failed(self) -> np.ndarray:
        """A (B,) mask of the runs that failed."""
        return ~self._watched

    def problems(self, context: Context) -> dict[int, str]:
        """A one-line description of what is wrong, for each watched run that has a problem
        at ``context`` (the estimator's context); those runs are no longer watched."""
        x_hat, P, nis = self._outputs(context)
        codes = _check_runs(
            x_hat, P, nis, self._watched, self._symmetry_tolerance, self._nis_limit,
            self._history, self._counts, self._medians,
        )  # fmt: skip
        found = {}
        for run in np.flatnonzero(codes):  # rare: a failing run
            found[int(run)] = self._describe(int(codes[run]), x_hat[run], P[run], run)
            self._watched[run] = False
        return found

    def _describe(self, code: int, x_hat: np.ndarray, P: np.ndarray, run: int) -> str:
        if code == _NOT_FINITE:
            return f"estimator output is not finite: x_hat={np.array2string(x_hat, precision=3)}"
        if code == _ASYMMETRIC:
            asymmetry = float(np.abs(P - P.T).max()) / max(float(P.trace()), 1e-300)
            return f"estimator covariance P is not symmetric (relative asymmetry {asymmetry:.2e})"
        if code == _INDEFINITE:
            smallest = float(np.linalg.eigvalsh(0.5 * (P + P.T))[0])
            return f"estimator covariance P is not positive definite (eigenvalue {smallest:.3e})"
        return (
            f"estimator innovations blew up: median NIS {self._medians[run]:.3g} over the last "
            f"{self._nis_window} updates (a consistent filter gives about 0.5)"
        )

    def _outputs(self, context: Context) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The estimator's ``x_TU_hat`` (B, 6), ``P_TU`` (B, 6, 6) and ``nis`` (B,)."""
        B = self._batch_size
        if self._filtered is not None:
            filtered = self._filtered(context)
            x, P, nis = filtered.x, filtered.published_P, filtered.nis
        else:
            x, P, nis = self._x_hat.Eval(context), self._P.Eval(context), self._nis.Eval(context)
        x = np.ascontiguousarray(x, dtype=float).reshape(B, 6)
        P = np.ascontiguousarray(P, dtype=float).reshape(B, 6, 6)
        return x, P, np.asarray(nis, dtype=float).reshape(B)

    def __call__(self, root_context: Context) -> EventStatus:
        # Only at the outer ticks: a plant with continuous state makes the simulator step
        # between them, where the estimator has nothing new (and evaluating it costs a filter
        # update on a measurement nobody takes).
        time = root_context.get_time()
        if abs(time - round(time / self._time_step) * self._time_step) > 1e-9 * max(time, 1.0):
            return _SUCCEEDED
        context = self._estimator.GetMyContextFromRoot(root_context)
        found = self.problems(context)
        if not found:
            return _SUCCEEDED
        k = round(time / self._time_step)
        for run, problem in found.items():
            self.failures[run] = f"{problem} at step k={k} (t={time:g} s)"
        if self._watched.any():
            return _SUCCEEDED
        # No system pointer: pydrake crashes formatting a Python system's name into the error.
        return EventStatus.Failed(None, self.failure)
