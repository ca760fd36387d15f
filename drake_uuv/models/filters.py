"""Filter steps for the relative state, as pure numpy functions (no Drake).

One implementation shared by every estimator LeafSystem:

* :func:`predict` — the time update ``x⁺ = A x + B a_W``, ``P⁺ = A P Aᵀ + Q``.
* :func:`range_difference_update` — the paper's KF update on ``Y = ½(d1² − d2²) = q_sᵀ q + v̄``
  (eq. 9), Joseph form. The paper's KF LeafSystem and the raw-range filters' linear start
  both call it.
* :func:`ekf_update` — EKF update on both raw ranges (sample means of all f samples), or on
  the one that returned, Joseph form.
* :func:`iekf_update` — iterated EKF: Gauss–Newton on the MAP cost with a backtracking
  step limit, Joseph form at the final iterate.

Every update returns ``(x, P, nis)`` where ``nis = νᵀ S⁻¹ ν`` is the normalised innovation
squared of the *prior* innovation (χ² with 1 degree of freedom for the linear update, 2 for
the range updates, when the filter is consistent).

Why the linear KF starts a raw-range filter
-------------------------------------------
The range model ``d_i = |q ± ½ q_s|`` is nearly linear only once the position error is small
compared with the range (the linearisation error of a range is about ``σ⊥²/(2d)`` for a
position error ``σ⊥`` across the line of sight). From the paper's prior (``x̂ = 0``,
``P = I``, true ``|q| = 3 m``) the EKF linearises at a point where both sonars look along
±q_s, the two Jacobian rows are antiparallel and the update is meaningless; it can lock
onto a wrong solution (the ranges are symmetric under reflection through the line of the
sonars). The range difference ``Y`` is *exactly* linear in ``q``, so the paper's KF converges
from any prior without a linearisation point and its covariance is exact (for a linear
filter with the right second moments the Riccati covariance is the true MSE, Gaussian or
not). The raw-range filter therefore runs linear-KF updates (built from the same sample
means it would use itself) until its hand-over policy (:mod:`drake_uuv.models.handover`)
says a Gaussian on the ranges holds, then continues as an (I)EKF from that estimate and
covariance.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from drake_uuv.models.measurement import (
    MIN_RANGE,
    range_jacobian,
    range_measurement,
)

#: A Gaussian update on the raw ranges: :func:`ekf_update`, :func:`iekf_update`, or the
#: unscented :func:`~drake_uuv.models.unscented.unscented_range_update`'s.
#: ``(x_pred, P_pred, z, q_s, R, sonars=(0, 1)) -> (x, P, nis)``: ``z`` the per-sonar sample
#: means, ``R`` their covariance, ``sonars`` the indices of the sonars that returned (the
#: signature is :func:`ekf_update`'s).
RangeUpdate = Callable[..., tuple[np.ndarray, np.ndarray, float]]


def _symmetrise(P: np.ndarray) -> np.ndarray:
    return 0.5 * (P + P.T)


def _joseph(P_pred: np.ndarray, K: np.ndarray, H: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Joseph form ``(I − K H) P (I − K H)ᵀ + K R Kᵀ``: symmetric PSD for any gain."""
    I_KH = np.eye(P_pred.shape[0]) - K @ H
    return _symmetrise(I_KH @ P_pred @ I_KH.T + K @ R @ K.T)


