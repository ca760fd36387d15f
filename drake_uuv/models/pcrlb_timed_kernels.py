"""The compiled recursion of :func:`~drake_uuv.models.pcrlb_timed.pcrlb_timed`, run by run.

Why a kernel: the recursion is sequential in the steps and each step is a handful of 6×6 and
9×9 operations, so numpy pays its cost per call (~µs) hundreds of times a step for a few
hundred flops; batched over runs it would also carry every run's per-step information
through memory several times. Here one compiled loop goes over the runs, and for each run
over its steps, with the inverses of symmetric positive definite matrices by Cholesky
written out (exactly symmetric, as :func:`~drake_uuv.models.pcrlb._pcrlb_kernel` does for
the plain bound). Each run's arithmetic is its own (its own window ``D`` too), so its bits do
not depend on the batch; a run whose matrix to invert is not positive definite (NaN in its
trajectory) is NaN from that step on and leaves the others.
"""

import numpy as np
from numba import njit


@njit(cache=True)
def spd_inverse(
    S: np.ndarray, n: int, out: np.ndarray, L: np.ndarray, L_inv: np.ndarray, d_inv: np.ndarray
) -> None:
    """``S⁻¹`` of the leading n×n block of a symmetric ``S`` (lower triangle read) into
    ``out``, by Cholesky, ``L⁻ᵀ L⁻¹`` (exactly symmetric); not positive definite (a pivot not
    > 0, or NaN) gives a NaN pivot, which makes the whole inverse NaN. ``L``, ``L_inv``
    (≥ n×n) and ``d_inv`` (≥ n) are scratch."""
    for j in range(n):
        d = S[j, j]
        for m in range(j):
            d -= L[j, m] * L[j, m]
        d = np.sqrt(d) if d > 0.0 else np.nan
        L[j, j] = d
        d_inv[j] = 1.0 / d
        for i in range(j + 1, n):
            v = S[i, j]
            for m in range(j):
                v -= L[i, m] * L[j, m]
            L[i, j] = v * d_inv[j]
    for j in range(n):
        L_inv[j, j] = d_inv[j]
        for i in range(j + 1, n):
            v = 0.0
            for m in range(j, i):
                v -= L[i, m] * L_inv[m, j]
            L_inv[i, j] = v * d_inv[i]
    for i in range(n):
        for j in range(i + 1):
            v = 0.0
            for m in range(i, n):
                v += L_inv[m, i] * L_inv[m, j]
            out[i, j] = v
            out[j, i] = v


@njit(cache=True)
def _step_information(
    rows: np.ndarray,
    noise: np.ndarray,
    counted0: bool,
    counted1: bool,
    size: int,
    out: np.ndarray,
) -> None:
    """``Hᵀ R⁻¹ H`` (its leading size×size block) of the step's counted pings into ``out``:
    rows ``h_i`` (2×9), ``R`` (2×2) their noise, marginalised to the pings counted."""
    if counted0 and counted1:
        det = noise[0, 0] * noise[1, 1] - noise[0, 1] * noise[1, 0]
        r00, r11 = noise[1, 1] / det, noise[0, 0] / det
        r01, r10 = -noise[0, 1] / det, -noise[1, 0] / det
        for a in range(size):
            g0 = r00 * rows[0, a] + r10 * rows[1, a]  # (R⁻¹ H)ᵀ's row a
            g1 = r01 * rows[0, a] + r11 * rows[1, a]
            for b in range(a + 1):
                v = g0 * rows[0, b] + g1 * rows[1, b]
                out[a, b] = v
                out[b, a] = v
    elif counted0 or counted1:
        i = 0 if counted0 else 1
        w = 1.0 / noise[i, i]
        for a in range(size):
            wa = w * rows[i, a]
            for b in range(a + 1):
                v = wa * rows[i, b]
                out[a, b] = v
                out[b, a] = v
    else:
        for a in range(size):
            for b in range(size):
                out[a, b] = 0.0


