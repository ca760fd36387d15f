"""The linear filter steps over a batch of runs: numba kernels that loop over a leading run axis.

The prediction, the paper's KF on ``Y`` (its noise, measurement and update), the prior's share
of the hand-over and the late ranges' update through a step; the Gaussian updates on the raw
ranges (EKF, iterated EKF, UKF) are :mod:`drake_uuv.models.raw_range_runs`', whose kernels
call this file's linear-algebra helpers.

An estimator steps B independent runs at once. Each step is a handful of 6×6 products per
run: numpy's cost per call would dominate at B = 1 and its many passes over (B, 6, 6) arrays
at B = 1000, so each step is one compiled loop over the runs (``cache=True``: compiled once,
kept between processes). A run's arithmetic never reads another run, so its numbers are the
same bits whatever its batch. A run whose numbers are NaN or infinite stays so and raises
nothing (``error_model="numpy"``; a failed Cholesky factor gives NaN).

Every update takes ``mask`` (B,): the runs to update; the others keep their prior and get a
NaN NIS. ``Q`` is one matrix for all runs (shape (1, n, n)) or one per run.
"""

import numpy as np
from numba import njit

_NOISE_MODELS = {"derived": 0, "paper_printed": 1}


def noise_model_code(noise_model: str) -> int:
    """The kernels' code of a noise model of ``Y`` (one-line error naming it otherwise)."""
    if noise_model not in _NOISE_MODELS:
        raise ValueError(
            f"estimator.noise_model: must be derived or paper_printed, got {noise_model!r}"
        )
    return _NOISE_MODELS[noise_model]


# --------------------------------------------------------------------------- small helpers


@njit(cache=True, error_model="numpy")
def _symmetrised_into(M, out):
    for i in range(6):
        out[i, i] = M[i, i]
        for j in range(i + 1, 6):
            value = 0.5 * (M[i, j] + M[j, i])
            out[i, j] = value
            out[j, i] = value


