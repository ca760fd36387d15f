"""Unscented Kalman update on the raw ranges, as plain numpy.

The measurement is the pair of per-sonar sample means ``z = [mean_j d1^j, mean_j d2^j]`` with
covariance ``R = diag(η1/f, η2/f)`` and model ``h(x) = [|q + ½ q_s|, |q − ½ q_s|]``, as for
the EKF; the UKF replaces the EKF's first-order Taylor expansion of ``h`` by an unscented
transform of the prior ``N(x̂⁻, P⁻)``, which keeps the second-order term of a range,
``tr(P⊥)/(2d)`` (``P⊥`` the prior position covariance across the line of sight), that the
EKF drops.

Sigma points
------------
The scaled unscented transform of Wan & van der Merwe (2000) on the n = 6 state, with
``α = 1``, ``β = 2``, ``κ = 3 − n`` (:data:`DEFAULT_PARAMETERS`): ``λ = α²(n + κ) − n = −3``,
``2n + 1`` points ``x̂``, ``x̂ ± √(n + λ) Lᵢ`` (``L`` the lower Cholesky factor of ``P⁻``,
``Lᵢ`` its columns), mean weights ``W₀ᵐ = λ/(n + λ) = −1``, ``Wᵢ = 1/(2(n + λ)) = 1/6``,
covariance weights ``W₀ᶜ = W₀ᵐ + 1 − α² + β = 1``, ``Wᵢ``. Why these:

* ``n + κ = 3`` is Julier & Uhlmann's rule: the points sit at ±√3 standard deviations, which
  matches the Gaussian's fourth moment along each sigma direction (``E e⁴ = 3σ⁴``); a
  cubature rule (``±√n``, here ±2.45σ) overstates it twice and puts points nearer the sonars
  when the prior is broad.
* ``β = 2`` is the Gaussian prior's choice, and with it every *covariance* weight is
  positive, so the joint covariance of ``(x, h(x))`` the points define is positive
  semi-definite and so are ``S`` and the posterior covariance (the negative mean weight
  ``W₀ᵐ`` only enters the means).
* Only the position block enters ``h``: the columns of ``L`` for the velocity have zero
  position rows (``L`` lower triangular, ``x = [q, ϑ]``), so their six points map to
  ``h(x̂)``. On ``q`` the rule is therefore the three-dimensional ±√3 rule with weight zero
  at the centre for the mean: the three-dimensional cubature rule, exactly.

Covariance update
-----------------
With the cross-covariance ``P_xz``, ``S = P_zz + R`` and ``K = P_xz S⁻¹``, the posterior
``P⁻ − K S Kᵀ`` is written in Joseph form with the statistically linearised measurement
matrix ``H = P_xzᵀ P⁻⁻¹`` and the effective noise ``R_eff = S − H P⁻ Hᵀ`` (``⪰ R``):
``(I − K H) P⁻ (I − K H)ᵀ + K R_eff Kᵀ``, algebraically equal, and symmetric positive
semi-definite under rounding as the EKF's Joseph form is. On a linear ``h(x) = H x`` the
update is the Kalman filter's, to rounding (the transform is exact for linear maps).

Every update returns ``(x, P, nis)`` like :func:`drake_uuv.models.filters.ekf_update`,
``nis = νᵀ S⁻¹ ν`` of the innovation against the unscented predicted measurement.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from drake_uuv.models.filters import RangeUpdate
from drake_uuv.models.measurement import batch_ranges


@dataclass(frozen=True)
class SigmaPointParameters:
    """``(α, β, κ)`` of the scaled unscented transform; ``κ = None`` means ``3 − n``."""

    alpha: float = 1.0
    beta: float = 2.0
    kappa: float | None = None

    def __post_init__(self) -> None:
        if not (np.isfinite(self.alpha) and self.alpha > 0.0):
            raise ValueError(f"alpha: must be > 0, got {self.alpha!r}")
        if not np.isfinite(self.beta):
            raise ValueError(f"beta: must be finite, got {self.beta!r}")
        if self.kappa is not None and not np.isfinite(self.kappa):
            raise ValueError(f"kappa: must be finite or None, got {self.kappa!r}")

    def spread(self, n: int) -> float:
        """``n + λ = α²(n + κ)``: the squared distance of the points in standard deviations."""
        kappa = 3.0 - n if self.kappa is None else self.kappa
        value = self.alpha**2 * (n + kappa)
        if not value > 0.0:
            raise ValueError(f"kappa: n + kappa must be > 0 for n = {n}, got {kappa!r}")
        return value


DEFAULT_PARAMETERS = SigmaPointParameters()


def sigma_points(
    x: np.ndarray, P: np.ndarray, parameters: SigmaPointParameters = DEFAULT_PARAMETERS
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The ``2n + 1`` sigma points (rows) of ``N(x, P)`` and their mean and covariance weights.

    Point 0 is ``x``; points ``1..n`` are ``x + √(n+λ) Lᵢ`` and ``n+1..2n`` are
    ``x − √(n+λ) Lᵢ`` with ``L = cholesky(P)``. Raises ``numpy.linalg.LinAlgError`` when ``P``
    is not positive definite.
    """
    x = np.asarray(x, dtype=float)
    n = x.size
    spread = parameters.spread(n)
    L = np.linalg.cholesky(np.asarray(P, dtype=float))
    offsets = np.sqrt(spread) * L.T  # row i is √(n+λ) Lᵢ
    points = np.empty((2 * n + 1, n))
    points[0] = x
    points[1 : n + 1] = x + offsets
    points[n + 1 :] = x - offsets
    lam = spread - n
    Wm = np.full(2 * n + 1, 0.5 / spread)
    Wm[0] = lam / spread
    Wc = Wm.copy()
    Wc[0] += 1.0 - parameters.alpha**2 + parameters.beta
    return points, Wm, Wc