def predict(
    x: np.ndarray, P: np.ndarray, a_W: np.ndarray, A: np.ndarray, B: np.ndarray, Q: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Time update: ``x(k+1|k) = A x(k|k) + B a_W(k)``, ``P(k+1|k) = A P Aᵀ + Q``.

    ``a_W`` is the known world-frame acceleration applied to the UUV (``R u1``); the target's
    unknown acceleration enters through ``Q = B W Bᵀ``.
    """
    x_next = A @ np.asarray(x, dtype=float) + B @ np.asarray(a_W, dtype=float).reshape(3)
    P_next = _symmetrise(A @ P @ A.T + Q)
    return x_next, P_next


_I6 = np.eye(6)


def range_difference_update(
    x_pred: np.ndarray, P_pred: np.ndarray, Y: float, m: float, Gamma: float, q_s: np.ndarray
) -> tuple[np.ndarray, np.ndarray, float]:
    """The paper's KF measurement update (eq. 9) on ``Y = q_sᵀ q + v̄``, ``E v̄ = m``, ``Var v̄ = Γ``.

    ``C = [q_sᵀ, 0]``; ``K = P Cᵀ (C P Cᵀ + Γ)⁻¹``; ``Υ̂ = Υ̂⁻ + K (Y − C Υ̂⁻ − m)``; the
    covariance in Joseph form ``(I − KC) P (I − KC)ᵀ + K Γ Kᵀ`` (symmetrised), which stays
    symmetric positive definite under rounding. ``m`` and ``Γ`` are the mean and variance of
    the noise ``v̄`` (:func:`drake_uuv.models.measurement.range_difference_noise`). Returns
    ``(x, P, nis)`` with ``nis = ν²/S`` (χ²₁ when consistent).
    """
    PCt = P_pred[:, :3] @ q_s
    S = float(q_s @ PCt[:3]) + Gamma
    K = PCt / S
    innovation = Y - float(q_s @ x_pred[:3]) - m
    I_KC = _I6.copy()
    I_KC[:, :3] -= K[:, np.newaxis] * q_s  # np.outer's product, without its wrapper
    P = I_KC @ P_pred @ I_KC.T
    P += Gamma * (K[:, np.newaxis] * K)
    P_sym = P + P.T
    P_sym *= 0.5  # _symmetrise(P), in place
    return x_pred + K * innovation, P_sym, innovation * innovation / S


def _select(
    z: np.ndarray, R: np.ndarray, sonars: tuple[int, ...] | np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The indices, measurements and noise covariance of the sonars used in an update."""
    rows = np.asarray(sonars, dtype=int).reshape(-1)
    if rows.size == 0 or not set(rows.tolist()) <= {0, 1}:
        raise ValueError(f"sonars must be a non-empty subset of (0, 1), got {sonars!r}")
    z = np.asarray(z, dtype=float).reshape(2)[rows]
    return rows, z, np.asarray(R, dtype=float)[np.ix_(rows, rows)]


def ekf_update(
    x_pred: np.ndarray,
    P_pred: np.ndarray,
    z: np.ndarray,
    q_s: np.ndarray,
    R: np.ndarray,
    sonars: tuple[int, ...] | np.ndarray = (0, 1),
    second_order: str = "none",
    correlation_steps: float = 1.0,
) -> tuple[np.ndarray, np.ndarray, float]:
    """EKF update on the raw ranges, Joseph form.

    ``z`` are the per-sonar sample means ``[mean_j d1^j, mean_j d2^j]`` and
    ``R = diag(η1/f, η2/f)`` their covariance. ``H`` is :func:`range_jacobian` at ``x_pred``.
    ``sonars`` selects the ranges used (``(0,)`` or ``(1,)`` when only one sonar returned; the
    other entry of ``z`` is then ignored and may be NaN).
    Returns ``(x, P, nis)`` with ``nis = νᵀ S⁻¹ ν`` (χ² with ``len(sonars)`` degrees of
    freedom when consistent).

    ``second_order`` keeps terms of the ranges' second-order expansion (Gelb, *Applied Optimal
    Estimation*, the truncated second-order filter): ``"mean"`` predicts each range as
    ``dᵢ + tr(P⊥ᵢ)/(2dᵢ)``, the mean of ``|q + e|`` under ``e ~ N(0, P_qq)`` to second order
    (:func:`second_order_range_terms`); ``"variance"`` adds the variance of that quadratic
    term, ``½ tr(H''ᵢ P H''ⱼ P)``, to ``R``; ``"full"`` both; ``"none"`` neither (the EKF).

    ``correlation_steps`` multiplies that variance. The quadratic term is a function of the
    estimate's error, which persists over the error's correlation time: over the τ updates a
    filter averages while its error stays, the term adds τ times the variance an independent
    noise would (a bias shared by N samples does not average out), so ``τ`` updates' worth
    counts at each (1: Gelb's, as if independent from update to update).
    """
    rows, z, R = _select(z, R, sonars)
    H = range_jacobian(x_pred, q_s)[rows]
    h = range_measurement(x_pred, q_s)[rows]
    if second_order != "none":
        mean, covariance = second_order_range_terms(x_pred, P_pred, q_s)
        if second_order in ("mean", "full"):
            h = h + mean[rows]
        if second_order in ("variance", "full"):
            R = R + correlation_steps * covariance[np.ix_(rows, rows)]
    nu = z - h
    S = H @ P_pred @ H.T + R
    K = np.linalg.solve(S, H @ P_pred).T  # P Hᵀ S⁻¹ (S, P symmetric)
    x = x_pred + K @ nu
    P = _joseph(P_pred, K, H, R)
    return x, P, float(nu @ np.linalg.solve(S, nu))


SECOND_ORDER_TERMS = ("none", "mean", "variance", "full")


def second_order_range_terms(
    x: np.ndarray, P: np.ndarray, q_s: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The second-order terms of both ranges ``dᵢ(q + e) = dᵢ + uᵢᵀe + ½ eᵀ H''ᵢ e + …`` under
    ``e ~ N(0, P_qq)``, ``H''ᵢ = (I − uᵢuᵢᵀ)/dᵢ``: their means ``tr(P⊥ᵢ)/(2dᵢ)`` (2) and
    covariance ``½ tr(H''ᵢ P_qq H''ⱼ P_qq)`` (2×2) [m, m²]."""
    q = np.asarray(x, dtype=float)[:3]
    P_qq = np.asarray(P, dtype=float)[:3, :3]
    q_s = np.asarray(q_s, dtype=float).reshape(3)
    hessians = []
    for sign in (0.5, -0.5):
        v = q + sign * q_s
        d = max(float(np.linalg.norm(v)), MIN_RANGE)
        u = v / d
        hessians.append((np.eye(3) - np.outer(u, u)) / d)
    mean = np.array([0.5 * np.trace(M @ P_qq) for M in hessians])
    covariance = np.array(
        [[0.5 * np.trace(Ma @ P_qq @ Mb @ P_qq) for Mb in hessians] for Ma in hessians]
    )
    return mean, covariance


def iekf_update(
    x_pred: np.ndarray,
    P_pred: np.ndarray,
    z: np.ndarray,
    q_s: np.ndarray,
    R: np.ndarray,
    max_iterations: int = 5,
    tolerance: float = 1e-8,
    max_halvings: int = 8,
    sonars: tuple[int, ...] | np.ndarray = (0, 1),
) -> tuple[np.ndarray, np.ndarray, float]:
    """Iterated EKF update: Gauss–Newton on the MAP cost, with a backtracking step limit.

    Minimises ``c(x) = ½|z − h(x)|²_{R⁻¹} + ½|x − x_pred|²_{P⁻¹}`` by the IEKF iteration
    ``x⁺ = x_pred + K_i (z − h(x_i) − H_i (x_pred − x_i))``, ``K_i = P H_iᵀ(H_i P H_iᵀ + R)⁻¹``
    (the Gauss–Newton step). A step that does not lower ``c`` is halved up to ``max_halvings``
    times; the iteration stops after ``max_iterations`` or when the step is below
    ``tolerance`` (in the ``P⁻¹`` norm). The covariance is the Joseph form with the gain and
    Jacobian at the final iterate. With one iteration and a full step its estimate and NIS
    are those of :func:`ekf_update` (the covariance then uses the Jacobian at the updated
    estimate rather than at the prediction). ``sonars`` selects the ranges, as there.
    Returns ``(x, P, nis)``; ``nis`` uses the prior innovation, as in :func:`ekf_update`.
    """
    rows, z, R = _select(z, R, sonars)
    L = np.linalg.cholesky(P_pred)
    R_inv = np.linalg.inv(R)

    def h(x: np.ndarray) -> np.ndarray:
        return range_measurement(x, q_s)[rows]

    def jacobian(x: np.ndarray) -> np.ndarray:
        return range_jacobian(x, q_s)[rows]

    def cost(x: np.ndarray) -> float:
        r = z - h(x)
        e = np.linalg.solve(L, x - x_pred)
        return 0.5 * float(r @ R_inv @ r) + 0.5 * float(e @ e)

    H0 = jacobian(x_pred)
    nu0 = z - h(x_pred)
    S0 = H0 @ P_pred @ H0.T + R
    nis = float(nu0 @ np.linalg.solve(S0, nu0))

    x = np.array(x_pred, dtype=float)
    c = cost(x)
    for _ in range(max(int(max_iterations), 1)):
        H = jacobian(x)
        S = H @ P_pred @ H.T + R
        K = np.linalg.solve(S, H @ P_pred).T
        step = x_pred + K @ (z - h(x) - H @ (x_pred - x)) - x
        scale = 1.0
        for _ in range(int(max_halvings) + 1):
            c_try = cost(x + scale * step)
            if c_try <= c:
                break
            scale *= 0.5
        else:
            break  # no descent along the Gauss–Newton direction: x is (numerically) optimal
        x = x + scale * step
        c = c_try
        if np.linalg.norm(np.linalg.solve(L, scale * step)) < tolerance:
            break
    H = jacobian(x)
    S = H @ P_pred @ H.T + R
    K = np.linalg.solve(S, H @ P_pred).T
    return x, _joseph(P_pred, K, H, R), nis
