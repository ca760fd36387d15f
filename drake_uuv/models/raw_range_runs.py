"""The Gaussian updates on the raw ranges over a batch of runs: EKF, iterated EKF and UKF.

The batched counterparts of :func:`~drake_uuv.models.filters.ekf_update`,
:func:`~drake_uuv.models.filters.iekf_update` and
:func:`~drake_uuv.models.unscented.ukf_range_update` (:func:`range_update_runs` picks one for
a :data:`~drake_uuv.models.filters.RangeUpdate`): numba kernels that loop over a leading run
axis, as those of :mod:`drake_uuv.models.filter_runs`, whose conventions they keep (a run's
numbers the same bits whatever its batch; NaN and inf raise nothing; ``mask`` (B,) the runs to
update, the others keeping their prior with a NaN NIS; ``use`` (B, 2) the sonars each run's
update uses; ``R`` one (1, 2, 2) for all runs or one per run).

The kernels call the small linear-algebra helpers of :mod:`drake_uuv.models.filter_runs`
(the Cholesky factor, its triangular solves, the 2×2 inverse, the Joseph form, the rows a run
uses): numba's cache does not notice a change in a compiled function that another file's
kernel calls, so after changing those helpers in ``filter_runs.py`` delete this file's cache
(``drake_uuv/models/__pycache__/raw_range_runs.*.nb[ci]``).
"""

import functools
from collections.abc import Callable

import numpy as np
from numba import njit

from drake_uuv.models.filter_runs import (
    _backward,
    _cholesky6,
    _forward,
    _inverse_small,
    _joseph_into,
    _rows,
)
from drake_uuv.models.measurement import MIN_RANGE


@njit(cache=True, error_model="numpy")
def _ranges_and_rows(x, q_s, r, rows, m, h, H):
    """The selected ranges ``h`` (m) and Jacobian rows ``H`` (m×6) of run r at ``x`` (6)."""
    for a in range(m):
        sign = 0.5 if rows[a] == 0 else -0.5
        v0 = x[0] + sign * q_s[r, 0]
        v1 = x[1] + sign * q_s[r, 1]
        v2 = x[2] + sign * q_s[r, 2]
        d = np.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
        h[a] = d
        scale = d if d > MIN_RANGE else MIN_RANGE
        H[a, 0], H[a, 1], H[a, 2] = v0 / scale, v1 / scale, v2 / scale
        H[a, 3] = H[a, 4] = H[a, 5] = 0.0


@njit(cache=True, error_model="numpy")
def _gain(P, H, Rm, m, S, Sinv, K):
    """``S = H P Hᵀ + R`` and ``K = P Hᵀ S⁻¹`` (``S⁻¹`` into ``Sinv``)."""
    HP = np.empty((2, 6))
    for a in range(m):
        for j in range(6):
            s = 0.0
            for k in range(3):
                s += H[a, k] * P[k, j]
            HP[a, j] = s
    for a in range(m):
        for b in range(m):
            s = 0.0
            for k in range(3):
                s += HP[a, k] * H[b, k]
            S[a, b] = s + Rm[a, b]
    _inverse_small(S, m, Sinv)
    for i in range(6):
        for a in range(m):
            s = 0.0
            for b in range(m):
                s += HP[b, i] * Sinv[b, a]
            K[i, a] = s


@njit(cache=True, error_model="numpy")
def _select_R(R, r, rows, m, Rm):
    q = 0 if R.shape[0] == 1 else r
    for a in range(m):
        for b in range(m):
            Rm[a, b] = R[q, rows[a], rows[b]]


@njit(cache=True, error_model="numpy")
def _quadratic(nu, Sinv, m):
    s = 0.0
    for a in range(m):
        for b in range(m):
            s += nu[a] * Sinv[a, b] * nu[b]
    return s


#: The second-order terms an EKF may keep (bits of ``order``): the range's mean
#: ``½ tr(H''P)`` and its variance ``½ tr(H''P H''P)``.
SECOND_ORDER_MEAN, SECOND_ORDER_VARIANCE = 1, 2
SECOND_ORDER_CODES = {"none": 0, "mean": 1, "variance": 2, "full": 3}