@njit(cache=True)
def _advance(
    P: np.ndarray,
    W: np.ndarray,
    Qp: np.ndarray,
    rows: np.ndarray,
    noise: np.ndarray,
    counted0: bool,
    counted1: bool,
    g: np.ndarray,
    out: np.ndarray,
    J: np.ndarray,
    Z: np.ndarray,
    L: np.ndarray,
    L_inv: np.ndarray,
    d_inv: np.ndarray,
) -> None:
    """``P⁻_{k+1} = G(t) P_z G(t)ᵀ + Qp`` with ``P_z = (blkdiag(P⁻_k⁻¹, W⁻¹) + Hᵀ R⁻¹ H)⁻¹``
    over the counted pings, into ``out`` (6×6). ``g`` (2×3) holds ``G``'s block weights:
    ``G = [[g00 I, g01 I, g02 I], [g10 I, g11 I, g12 I]]``."""
    _step_information(rows, noise, counted0, counted1, 9, J)
    spd_inverse(P, 6, Z, L, L_inv, d_inv)
    for i in range(6):
        for j in range(6):
            J[i, j] += Z[i, j]
    spd_inverse(W, 3, Z, L, L_inv, d_inv)
    for i in range(3):
        for j in range(3):
            J[6 + i, 6 + j] += Z[i, j]
    spd_inverse(J, 9, Z, L, L_inv, d_inv)
    for a in range(2):
        for b in range(a + 1):
            for i in range(3):
                for j in range(3):
                    v = 0.0
                    for c in range(3):
                        for e in range(3):
                            v += g[a, c] * g[b, e] * Z[3 * c + i, 3 * e + j]
                    out[3 * a + i, 3 * b + j] = v
    for i in range(3):  # the upper right block, and the position noise: exactly symmetric
        for j in range(3):
            out[i, 3 + j] = out[3 + j, i]
    for i in range(6):
        for j in range(i + 1):
            v = 0.5 * (out[i, j] + out[j, i])
            if i < 3:
                v += 0.5 * (Qp[i, j] + Qp[j, i])
            out[i, j] = v
            out[j, i] = v


@njit(cache=True)
def timed_bound_kernel(
    rows: np.ndarray,
    noise: np.ndarray,
    present: np.ndarray,
    lags: np.ndarray,
    windows: np.ndarray,
    P0: np.ndarray,
    W: np.ndarray,
    Qp: np.ndarray,
    t: float,
    out: np.ndarray,
) -> None:
    """:func:`~drake_uuv.models.pcrlb_timed.pcrlb_timed` of each run (R runs of N steps) into
    ``out`` (R×N×6×6): ``rows`` (R×N×2×9) the pings' rows on ``z = [x_k, ū_k]`` (zero where
    absent), ``noise`` (R×N×2×2), ``present`` (R×N×2) whether a range of the ping ever
    arrives, ``lags`` (R×N×2) its arrival tick minus k, ``windows`` (R) the run's ``D``,
    ``P0`` (6×6, symmetric), ``W`` and ``Qp`` (R×N×3×3) each step's acceleration and position
    noise covariances.

    The complete recursion (all of each step's pings) gives ``P⁻_k`` for every k; tick j
    starts from the complete ``P⁻_{j−D+1}`` (step ``j − D`` is complete at j) and
    fast-forwards through steps ``j − D + 1 .. j − 1`` with the pings of lag ``≤ j − k``, then
    takes the tick's own pings at ``τ = 0`` that arrive at once."""
    runs, steps = rows.shape[0], rows.shape[1]
    g = np.array([[1.0, t, -0.5 * t * t], [0.0, 1.0, -t]])
    complete = np.empty((steps, 6, 6))
    P = np.empty((6, 6))
    nxt = np.empty((6, 6))
    J = np.empty((9, 9))
    Z = np.empty((9, 9))
    L = np.empty((9, 9))
    L_inv = np.empty((9, 9))
    d_inv = np.empty(9)
    for r in range(runs):
        D = windows[r]
        complete[0] = P0
        for k in range(steps - 1):
            _advance(
                complete[k], W[r, k], Qp[r, k], rows[r, k], noise[r, k],
                present[r, k, 0], present[r, k, 1], g, complete[k + 1], J, Z, L, L_inv, d_inv,
            )  # fmt: skip
        for j in range(steps):
            first = min(max(j - D + 1, 0), j)
            P[:] = complete[first]
            for k in range(first, j):
                ell = j - k
                _advance(
                    P, W[r, k], Qp[r, k], rows[r, k], noise[r, k],
                    present[r, k, 0] and lags[r, k, 0] <= ell,
                    present[r, k, 1] and lags[r, k, 1] <= ell,
                    g, nxt, J, Z, L, L_inv, d_inv,
                )  # fmt: skip
                P[:] = nxt
            # the tick's own pings (τ = 0, lag 0): their rows' x_k block
            _step_information(
                rows[r, j], noise[r, j],
                present[r, j, 0] and lags[r, j, 0] == 0,
                present[r, j, 1] and lags[r, j, 1] == 0,
                6, J,
            )  # fmt: skip
            spd_inverse(P, 6, Z, L, L_inv, d_inv)
            for i in range(6):
                for m in range(6):
                    J[i, m] += Z[i, m]
            spd_inverse(J, 6, out[r, j], L, L_inv, d_inv)