@njit(cache=True, error_model="numpy")
def _cholesky6(P, L):
    """Lower factor of ``P`` into ``L``; NaN where ``P`` is not positive definite."""
    for i in range(6):
        for j in range(6):
            L[i, j] = 0.0
    for j in range(6):
        s = P[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        if not s > 0.0:
            for a in range(6):
                for b in range(6):
                    L[a, b] = np.nan
            return False
        d = np.sqrt(s)
        L[j, j] = d
        for i in range(j + 1, 6):
            s = P[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            L[i, j] = s / d
    return True


@njit(cache=True, error_model="numpy")
def _forward(L, v, out):
    """``L⁻¹ v`` for lower-triangular ``L`` (6)."""
    for i in range(6):
        s = v[i]
        for k in range(i):
            s -= L[i, k] * out[k]
        out[i] = s / L[i, i]


@njit(cache=True, error_model="numpy")
def _backward(L, v, out):
    """``L⁻ᵀ v`` for lower-triangular ``L`` (6)."""
    for i in range(5, -1, -1):
        s = v[i]
        for k in range(i + 1, 6):
            s -= L[k, i] * out[k]
        out[i] = s / L[i, i]


@njit(cache=True, error_model="numpy")
def _inverse_small(S, m, Sinv):
    """``S⁻¹`` of the leading m×m block (m = 1 or 2) into ``Sinv``."""
    if m == 1:
        Sinv[0, 0] = 1.0 / S[0, 0]
        return
    det = S[0, 0] * S[1, 1] - S[0, 1] * S[1, 0]
    Sinv[0, 0] = S[1, 1] / det
    Sinv[1, 1] = S[0, 0] / det
    Sinv[0, 1] = -S[0, 1] / det
    Sinv[1, 0] = -S[1, 0] / det


@njit(cache=True, error_model="numpy")
def _joseph_into(P, K, H, Rm, m, out):
    """``(I − K H) P (I − K H)ᵀ + K R Kᵀ``, symmetrised, into ``out``; ``K`` 6×m, ``H`` m×6."""
    T = np.empty((6, 6))
    for i in range(6):
        for j in range(6):
            s = 1.0 if i == j else 0.0
            for a in range(m):
                s -= K[i, a] * H[a, j]
            T[i, j] = s
    TP = np.empty((6, 6))
    for i in range(6):
        for j in range(6):
            s = 0.0
            for k in range(6):
                s += T[i, k] * P[k, j]
            TP[i, j] = s
    KR = np.empty((6, 2))
    for i in range(6):
        for b in range(m):
            s = 0.0
            for a in range(m):
                s += K[i, a] * Rm[a, b]
            KR[i, b] = s
    M = np.empty((6, 6))
    for i in range(6):
        for j in range(6):
            s = 0.0
            for k in range(6):
                s += TP[i, k] * T[j, k]
            for b in range(m):
                s += KR[i, b] * K[j, b]
            M[i, j] = s
    _symmetrised_into(M, out)


@njit(cache=True, error_model="numpy")
def _rows(use, r, rows):
    m = 0
    for i in range(2):
        if use[r, i]:
            rows[m] = i
            m += 1
    return m


# ------------------------------------------------------------------------------ prediction


@njit(cache=True, error_model="numpy")
def _predict(x, P, a, A, Bm, Q, x_out, P_out):
    AP = np.empty((6, 6))
    M = np.empty((6, 6))
    shared = Q.shape[0] == 1
    for r in range(x.shape[0]):
        q = 0 if shared else r
        for i in range(6):
            s = 0.0
            for j in range(6):
                s += A[i, j] * x[r, j]
            for j in range(3):
                s += Bm[i, j] * a[r, j]
            x_out[r, i] = s
        for i in range(6):
            for j in range(6):
                s = 0.0
                for k in range(6):
                    s += A[i, k] * P[r, k, j]
                AP[i, j] = s
        for i in range(6):
            for j in range(6):
                s = 0.0
                for k in range(6):
                    s += AP[i, k] * A[j, k]
                M[i, j] = s + Q[q, i, j]
        _symmetrised_into(M, P_out[r])


def predict_runs(
    x: np.ndarray, P: np.ndarray, a: np.ndarray, A: np.ndarray, B: np.ndarray, Q: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``A x + B a`` and ``A P Aᵀ + Q`` (symmetrised) of each run: ``x`` (B, 6), ``P``
    (B, 6, 6), ``a`` (B, 3); ``Q`` (6, 6) for all runs or (B, 6, 6)."""
    x_out = np.empty(x.shape)
    P_out = np.empty(P.shape)
    _predict(x, P, a, A, B, Q.reshape(-1, 6, 6), x_out, P_out)
    return x_out, P_out


@njit(cache=True, error_model="numpy")
def _congruence(S, A, mask, out):
    """``A S Aᵀ`` (no process noise) of the runs in ``mask``; the others' ``S`` unchanged."""
    AS = np.empty((6, 6))
    for r in range(S.shape[0]):
        if not mask[r]:
            out[r] = S[r]
            continue
        for i in range(6):
            for j in range(6):
                s = 0.0
                for k in range(6):
                    s += A[i, k] * S[r, k, j]
                AS[i, j] = s
        for i in range(6):
            for j in range(6):
                s = 0.0
                for k in range(6):
                    s += AS[i, k] * A[j, k]
                out[r, i, j] = s


def congruence_runs(S: np.ndarray, A: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """``A S Aᵀ`` of the runs in ``mask`` (B,), the others' ``S`` (B, 6, 6) unchanged."""
    out = np.empty(S.shape)
    _congruence(S, A, mask, out)
    return out


# ------------------------------------------------------------------- the paper's Y update


@njit(cache=True, error_model="numpy")
def _clip(v):
    return v if (v > 0.0 or v != v) else 0.0


@njit(cache=True, error_model="numpy")
def _difference_noise(model, eta, ms, m_out, gamma_out):
    for r in range(eta.shape[0]):
        e1, e2 = eta[r, 0], eta[r, 1]
        if model == 0:
            m_out[r] = 0.5 * (e1 - e2)
            gamma_out[r] = (
                e1 * _clip(ms[r, 0] - e1) + e2 * _clip(ms[r, 1] - e2) + 0.5 * (e1 * e1 + e2 * e2)
            )
        else:
            m_out[r] = e1 + e2
            gamma_out[r] = (
                2.0 * e1 * e1 + 2.0 * e2 * e2 + 4.0 * (ms[r, 0] - e1) * e1
                + 4.0 * (ms[r, 1] - e2) * e2
            )  # fmt: skip


def range_difference_noise_runs(
    model: int, eta: np.ndarray, mean_squared_ranges: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``(m, Γ)`` (B each) of :func:`~drake_uuv.models.measurement.range_difference_noise`
    per run: ``eta`` (B, 2) the variances, ``mean_squared_ranges`` (B, 2), ``model`` from
    :func:`noise_model_code`."""
    B = eta.shape[0]
    m, gamma = np.empty(B), np.empty(B)
    _difference_noise(model, eta, mean_squared_ranges, m, gamma)
    return m, gamma


@njit(cache=True, error_model="numpy")
def _paper_measurement(samples, eta, model, Y, ms):
    f = samples.shape[2]
    for r in range(samples.shape[0]):
        d1, d2 = samples[r, 0, 0], samples[r, 1, 0]
        Y[r] = 0.5 * (d1 * d1 - d2 * d2)
        for i in range(2):
            s = 0.0
            for j in range(f):
                s += samples[r, i, j] * samples[r, i, j]
            ms[r, i] = s / f


def paper_measurement_runs(
    samples: np.ndarray, eta: np.ndarray, model: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The paper's ``(Y, m, Γ)`` (B each) of each run's samples (B, 2, f) and variances
    ``eta`` (B, 2): :func:`~drake_uuv.models.measurement.paper_measurement` per run."""
    B = samples.shape[0]
    Y, ms = np.empty(B), np.empty((B, 2))
    _paper_measurement(samples, eta, model, Y, ms)
    m, gamma = range_difference_noise_runs(model, eta, ms)
    return Y, m, gamma


@njit(cache=True, error_model="numpy")
def _range_difference_update(x, P, Y, m, gamma, q_s, mask, x_out, P_out, nis_out):
    PC = np.empty(6)  # P Cᵀ
    CP = np.empty(6)  # C P
    T = np.empty((6, 6))
    M = np.empty((6, 6))
    for r in range(x.shape[0]):
        if not mask[r]:
            x_out[r] = x[r]
            P_out[r] = P[r]
            nis_out[r] = np.nan
            continue
        c0, c1, c2 = q_s[r, 0], q_s[r, 1], q_s[r, 2]
        for i in range(6):
            PC[i] = P[r, i, 0] * c0 + P[r, i, 1] * c1 + P[r, i, 2] * c2
            CP[i] = c0 * P[r, 0, i] + c1 * P[r, 1, i] + c2 * P[r, 2, i]
        S = c0 * PC[0] + c1 * PC[1] + c2 * PC[2] + gamma[r]
        innovation = Y[r] - (c0 * x[r, 0] + c1 * x[r, 1] + c2 * x[r, 2]) - m[r]
        # (I − K C) P = P − K (C P); then ·(I − K C)ᵀ = T − (T Cᵀ) Kᵀ; plus Γ K Kᵀ.
        for i in range(6):
            k = PC[i] / S
            x_out[r, i] = x[r, i] + k * innovation
            for j in range(6):
                T[i, j] = P[r, i, j] - k * CP[j]
        for i in range(6):
            tc = T[i, 0] * c0 + T[i, 1] * c1 + T[i, 2] * c2
            ki = PC[i] / S
            for j in range(6):
                kj = PC[j] / S
                M[i, j] = T[i, j] - tc * kj + gamma[r] * ki * kj
        _symmetrised_into(M, P_out[r])
        nis_out[r] = innovation * innovation / S


def range_difference_update_runs(
    x: np.ndarray,
    P: np.ndarray,
    Y: np.ndarray,
    m: np.ndarray,
    gamma: np.ndarray,
    q_s: np.ndarray,
    mask: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The paper's KF update (eq. 9, Joseph form) of each run in ``mask``:
    :func:`~drake_uuv.models.filters.range_difference_update` with ``x`` (B, 6), ``P``
    (B, 6, 6), ``Y``, ``m``, ``Γ`` (B), ``q_s`` (B, 3). Returns ``(x, P, nis)``."""
    x_out, P_out, nis = np.empty(x.shape), np.empty(P.shape), np.empty(x.shape[0])
    _range_difference_update(x, P, Y, m, gamma, q_s, mask, x_out, P_out, nis)
    return x_out, P_out, nis


@njit(cache=True, error_model="numpy")
def _prior_share_update(S, P, q_s, gamma, mask, out):
    T = np.empty((6, 6))
    K = np.empty(6)
    for r in range(S.shape[0]):
        if not mask[r]:
            out[r] = S[r]
            continue
        c0, c1, c2 = q_s[r, 0], q_s[r, 1], q_s[r, 2]
        for i in range(6):
            K[i] = (P[r, i, 0] * c0 + P[r, i, 1] * c1 + P[r, i, 2] * c2) / gamma[r]
        for i in range(6):
            for j in range(6):
                cs = c0 * S[r, 0, j] + c1 * S[r, 1, j] + c2 * S[r, 2, j]
                T[i, j] = S[r, i, j] - K[i] * cs
        M = np.empty((6, 6))
        for i in range(6):
            tc = T[i, 0] * c0 + T[i, 1] * c1 + T[i, 2] * c2
            for j in range(6):
                M[i, j] = T[i, j] - tc * K[j]
        _symmetrised_into(M, out[r])


def prior_share_update_runs(
    S: np.ndarray, P: np.ndarray, q_s: np.ndarray, gamma: np.ndarray, mask: np.ndarray
) -> np.ndarray:
    """:func:`~drake_uuv.models.handover_measures.prior_share_update` of each run in ``mask``."""
    out = np.empty(S.shape)
    _prior_share_update(S, P, q_s, gamma, mask, out)
    return out


# ----------------------------------------------------------- late ranges: a step's update


@njit(cache=True, error_model="numpy")
def _update_through(z, P_z, G, y_prior, y_post, P_y_post, mask, z_out, P_out):
    PzG = np.empty((9, 6))
    Py = np.empty((6, 6))
    L = np.empty((6, 6))
    K = np.empty((9, 6))
    col, tmp, sol = np.empty(6), np.empty(6), np.empty(6)
    T = np.empty((9, 9))
    TP = np.empty((9, 9))
    KP = np.empty((9, 6))
    M = np.empty((9, 9))
    for r in range(z.shape[0]):
        if not mask[r]:
            z_out[r] = z[r]
            P_out[r] = P_z[r]
            continue
        for i in range(9):
            for j in range(6):
                s = 0.0
                for k in range(9):
                    s += P_z[r, i, k] * G[r, j, k]
                PzG[i, j] = s
        for i in range(6):
            for j in range(6):
                s = 0.0
                for k in range(9):
                    s += G[r, i, k] * PzG[k, j]
                Py[i, j] = s
        _cholesky6(Py, L)
        for i in range(9):  # row i of K solves P_y kᵢ = (P_z Gᵀ)ᵢ (P_y symmetric)
            for j in range(6):
                col[j] = PzG[i, j]
            _forward(L, col, tmp)
            _backward(L, tmp, sol)
            for j in range(6):
                K[i, j] = sol[j]
        for i in range(9):
            s = z[r, i]
            for j in range(6):
                s += K[i, j] * (y_post[r, j] - y_prior[r, j])
            z_out[r, i] = s
        for i in range(9):
            for j in range(9):
                s = 1.0 if i == j else 0.0
                for k in range(6):
                    s -= K[i, k] * G[r, k, j]
                T[i, j] = s
        for i in range(9):
            for j in range(9):
                s = 0.0
                for k in range(9):
                    s += T[i, k] * P_z[r, k, j]
                TP[i, j] = s
            for j in range(6):
                s = 0.0
                for k in range(6):
                    s += K[i, k] * P_y_post[r, k, j]
                KP[i, j] = s
        for i in range(9):
            for j in range(9):
                s = 0.0
                for k in range(9):
                    s += TP[i, k] * T[j, k]
                for k in range(6):
                    s += KP[i, k] * K[j, k]
                M[i, j] = s
        for i in range(9):
            P_out[r, i, i] = M[i, i]
            for j in range(i + 1, 9):
                value = 0.5 * (M[i, j] + M[j, i])
                P_out[r, i, j] = value
                P_out[r, j, i] = value


def update_through_runs(
    z: np.ndarray,
    P_z: np.ndarray,
    G: np.ndarray,
    y_prior: np.ndarray,
    y_posterior: np.ndarray,
    P_y_posterior: np.ndarray,
    mask: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`~drake_uuv.models.timing.update_through` of each run in ``mask``: ``z`` (B, 9),
    ``P_z`` (B, 9, 9), ``G`` (B, 6, 9), ``y`` (B, 6), ``P_y⁺`` (B, 6, 6); the others keep
    theirs."""
    z_out, P_out = np.empty(z.shape), np.empty(P_z.shape)
    _update_through(z, P_z, G, y_prior, y_posterior, P_y_posterior, mask, z_out, P_out)
    return z_out, P_out