@njit(cache=True, error_model="numpy")
def _second_order(P, H, h, m, order, scale, Rm):
    """Gelb's second-order terms of the ranges (Hessian ``(I − u uᵀ)/d`` on ``q``, ``u = H``'s
    row): the mean ``tr(P⊥)/(2d)`` added to ``h`` and, between ranges a and b,
    ``½ tr(M_a P M_b P)/(d_a d_b)`` (the variance of ``½ eᵀ H'' e`` for Gaussian ``e``) times
    ``scale`` (the error's correlation in steps) added to ``Rm``."""
    Mp = np.empty((2, 3, 3))  # (I − u uᵀ) P_qq of each range
    d = np.empty(2)  # the ranges at the estimate, before the mean term is added
    for a in range(m):
        d[a] = h[a] if h[a] > MIN_RANGE else MIN_RANGE
    for a in range(m):
        for i in range(3):
            for j in range(3):
                s = P[i, j]
                for k in range(3):
                    s -= H[a, i] * H[a, k] * P[k, j]
                Mp[a, i, j] = s
    for a in range(m):
        if order & 2:
            for b in range(m):
                s = 0.0
                for i in range(3):
                    for j in range(3):
                        s += Mp[a, i, j] * Mp[b, j, i]
                Rm[a, b] += scale * 0.5 * s / (d[a] * d[b])
        if order & 1:
            h[a] += 0.5 * (Mp[a, 0, 0] + Mp[a, 1, 1] + Mp[a, 2, 2]) / d[a]


@njit(cache=True, error_model="numpy")
def _ekf(x, P, z, q_s, R, use, mask, order, scale, x_out, P_out, nis_out):
    rows = np.empty(2, np.int64)
    h, nu = np.empty(2), np.empty(2)
    H, Rm, S, Sinv = np.empty((2, 6)), np.empty((2, 2)), np.empty((2, 2)), np.empty((2, 2))
    K = np.empty((6, 2))
    for r in range(x.shape[0]):
        m = _rows(use, r, rows)
        if not mask[r] or m == 0:
            x_out[r] = x[r]
            P_out[r] = P[r]
            nis_out[r] = np.nan
            continue
        _ranges_and_rows(x[r], q_s, r, rows, m, h, H)
        _select_R(R, r, rows, m, Rm)
        if order != 0:
            _second_order(P[r], H, h, m, order, scale, Rm)
        for a in range(m):
            nu[a] = z[r, rows[a]] - h[a]
        _gain(P[r], H, Rm, m, S, Sinv, K)
        for i in range(6):
            s = x[r, i]
            for a in range(m):
                s += K[i, a] * nu[a]
            x_out[r, i] = s
        _joseph_into(P[r], K, H, Rm, m, P_out[r])
        nis_out[r] = _quadratic(nu, Sinv, m)


@njit(cache=True, error_model="numpy")
def _iekf_cost(x, x_pred, L, z, q_s, r, rows, m, Rinv, h, H, e, d):
    _ranges_and_rows(x, q_s, r, rows, m, h, H)
    res = np.empty(2)
    for a in range(m):
        res[a] = z[r, rows[a]] - h[a]
    for i in range(6):
        d[i] = x[i] - x_pred[i]
    _forward(L, d, e)
    c = 0.0
    for i in range(6):
        c += e[i] * e[i]
    return 0.5 * _quadratic(res, Rinv, m) + 0.5 * c


