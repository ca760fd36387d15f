"""Posterior Cramér–Rao lower bound (PCRLB) of the relative state, and the KF's own bound.

Pure numpy. The bound is for the *filtered* estimate ``x̂(k|k)`` from the prior and all
measurements up to and including step ``k``; the measurement is the two raw ranges with all
``f`` samples per sonar, whose Fisher information is that of the per-sonar sample means,
``R = diag(η1/f, η2/f)``.

Recursion (Tichavský, Muravchik, Nehorai 1998) for linear dynamics ``x(k+1) = A x(k) +
B(a_W − ū)`` with additive Gaussian process noise of covariance ``Q = B W Bᵀ``. Since ``Q`` is
singular (rank 3), the usual ``D¹¹ − D¹²(J + D¹¹)⁻¹D²¹`` form (which needs ``Q⁻¹``) fails; the
equivalent form that needs only ``J⁻¹`` is used::

    J(0)   = P0⁻¹ + M(0)
    J(k+1) = (Q + A J(k)⁻¹ Aᵀ)⁻¹ + M(k+1),     M(k) = E[H(x_k)ᵀ R⁻¹ H(x_k)]

and the bound is ``P_bound(k) = J(k)⁻¹`` (``E[(x̂ − x)(x̂ − x)ᵀ] ⪰ J⁻¹``). The known control
``a_W`` does not enter. It is computed as a covariance recursion (``P⁻ = A P Aᵀ + Q``,
``P = (P⁻⁻¹ + M)⁻¹``), which is the same arithmetic with one inverse fewer.

The expectation and Monte Carlo averaging
-----------------------------------------
For linear-Gaussian dynamics the *only* expectation in the exact recursion is the one in the
measurement term ``M(k)``: the exact unconditional PCRLB is the recursion run **once** with
``M(k)`` averaged over the distribution of the true state at step k. With Monte Carlo runs,
average the information increments ``H(x_k)ᵀ R⁻¹ H(x_k)`` over runs at each k and recurse
once (``unconditional`` of :func:`pcrlb_over_runs`). That is neither "average J" nor "average
J⁻¹" of per-run recursions. Because ``J ↦ (Q + A J⁻¹ Aᵀ)⁻¹`` is monotone and
matrix-concave and inversion is matrix-convex,

    PCRLB (averaged M)  ⪯  (mean over runs of J_run)⁻¹  ⪯  mean over runs of J_run⁻¹,

so averaging per-run J is a slightly conservative approximation of the bound, and
averaging per-run J⁻¹ (:func:`pcrlb_along_trajectory` per run, then the mean:
``per_run_mean``) the most conservative; only the first is a proven bound.

The gap is not small here. Each run's ranges carry information in only two directions
(the null direction ``q_s × q`` is across both lines of sight), and in the closed loop the
true ``q`` wanders about ``R q*`` by up to a metre in the body z direction, so the null
direction differs from run to run at the same k. Averaging ``M`` over runs fills in the
null direction and gives a bound no single run can approach: on the paper scenario with
the EKF (30 runs) the steady-state position bound is 0.215 m with averaged ``M``, 0.219 m
with averaged J, 0.235 m with averaged ``J⁻¹``, while the EKF reaches 0.239 m (velocity:
0.0897, 0.0900, 0.0912, EKF 0.0908). An estimator that is efficient run by run attains
the mean of ``J⁻¹``; the averaged-``M`` bound is then unattainable by about 9 % (Jensen).
Check: tracking the *true* state instead (``_reference.py --control-from-truth``) makes
the geometry independent of the estimate; the three averages then coincide (0.235 m) and
the EKF attains the bound (100 runs: 0.998 ± 0.011 in position, 0.997 ± 0.006 in
velocity), while in the real loop it is at 1.083 ± 0.012 × the averaged-``M`` bound and
0.995 × the mean of per-run ``J⁻¹``.
Report the averaged-``M`` bound as the PCRLB and the mean of per-run ``J⁻¹`` beside it.

Closed loop: the control depends on the estimate, so the true trajectories, and with them
the bound, depend on the estimator. Evaluate the bound on the trajectories of the run
being scored (see ``_reference.py``).

The linear KF's own bound, :func:`kf_riccati_covariance`, is its Riccati covariance: for a
linear filter with the correct noise second moments it *is* the filter's MSE, whatever the
noise distribution. Since ``Y = ½(d1² − d2²)`` is a function of the ranges, the PCRLB is
below it (``M(k) ⪰ Cᵀ Γ⁻¹ C`` at every step by Cauchy–Schwarz).

Here every range is taken at its step's tick and reaches the estimator at once, with the
vehicle's navigation perfect. Ranges at their own ping times, counted once they arrive, are
in :mod:`drake_uuv.models.pcrlb_timed` (the same recursion when every ping is at the tick);
what navigation errors and the sound speed add, in :mod:`drake_uuv.models.navigation_noise`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from drake_uuv.models.motion import double_integrator, process_noise_covariance


def symmetrise(P: np.ndarray) -> np.ndarray:
    """``½(P + Pᵀ)`` of (stacked) square matrices: rounding leaves covariances asymmetric."""
    return 0.5 * (P + np.swapaxes(P, -1, -2))


def _as_trajectory(a: np.ndarray, name: str, width: int) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    if a.ndim != 2 or a.shape[1] != width:
        raise ValueError(f"{name} must have shape (N, {width}), got {a.shape}")
    return a


def _as_trajectories(a: np.ndarray, name: str, width: int) -> np.ndarray:
    """A trajectory (N×width) or a stack of them (…×N×width)."""
    a = np.asarray(a, dtype=float)
    if a.ndim < 2 or a.shape[-1] != width:
        raise ValueError(f"{name} must have shape (N, {width}), got {a.shape}")
    return a


def _availability(available: np.ndarray | None, shape: tuple[int, ...] | int) -> np.ndarray:
    shape = (shape, 2) if isinstance(shape, int) else (*shape, 2)
    if available is None:
        return np.ones(shape, dtype=bool)
    mask = np.asarray(available, dtype=bool)
    if mask.shape != shape:
        raise ValueError(f"available must have shape {shape}, got {mask.shape}")
    return mask


def measurement_information(
    q_true: np.ndarray,
    q_s: np.ndarray,
    eta: np.ndarray,
    samples_per_step: int,
    available: np.ndarray | None = None,
    out: np.ndarray | None = None,
) -> np.ndarray:
    """Fisher information ``M(k) = H(x_k)ᵀ R⁻¹ H(x_k)`` of the raw ranges at each step.

    ``q_true`` (N×3) true relative positions, ``q_s`` (N×3) world baselines, ``eta`` (2,)
    range noise variances, ``f = samples_per_step``; ``available`` (N×2 bool, default all
    true) says which sonar returned at each step (a missing return carries no information).
    Returns (N×6×6); only the position block is non-zero: ``Σ_i (f/η_i) u_i u_iᵀ`` over the
    available sonars, with ``u_i`` the unit line-of-sight vectors. Leading axes (runs:
    ``B×N×3`` → ``B×N×6×6``) go element by element, each run the same bits as alone.
    ``out`` (optional, C-contiguous, the result's shape) receives the result.
    """
    q = _as_trajectories(q_true, "q_true", 3)
    qs = _as_trajectories(q_s, "q_s", 3)
    if qs.shape != q.shape:
        raise ValueError(f"q_s shape {qs.shape} differs from q_true shape {q.shape}")
    mask = _availability(available, q.shape[:-1])
    eta = np.asarray(eta, dtype=float).reshape(2)
    weights = float(samples_per_step) / eta
    M = np.empty((*q.shape[:-1], 6, 6)) if out is None else out
    if M.shape != (*q.shape[:-1], 6, 6) or not M.flags.c_contiguous:
        raise ValueError(f"out must be C-contiguous of shape {(*q.shape[:-1], 6, 6)}")
    _information_kernel(
        np.ascontiguousarray(q).reshape(-1, 3), np.ascontiguousarray(qs).reshape(-1, 3),
        np.ascontiguousarray(mask).reshape(-1, 2), weights, M.reshape(-1, 6, 6),
    )  # fmt: skip
    return M


@njit(cache=True)
def _information_kernel(
    q: np.ndarray, q_s: np.ndarray, mask: np.ndarray, weights: np.ndarray, M: np.ndarray
) -> None:
    """``Σ_i w_i u_i u_iᵀ`` into each step's position block (the rest of ``M`` zero), with
    ``u_i = r_i / max(|r_i|, 1e-9)``, ``r_i = q ± ½ q_s``, ``w_i`` the sonar's weight where it
    returned (numpy's order of operations, step by step)."""
    u = np.empty(3)
    for n in range(q.shape[0]):
        M[n] = 0.0
        for i in range(2):
            sign = 0.5 if i == 0 else -0.5
            squared = 0.0
            for a in range(3):
                u[a] = q[n, a] + sign * q_s[n, a]
                squared += u[a] * u[a]
            norm = max(np.sqrt(squared), 1e-9)
            for a in range(3):
                u[a] = u[a] / norm
            w = weights[i] if mask[n, i] else 0.0
            for a in range(3):
                wu = w * u[a]
                for b in range(3):
                    M[n, a, b] += wu * u[b]


def pcrlb_recursion(
    information: np.ndarray, P0: np.ndarray, W: np.ndarray, time_step: float
) -> np.ndarray:
    """Run ``J(k+1) = (Q + A J(k)⁻¹ Aᵀ)⁻¹ + M(k+1)`` from ``J(0) = P0⁻¹ + M(0)``.

    ``information`` (N×6×6) are the measurement information increments ``M(k)`` (already
    averaged over runs if a Monte Carlo bound is wanted), ``P0`` the prior covariance of
    ``x(0)`` (the filter's ``P(0|−1)``), ``W`` the target acceleration covariance.
    Returns the bounds ``J(k)⁻¹`` (N×6×6) on the filtered estimate's error covariance.
    Leading batch dimensions (``B×N×6×6``) run independent recursions at once, each the same
    bits as alone (a compiled loop over them, :func:`_pcrlb_kernel`). A recursion whose
    matrix to invert is not positive definite (a singular prior, a non-finite trajectory) is
    NaN from that step on, and leaves the others.
    """
    M = np.asarray(information, dtype=float)
    if M.ndim < 3 or M.shape[-2:] != (6, 6):
        raise ValueError(f"information must have shape (N, 6, 6), got {M.shape}")
    double_integrator(time_step)  # checks the step
    Q = process_noise_covariance(W, time_step)
    P0 = symmetrise(np.asarray(P0, dtype=float).reshape(6, 6))
    bounds = np.empty(M.shape)
    _pcrlb_kernel(
        np.ascontiguousarray(M).reshape(-1, *M.shape[-3:]), P0, Q, float(time_step),
        bounds.reshape(-1, *M.shape[-3:]),
    )  # fmt: skip
    return bounds


#: Recursions the kernel steps side by side (independent lanes the compiler may put in one
#: SIMD register; each lane's arithmetic is its own run's, so its bits are the run's alone).
_LANES = 4


@njit(cache=True)
def _pcrlb_kernel(M: np.ndarray, P0: np.ndarray, Q: np.ndarray, t: float, out: np.ndarray) -> None:
    """The recursion of :func:`pcrlb_recursion` for each of ``M``'s runs (R×N×6×6) into
    ``out``, as a covariance recursion: ``P⁻ = ½(X + Xᵀ)`` with ``X = A P Aᵀ + Q`` (``A`` the
    double integrator of step t, written out), ``J = ½(Y + Yᵀ)`` with ``Y = P⁻⁻¹ + M``,
    ``P = J⁻¹`` (inverses by Cholesky: exactly symmetric; NaN where a matrix is not
    positive definite, and so from there on). Runs go :data:`_LANES` at a time, lane g
    holding run ``first + g`` (the last run repeated past the end, not written)."""
    runs, steps = M.shape[0], M.shape[1]
    G = _LANES
    P = np.empty((6, 6, G))
    X = np.empty((6, 6, G))
    S = np.empty((6, 6, G))
    L = np.empty((6, 6, G))
    L_inv = np.empty((6, 6, G))
    d_inv = np.empty((6, G))
    lanes = np.empty(G, np.int64)
    for first in range(0, runs, G):
        for g in range(G):
            lanes[g] = min(first + g, runs - 1)
        for k in range(steps):
            if k == 0:
                for i in range(6):
                    for j in range(6):
                        for g in range(G):
                            S[i, j, g] = P0[i, j]
            else:
                _predict_lanes(P, Q, t, X)
                for i in range(6):
                    for j in range(6):
                        for g in range(G):
                            S[i, j, g] = 0.5 * (X[i, j, g] + X[j, i, g])
            _inverse_lanes(S, X, L, L_inv, d_inv)
            for i in range(6):
                for j in range(6):
                    for g in range(G):
                        S[i, j, g] = X[i, j, g] + M[lanes[g], k, i, j]
            for i in range(6):
                for j in range(6):
                    for g in range(G):
                        X[i, j, g] = 0.5 * (S[i, j, g] + S[j, i, g])
            _inverse_lanes(X, P, L, L_inv, d_inv)
            for g in range(min(G, runs - first)):
                for i in range(6):
                    for j in range(6):
                        out[first + g, k, i, j] = P[i, j, g]


@njit(cache=True)
def _predict_lanes(P: np.ndarray, Q: np.ndarray, t: float, out: np.ndarray) -> None:
    """``A P Aᵀ + Q`` per lane for the double integrator ``A = [[I, tI], [0, I]]``: with ``P``
    in 3×3 blocks ``[[P11, P12], [P21, P22]]``, ``A P Aᵀ = [[P11 + t P21 + t (P12 + t P22),
    P12 + t P22], [P21 + t P22, P22]]``."""
    for i in range(3):
        for j in range(3):
            for g in range(_LANES):
                p12 = P[i, j + 3, g] + t * P[i + 3, j + 3, g]
                out[i, j, g] = P[i, j, g] + t * P[i + 3, j, g] + t * p12 + Q[i, j]
                out[i, j + 3, g] = p12 + Q[i, j + 3]
                out[i + 3, j, g] = P[i + 3, j, g] + t * P[i + 3, j + 3, g] + Q[i + 3, j]
                out[i + 3, j + 3, g] = P[i + 3, j + 3, g] + Q[i + 3, j + 3]


@njit(cache=True)
def _inverse_lanes(
    S: np.ndarray, out: np.ndarray, L: np.ndarray, L_inv: np.ndarray, d_inv: np.ndarray
) -> None:
    """``S⁻¹`` per lane of symmetric 6×6 matrices (6×6×G) by Cholesky, ``L⁻ᵀ L⁻¹`` (exactly
    symmetric); a lane whose ``S`` is not positive definite (a pivot not > 0, or NaN) gets a
    NaN pivot, which makes its whole inverse NaN."""
    G = _LANES
    for j in range(6):
        for g in range(G):
            d = S[j, j, g]
            for m in range(j):
                d -= L[j, m, g] * L[j, m, g]
            d = np.sqrt(d) if d > 0.0 else np.nan
            L[j, j, g] = d
            d_inv[j, g] = 1.0 / d
        for i in range(j + 1, 6):
            for g in range(G):
                v = S[i, j, g]
                for m in range(j):
                    v -= L[i, m, g] * L[j, m, g]
                L[i, j, g] = v * d_inv[j, g]
    for j in range(6):
        for g in range(G):
            L_inv[j, j, g] = d_inv[j, g]
        for i in range(j + 1, 6):
            for g in range(G):
                v = 0.0
                for m in range(j, i):
                    v -= L[i, m, g] * L_inv[m, j, g]
                L_inv[i, j, g] = v * d_inv[i, g]
    for i in range(6):
        for j in range(i + 1):
            for g in range(G):
                v = 0.0
                for m in range(i, 6):
                    v += L_inv[m, i, g] * L_inv[m, j, g]
                out[i, j, g] = v
                out[j, i, g] = v


@njit(cache=True)
def cholesky6(S: np.ndarray, L: np.ndarray, d_inv: np.ndarray) -> bool:
    """The lower Cholesky factor of a symmetric 6×6 ``S`` (lower triangle read) into ``L``
    (its upper triangle left as is) and the reciprocals of its diagonal into ``d_inv``; False
    where ``S`` is not numerically positive definite or not finite. (The size is fixed so the
    compiler unrolls the loops.)"""
    for j in range(6):
        d = S[j, j]
        for m in range(j):
            d -= L[j, m] * L[j, m]
        if not d > 0.0:  # NaN too
            return False
        d = np.sqrt(d)
        L[j, j] = d
        d_inv[j] = 1.0 / d
        for i in range(j + 1, 6):
            v = S[i, j]
            for m in range(j):
                v -= L[i, m] * L[j, m]
            L[i, j] = v * d_inv[j]
    return True


@njit(cache=True)
def lower_inverse6(L: np.ndarray, d_inv: np.ndarray, L_inv: np.ndarray) -> None:
    """``L⁻¹`` into ``L_inv``'s lower triangle, of a 6×6 lower-triangular ``L`` whose
    diagonal's reciprocals are ``d_inv``."""
    for j in range(6):
        L_inv[j, j] = d_inv[j]
        for i in range(j + 1, 6):
            v = 0.0
            for m in range(j, i):
                v -= L[i, m] * L_inv[m, j]
            L_inv[i, j] = v * d_inv[i]


def pcrlb_along_trajectory(
    q_true: np.ndarray,
    q_s: np.ndarray,
    P0: np.ndarray,
    W: np.ndarray,
    eta: np.ndarray,
    samples_per_step: int,
    time_step: float,
    available: np.ndarray | None = None,
) -> np.ndarray:
    """PCRLB ``J(k)⁻¹`` (N×6×6) with the expectation replaced by its value on one trajectory.

    ``q_true`` (N×3) is the true relative position ``p_uuv − p_target`` at steps 0..N−1,
    ``q_s`` (N×3) the world baselines ``R(k) b``, ``P0`` (6×6) the prior covariance
    ``P(0|−1)``, ``W`` (3×3), ``eta`` (2,) the range noise variances, ``samples_per_step`` f,
    ``available`` (N×2 bool, optional) which sonars returned (see
    :func:`measurement_information`).
    For the Monte Carlo bound use :func:`pcrlb_over_runs` (see the module docstring).
    """
    M = measurement_information(q_true, q_s, eta, samples_per_step, available)
    return pcrlb_recursion(M, P0, W, time_step)


def _runs(q_true_runs: np.ndarray, q_s_runs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Checks and broadcasts the (runs×N×3) trajectories of the Monte Carlo bounds."""
    q = np.asarray(q_true_runs, dtype=float)
    if q.ndim != 3 or q.shape[2] != 3:
        raise ValueError(f"q_true_runs must have shape (runs, N, 3), got {q.shape}")
    qs = np.asarray(q_s_runs, dtype=float)
    if qs.ndim == 2:
        qs = np.broadcast_to(qs, q.shape)
    if qs.shape != q.shape:
        raise ValueError(f"q_s_runs shape {qs.shape} does not match q_true_runs {q.shape}")
    return q, qs


class MonteCarloBounds(NamedTuple):
    """The two bounds of a set of Monte Carlo runs (each N×6×6)."""

    # The unconditional PCRLB: the information increments averaged over runs, recursed once.
    unconditional: np.ndarray
    # The mean over runs of the per-trajectory bounds J_run(k)⁻¹: not a proven bound (see the
    # module docstring), but what an estimator that is efficient on every trajectory attains.
    per_run_mean: np.ndarray


def pcrlb_over_runs(
    q_true_runs: np.ndarray,
    q_s_runs: np.ndarray,
    P0: np.ndarray,
    W: np.ndarray,
    eta: np.ndarray,
    samples_per_step: int,
    time_step: float,
) -> MonteCarloBounds:
    """Both bounds of Monte Carlo runs, reported side by side.

    ``q_true_runs`` and ``q_s_runs`` have shape (runs×N×3) (``q_s_runs`` may also be (N×3)
    when the attitude does not depend on the run). The unconditional bound averages
    ``H(x_k)ᵀ R⁻¹ H(x_k)`` over runs at every k, then runs the recursion once: the
    expectation of the recursion sits inside J. The per-run mean recurses each run alone.
    """
    q, qs = _runs(q_true_runs, q_s_runs)
    information = np.zeros((q.shape[1], 6, 6))
    bounds = np.zeros((q.shape[1], 6, 6))
    for run in range(q.shape[0]):
        M = measurement_information(q[run], qs[run], eta, samples_per_step)
        information += M
        bounds += pcrlb_recursion(M, P0, W, time_step)
    runs = q.shape[0]
    return MonteCarloBounds(pcrlb_recursion(information / runs, P0, W, time_step), bounds / runs)


def kf_riccati_covariance(
    q_s: np.ndarray,
    P0: np.ndarray,
    W: np.ndarray,
    Gamma: np.ndarray,
    time_step: float,
    available: np.ndarray | None = None,
) -> np.ndarray:
    """The paper's linear KF's own covariance ``P(k|k)`` (N×6×6): its Riccati recursion.

    Measurement ``Y(k) = q_s(k)ᵀ q + v̄`` with noise variance ``Gamma[k]`` (N,), ``C(k) =
    [q_s(k)ᵀ, 0]``, prior ``P(0|−1) = P0``; gain form with Joseph update, as the filter runs.
    ``available`` (N×2 bool, optional): ``Y`` needs both ranges, so a step where either sonar
    is missing only predicts.
    With ``Γ`` evaluated on the true ranges this is the KF's MSE (a lower bound for no other
    estimator; compare it with the PCRLB to see what ``Y`` throws away).
    """
    qs = _as_trajectory(q_s, "q_s", 3)
    Gamma = np.asarray(Gamma, dtype=float).reshape(-1)
    if Gamma.shape[0] != qs.shape[0]:
        raise ValueError(f"Gamma has {Gamma.shape[0]} entries for {qs.shape[0]} steps")
    both = _availability(available, qs.shape[0]).all(axis=1)
    A, _ = double_integrator(time_step)
    Q = process_noise_covariance(W, time_step)
    P_pred = symmetrise(np.asarray(P0, dtype=float).reshape(6, 6))
    covs = np.empty((qs.shape[0], 6, 6))
    eye = np.eye(6)
    for k in range(qs.shape[0]):
        if k > 0:
            P_pred = symmetrise(A @ covs[k - 1] @ A.T + Q)
        if not both[k]:
            covs[k] = P_pred
            continue
        C = np.zeros((1, 6))
        C[0, :3] = qs[k]
        S = float((C @ P_pred @ C.T)[0, 0]) + Gamma[k]
        K = P_pred @ C.T / S
        I_KC = eye - K @ C
        covs[k] = symmetrise(I_KC @ P_pred @ I_KC.T + Gamma[k] * (K @ K.T))
    return covs


def bound_rmse(covs: np.ndarray, start: int) -> tuple[float, float]:
    """``(position_rmse, velocity_rmse)`` = sqrt of the mean over ``k ≥ start`` of the traces
    of the 3×3 position and velocity blocks of ``covs`` (N×6×6).

    Compare with an estimator's ``sqrt(mean over runs and k ≥ start of |x̂ − x|²)``.
    """
    position, velocity = bound_rmse_runs(np.asarray(covs, dtype=float)[np.newaxis], start)
    return float(position[0]), float(velocity[0])


def bound_rmse_runs(covs: np.ndarray, start: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`bound_rmse` of each run's covariances (…×N×6×6 → two … arrays), along each
    run's own steps."""
    covs = np.asarray(covs, dtype=float)
    if not 0 <= start < covs.shape[-3]:
        raise ValueError(f"start must be in [0, {covs.shape[-3]}), got {start}")
    tail = covs[..., start:, :, :]
    position = np.trace(tail[..., :3, :3], axis1=-2, axis2=-1).mean(axis=-1)
    velocity = np.trace(tail[..., 3:, 3:], axis1=-2, axis2=-1).mean(axis=-1)
    return np.sqrt(position), np.sqrt(velocity)