def unscented_update(
    x_pred: np.ndarray,
    P_pred: np.ndarray,
    z: np.ndarray,
    R: np.ndarray,
    h: Callable[[np.ndarray], np.ndarray],
    parameters: SigmaPointParameters = DEFAULT_PARAMETERS,
    correlation_steps: float = 1.0,
) -> tuple[np.ndarray, np.ndarray, float]:
    """One unscented Kalman measurement update for ``z = h(x) + v``, ``v ~ N(0, R)``.

    ``h`` maps sigma points (rows of an ``(m, n)`` array) to predicted measurements
    (``(m, p)``). Returns ``(x, P, nis)``; the covariance in the Joseph form of the module
    docstring.

    ``correlation_steps`` multiplies the linearisation error's variance ``Ω = S − R − H P Hᵀ``
    (what the statistically linearised ``H`` leaves of the predicted measurement's spread):
    the error is a function of the estimate's, which persists over the updates a filter
    averages, so it counts that many updates' worth (1: the UKF's own, as if independent).
    """
    x_pred = np.asarray(x_pred, dtype=float)
    P_pred = np.asarray(P_pred, dtype=float)
    z = np.asarray(z, dtype=float).reshape(-1)
    R = np.asarray(R, dtype=float).reshape(z.size, z.size)
    points, Wm, Wc = sigma_points(x_pred, P_pred, parameters)
    Z = np.asarray(h(points), dtype=float).reshape(points.shape[0], z.size)
    z_hat = Wm @ Z
    dZ = Z - z_hat
    dX = points - x_pred  # the weighted mean of the points is x_pred exactly
    S = (Wc[:, None] * dZ).T @ dZ + R
    P_xz = (Wc[:, None] * dX).T @ dZ
    H = np.linalg.solve(P_pred, P_xz).T  # statistical linearisation: P_xzᵀ P⁻¹
    if correlation_steps != 1.0:
        omega = S - R - H @ P_pred @ H.T
        S = S + (correlation_steps - 1.0) * 0.5 * (omega + omega.T)
    K = np.linalg.solve(S, P_xz.T).T  # P_xz S⁻¹ (S symmetric)
    nu = z - z_hat
    x = x_pred + K @ nu
    R_eff = S - H @ P_pred @ H.T
    R_eff = 0.5 * (R_eff + R_eff.T)
    I_KH = np.eye(x.size) - K @ H
    P = I_KH @ P_pred @ I_KH.T + K @ R_eff @ K.T
    return x, 0.5 * (P + P.T), float(nu @ np.linalg.solve(S, nu))


def range_model_points(points: np.ndarray, q_s: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """The selected ranges ``|q ± ½ q_s|`` of each point (rows of ``points``).

    Returns shape ``(m, len(rows))``.
    """
    return batch_ranges(points[:, :3].T, q_s).T[:, rows]


def ukf_range_update(
    x_pred: np.ndarray,
    P_pred: np.ndarray,
    z: np.ndarray,
    q_s: np.ndarray,
    R: np.ndarray,
    sonars: tuple[int, ...] | np.ndarray = (0, 1),
    parameters: SigmaPointParameters = DEFAULT_PARAMETERS,
    correlation_steps: float = 1.0,
) -> tuple[np.ndarray, np.ndarray, float]:
    """UKF update on the raw ranges: the unscented counterpart of ``ekf_update``
    (``correlation_steps`` as :func:`unscented_update`'s).

    ``z`` are the per-sonar sample means, ``R = diag(η1/f, η2/f)`` their covariance, ``q_s``
    the world baseline; ``sonars`` selects the ranges used (``(0,)`` or ``(1,)`` when only one
    sonar returned; the other entry of ``z`` is then ignored and may be NaN). Returns
    ``(x, P, nis)`` with ``nis`` χ² with ``len(sonars)`` degrees of freedom when consistent.
    """
    rows = np.asarray(sonars, dtype=int).reshape(-1)
    if rows.size == 0 or not set(rows.tolist()) <= {0, 1}:
        raise ValueError(f"sonars: must be a non-empty subset of (0, 1), got {sonars!r}")
    z = np.asarray(z, dtype=float).reshape(2)[rows]
    R = np.asarray(R, dtype=float)[np.ix_(rows, rows)]
    return unscented_update(
        x_pred, P_pred, z, R, lambda X: range_model_points(X, q_s, rows), parameters,
        correlation_steps,
    )  # fmt: skip


def unscented_range_update(parameters: SigmaPointParameters = DEFAULT_PARAMETERS) -> RangeUpdate:
    """:func:`ukf_range_update` with its sigma-point parameters bound: a
    :data:`~drake_uuv.models.filters.RangeUpdate`."""
    if not isinstance(parameters, SigmaPointParameters):
        raise ValueError(f"parameters: must be SigmaPointParameters, got {parameters!r}")
    parameters.spread(6)  # Fail early on a κ with n + κ ≤ 0.
    return functools.partial(ukf_range_update, parameters=parameters)