@njit(cache=True, error_model="numpy")
def _iekf(
    x, P, z, q_s, R, use, mask, max_iterations, tolerance, max_halvings, x_out, P_out, nis_out
):
    rows = np.empty(2, np.int64)
    h, nu = np.empty(2), np.empty(2)
    H, Rm, Rinv = np.empty((2, 6)), np.empty((2, 2)), np.empty((2, 2))
    S, Sinv = np.empty((2, 2)), np.empty((2, 2))
    K = np.empty((6, 2))
    L = np.empty((6, 6))
    xi, step, trial = np.empty(6), np.empty(6), np.empty(6)
    e, d, w = np.empty(6), np.empty(6), np.empty(6)
    for r in range(x.shape[0]):
        m = _rows(use, r, rows)
        if not mask[r] or m == 0:
            x_out[r] = x[r]
            P_out[r] = P[r]
            nis_out[r] = np.nan
            continue
        xp = x[r]
        Pr = P[r]
        _cholesky6(Pr, L)
        _select_R(R, r, rows, m, Rm)
        _inverse_small(Rm, m, Rinv)
        _ranges_and_rows(xp, q_s, r, rows, m, h, H)
        for a in range(m):
            nu[a] = z[r, rows[a]] - h[a]
        _gain(Pr, H, Rm, m, S, Sinv, K)
        nis_out[r] = _quadratic(nu, Sinv, m)
        for i in range(6):
            xi[i] = xp[i]
        c = _iekf_cost(xi, xp, L, z, q_s, r, rows, m, Rinv, h, H, e, d)
        for _ in range(max(max_iterations, 1)):
            _ranges_and_rows(xi, q_s, r, rows, m, h, H)
            _gain(Pr, H, Rm, m, S, Sinv, K)
            # step = x_pred + K (z − h(x) − H (x_pred − x)) − x
            for a in range(m):
                s = z[r, rows[a]] - h[a]
                for k in range(3):
                    s -= H[a, k] * (xp[k] - xi[k])
                nu[a] = s
            for i in range(6):
                s = xp[i]
                for a in range(m):
                    s += K[i, a] * nu[a]
                step[i] = s - xi[i]
            scale = 1.0
            descended = False
            c_try = c
            for _ in range(max_halvings + 1):
                for i in range(6):
                    trial[i] = xi[i] + scale * step[i]
                c_try = _iekf_cost(trial, xp, L, z, q_s, r, rows, m, Rinv, h, H, e, d)
                if c_try <= c:
                    descended = True
                    break
                scale *= 0.5
            if not descended:
                break  # no descent along the Gauss–Newton direction: x is (numerically) optimal
            for i in range(6):
                xi[i] = xi[i] + scale * step[i]
                w[i] = scale * step[i]
            c = c_try
            _forward(L, w, e)
            norm = 0.0
            for i in range(6):
                norm += e[i] * e[i]
            if np.sqrt(norm) < tolerance:
                break
        _ranges_and_rows(xi, q_s, r, rows, m, h, H)
        _gain(Pr, H, Rm, m, S, Sinv, K)
        x_out[r] = xi
        _joseph_into(Pr, K, H, Rm, m, P_out[r])


@njit(cache=True, error_model="numpy")
def _sigma_points(xr, L, root, pts):
    """The 13 sigma points of ``N(xr, L Lᵀ)``: ``xr``, then ``xr ± root·L[:, p]``."""
    for i in range(6):
        pts[0, i] = xr[i]
    for p in range(6):  # column p of L: points 1 + p and 7 + p
        for i in range(6):
            off = root * L[i, p]
            pts[1 + p, i] = xr[i] + off
            pts[7 + p, i] = xr[i] - off


@njit(cache=True, error_model="numpy")
def _point_ranges(pts, q_s, r, rows, m, Z):
    """The selected ranges ``Z`` (13×m) of run r's sigma points (a negative square: 0)."""
    qq = 0.25 * (q_s[r, 0] * q_s[r, 0] + q_s[r, 1] * q_s[r, 1] + q_s[r, 2] * q_s[r, 2])
    for p in range(13):
        sq = pts[p, 0] * pts[p, 0] + pts[p, 1] * pts[p, 1] + pts[p, 2] * pts[p, 2] + qq
        pr = q_s[r, 0] * pts[p, 0] + q_s[r, 1] * pts[p, 1] + q_s[r, 2] * pts[p, 2]
        for a in range(m):
            v = sq + pr if rows[a] == 0 else sq - pr
            Z[p, a] = np.sqrt(v if v > 0.0 or v != v else 0.0)


@njit(cache=True, error_model="numpy")
def _unscented_moments(Z, pts, xr, z, r, rows, m, Rm, Wm0, Wi, Wc0, z_hat, nu, S, Pxz):
    """The predicted ranges ``z_hat``, innovations ``nu``, ``S`` (with ``Rm``) and ``P_xz``
    of the sigma points' ranges ``Z``."""
    for a in range(m):
        s = Wm0 * Z[0, a]
        for p in range(1, 13):
            s += Wi * Z[p, a]
        z_hat[a] = s
        nu[a] = z[r, rows[a]] - s
    for a in range(m):
        for b in range(m):
            s = Wc0 * (Z[0, a] - z_hat[a]) * (Z[0, b] - z_hat[b])
            for p in range(1, 13):
                s += Wi * (Z[p, a] - z_hat[a]) * (Z[p, b] - z_hat[b])
            S[a, b] = s + Rm[a, b]
        for i in range(6):
            s = 0.0  # point 0's deviation from x is zero
            for p in range(1, 13):
                s += Wi * (pts[p, i] - xr[i]) * (Z[p, a] - z_hat[a])
            Pxz[i, a] = s


@njit(cache=True, error_model="numpy")
def _effective_rows(Pr, L, Pxz, S, m, H, Reff, col, tmp, sol):
    """The statistically linearised ``H = P_xzᵀ P⁻¹`` (m×6) and ``R_eff = S − H P Hᵀ``
    (symmetrised), the Joseph form's pair."""
    # H = P_xzᵀ P⁻¹: row a solves P hₐ = P_xz[:, a] through the factor.
    for a in range(m):
        for i in range(6):
            col[i] = Pxz[i, a]
        _forward(L, col, tmp)
        _backward(L, tmp, sol)
        for i in range(6):
            H[a, i] = sol[i]
    # R_eff = S − H P Hᵀ, symmetrised
    for a in range(m):
        for b in range(m):
            s = 0.0
            for i in range(6):
                t = 0.0
                for j in range(6):
                    t += Pr[i, j] * H[b, j]
                s += H[a, i] * t
            Reff[a, b] = S[a, b] - s
    if m == 2:
        off = 0.5 * (Reff[0, 1] + Reff[1, 0])
        Reff[0, 1] = off
        Reff[1, 0] = off


@njit(cache=True, error_model="numpy")
def _ukf(x, P, z, q_s, R, use, mask, root, Wm0, Wi, Wc0, scale, x_out, P_out, nis_out):
    rows = np.empty(2, np.int64)
    Rm, S, Sinv = np.empty((2, 2)), np.empty((2, 2)), np.empty((2, 2))
    L = np.empty((6, 6))
    Z = np.empty((13, 2))
    pts = np.empty((13, 6))
    z_hat, nu = np.empty(2), np.empty(2)
    Pxz = np.empty((6, 2))
    K = np.empty((6, 2))
    H = np.empty((2, 6))
    col, tmp, sol = np.empty(6), np.empty(6), np.empty(6)
    Reff = np.empty((2, 2))
    for r in range(x.shape[0]):
        m = _rows(use, r, rows)
        if not mask[r] or m == 0:
            x_out[r] = x[r]
            P_out[r] = P[r]
            nis_out[r] = np.nan
            continue
        xr = x[r]
        Pr = P[r]
        _cholesky6(Pr, L)
        _select_R(R, r, rows, m, Rm)
        _sigma_points(xr, L, root, pts)
        _point_ranges(pts, q_s, r, rows, m, Z)
        _unscented_moments(Z, pts, xr, z, r, rows, m, Rm, Wm0, Wi, Wc0, z_hat, nu, S, Pxz)
        # H = Pxzᵀ P⁻¹ and R_eff = S − H P Hᵀ, once: with the correlation, S and R_eff both
        # gain (scale − 1) Ω, Ω = R_eff − R the linearisation error's variance.
        _effective_rows(Pr, L, Pxz, S, m, H, Reff, col, tmp, sol)
        if scale != 1.0:
            for a in range(m):
                for b in range(m):
                    extra = (scale - 1.0) * (Reff[a, b] - Rm[a, b])
                    S[a, b] += extra
                    Reff[a, b] += extra
        _inverse_small(S, m, Sinv)
        for i in range(6):
            for a in range(m):
                s = 0.0
                for b in range(m):
                    s += Pxz[i, b] * Sinv[b, a]
                K[i, a] = s
        for i in range(6):
            s = xr[i]
            for a in range(m):
                s += K[i, a] * nu[a]
            x_out[r, i] = s
        _joseph_into(Pr, K, H, Reff, m, P_out[r])
        nis_out[r] = _quadratic(nu, Sinv, m)


def _outputs(x: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return np.empty(x.shape), np.empty(P.shape), np.empty(x.shape[0])


def ekf_update_runs(
    x: np.ndarray,
    P: np.ndarray,
    z: np.ndarray,
    q_s: np.ndarray,
    R: np.ndarray,
    use: np.ndarray,
    mask: np.ndarray,
    second_order: str = "none",
    correlation_steps: float = 1.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`~drake_uuv.models.filters.ekf_update` of each run in ``mask`` on the sonars of
    ``use`` (B, 2): ``z`` (B, 2) the range means, ``q_s`` (B, 3), ``R`` (2, 2) or (B, 2, 2);
    ``second_order`` the terms of the ranges' expansion it keeps (none, mean, variance, full),
    ``correlation_steps`` the factor of their variance."""
    out = _outputs(x, P)
    order = SECOND_ORDER_CODES[second_order]
    _ekf(x, P, z, q_s, R.reshape(-1, 2, 2), use, mask, order, float(correlation_steps), *out)
    return out


def iekf_update_runs(
    x: np.ndarray,
    P: np.ndarray,
    z: np.ndarray,
    q_s: np.ndarray,
    R: np.ndarray,
    use: np.ndarray,
    mask: np.ndarray,
    max_iterations: int = 5,
    tolerance: float = 1e-8,
    max_halvings: int = 8,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`~drake_uuv.models.filters.iekf_update` of each run in ``mask`` (arguments as
    :func:`ekf_update_runs`'s)."""
    out = _outputs(x, P)
    _iekf(
        x, P, z, q_s, R.reshape(-1, 2, 2), use, mask, int(max_iterations), float(tolerance),
        int(max_halvings), *out,
    )  # fmt: skip
    return out


def ukf_update_runs(
    x: np.ndarray,
    P: np.ndarray,
    z: np.ndarray,
    q_s: np.ndarray,
    R: np.ndarray,
    use: np.ndarray,
    mask: np.ndarray,
    spread: float,
    alpha: float,
    beta: float,
    correlation_steps: float = 1.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`~drake_uuv.models.unscented.ukf_range_update` of each run in ``mask``
    (arguments as :func:`ekf_update_runs`'s; ``spread = n + λ``, ``alpha``, ``beta`` of the
    sigma points, ``correlation_steps`` the factor of the linearisation error's variance)."""
    out = _outputs(x, P)
    Wi = 0.5 / spread
    Wm0 = (spread - 6.0) / spread
    Wc0 = Wm0 + 1.0 - alpha * alpha + beta
    _ukf(
        x, P, z, q_s, R.reshape(-1, 2, 2), use, mask, np.sqrt(spread), Wm0, Wi, Wc0,
        float(correlation_steps), *out,
    )  # fmt: skip
    return out


#: A Gaussian update of a batch of runs on the raw ranges:
#: ``(x, P, z, q_s, R, use, mask) -> (x, P, nis)`` (:func:`ekf_update_runs`'s signature).
RangeUpdateRuns = Callable[..., tuple[np.ndarray, np.ndarray, np.ndarray]]


def range_update_runs(update: Callable) -> RangeUpdateRuns:
    """The batched counterpart of a :data:`~drake_uuv.models.filters.RangeUpdate`
    (:func:`~drake_uuv.models.filters.ekf_update`, :func:`~drake_uuv.models.filters.iekf_update`,
    :func:`~drake_uuv.models.unscented.ukf_range_update`, or one of them with its keyword
    arguments bound by ``functools.partial``)."""
    from drake_uuv.models.filters import ekf_update, iekf_update
    from drake_uuv.models.unscented import DEFAULT_PARAMETERS, ukf_range_update

    keywords = {}
    function = update
    if isinstance(update, functools.partial):
        function, keywords = update.func, dict(update.keywords)
    if function is ekf_update and set(keywords) <= {"second_order", "correlation_steps"}:
        return functools.partial(ekf_update_runs, **keywords) if keywords else ekf_update_runs
    if function is iekf_update and set(keywords) <= {"max_iterations", "tolerance", "max_halvings"}:
        return functools.partial(iekf_update_runs, **keywords)
    if function is ukf_range_update and set(keywords) <= {"parameters", "correlation_steps"}:
        parameters = keywords.get("parameters", DEFAULT_PARAMETERS)
        return functools.partial(
            ukf_update_runs, spread=parameters.spread(6), alpha=parameters.alpha,
            beta=parameters.beta, correlation_steps=keywords.get("correlation_steps", 1.0),
        )  # fmt: skip
    raise ValueError(f"range_update: no batched counterpart of {update!r}")
