"""The particle filter's periodic update over a batch of runs, compiled: resampling (systematic),
the shrinkage kernel's regularisation, and the move by the double integrator with each
particle's own acceleration draw (see :mod:`drake_uuv.models.particle_kernels` for the layout,
the arithmetic and the costs; the draws are :mod:`drake_uuv.models.particle_random`'s).
"""

import math

import numpy as np
from numba import njit

from drake_uuv.models.particle_kernels import (
    CONTRACT,
    effective_sample_size,
    moments_into,
    normalise_into,
    psd_factor,
    weigh_into,
)
from drake_uuv.models.particle_random import (
    ACCELERATION_SLOT,
    DRAW_SLOT,
    JITTER_SLOT,
    KERNEL_SLOT,
    normal,
    resampling_counter,
    slot_counter,
    uniform,
)


@njit(cache=True, fastmath=CONTRACT)
def cloud_advance(
    particles: np.ndarray,
    log_weights: np.ndarray,
    reweigh: np.ndarray,
    posterior_log_weights: np.ndarray,
    posterior_weights: np.ndarray,
    posterior_x: np.ndarray,
    posterior_P: np.ndarray,
    keys: np.ndarray,
    moving: np.ndarray,
    drawn: np.ndarray,
    draw_x: np.ndarray,
    draw_P: np.ndarray,
    weigh_draw: np.ndarray,
    offset: np.ndarray,
    z: np.ndarray,
    used: np.ndarray,
    q_s: np.ndarray,
    R: np.ndarray,
    time_step: float,
    acceleration: np.ndarray,
    W_factor: np.ndarray,
    jitter: np.ndarray,
    resample_threshold: float,
    bandwidth: float,
    range_bearing: bool,
    out: np.ndarray,
    out_log_weights: np.ndarray,
    x: np.ndarray,
    P: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """The periodic update of every ``moving`` run (others: ``x``, ``P`` NaN, not written).

    A run's cloud: for a ``drawn`` run N draws of ``N(draw_x, draw_P)`` (relative) less
    ``offset``, weighed by the ranges ``z``, ``used``, ``q_s``, ``R`` where ``weigh_draw``;
    else its ``particles`` (B×N×6, stored) with ``log_weights``, or where ``reweigh`` the
    posterior's (:func:`~drake_uuv.models.particle_kernels.cloud_posterior`'s log weights,
    weights and moments). Resampled when its effective sample size is below
    ``resample_threshold · N`` (systematic, then the shrinkage kernel of ``bandwidth``, with
    ``range_bearing`` in range–bearing coordinates where the cloud allows: see
    :mod:`drake_uuv.models.particle_filter`), moved
    by the double integrator of ``time_step`` with ``acceleration`` (B×3) less ``W_factor ε``,
    plus ``jitter[b] ε'`` (factors of the navigation's noise; zeros: none). Writes ``out``
    (B×N×6; not ``particles``), ``out_log_weights`` and the predicted moments ``x``, ``P``.
    Run b draws from ``keys[b]``."""
    B, n = log_weights.shape
    weights, lw, chosen = np.empty(n), np.empty(n), np.empty(n, dtype=np.int64)
    ranges, drawn_cloud = np.empty((n, 2)), np.empty((n, 6))
    L, mean, c = np.empty((6, 6)), np.empty(6), np.empty(6)
    local = np.empty((n if range_bearing else 0, 6))
    half = 0.5 * time_step * time_step
    for b in range(B):
        if not moving[b]:
            x[b, :] = math.nan
            P[b, :, :] = math.nan
            continue
        key = keys[b]
        for k in range(3):
            c[k] = half * acceleration[b, k]
            c[k + 3] = time_step * acceleration[b, k]
        if drawn[b]:
            _draw_cloud(key, draw_x[b], draw_P[b], offset[b], L, drawn_cloud, lw, weights)
        known = starting_weights(
            b, drawn, weigh_draw, reweigh, drawn_cloud, offset, z, used, q_s, R, ranges,
            log_weights, posterior_log_weights, posterior_weights, posterior_x, lw, weights, mean,
        )  # fmt: skip
        cov = posterior_P[b] if known else P[b]  # P[b] is work space without the moments
        _advance_run(
            particles[b], drawn_cloud, drawn[b], lw, weights, known, mean, cov, key, chosen, L, c,
            time_step, W_factor, jitter[b], resample_threshold, bandwidth, range_bearing,
            offset[b], local, out[b], out_log_weights[b], x[b], P[b],
        )  # fmt: skip


@njit(fastmath=CONTRACT)
def starting_weights(
    b: int,
    drawn: np.ndarray,
    weigh_draw: np.ndarray,
    reweigh: np.ndarray,
    drawn_cloud: np.ndarray,
    offset: np.ndarray,
    z: np.ndarray,
    used: np.ndarray,
    q_s: np.ndarray,
    R: np.ndarray,
    ranges: np.ndarray,
    log_weights: np.ndarray,
    posterior_log_weights: np.ndarray,
    posterior_weights: np.ndarray,
    posterior_x: np.ndarray,
    lw: np.ndarray,
    weights: np.ndarray,
    mean: np.ndarray,
) -> bool:  # pragma: no cover - compiled
    """Run b's log weights and weights before its move, into ``lw`` and ``weights``: a drawn
    cloud's (already drawn into ``drawn_cloud``, ``lw``, ``weights``), weighed by the ranges
    where ``weigh_draw``; else the posterior's where ``reweigh``, with its mean in the stored
    frame in ``mean`` (returns True: the posterior's moments are known); else the stored ones.
    Shared by the particle and the marginalised clouds' periodic updates."""
    if drawn[b]:
        if weigh_draw[b]:
            # Not in place: a tempered update reads the prior log weights.
            weigh_into(
                drawn_cloud, offset[b], lw.copy(), weights.copy(), z[b], used[b], q_s[b], R[b],
                ranges, lw, weights,
            )  # fmt: skip
        return False
    if reweigh[b]:  # the posterior's weights and moments (stored frame: less offset)
        lw[:] = posterior_log_weights[b]
        weights[:] = posterior_weights[b]
        for k in range(6):
            mean[k] = posterior_x[b, k] - offset[b, k]
        return True
    lw[:] = log_weights[b]
    normalise_into(lw, weights)
    return False


@njit
def _draw_cloud(
    key: np.uint64,
    mean: np.ndarray,
    cov: np.ndarray,
    offset: np.ndarray,
    L: np.ndarray,
    out: np.ndarray,
    lw: np.ndarray,
    weights: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """N draws of ``N(mean, cov)`` less ``offset`` in ``out`` (N×6), equally weighted (``lw``,
    ``weights``); ``L`` work space."""
    psd_factor(cov, L)
    n = out.shape[0]
    m, factor = _six(mean), lower_entries(L)
    for i in range(n):
        d = gaussian_draw(key, i, DRAW_SLOT, m, factor)
        for k in range(6):
            out[i, k] = d[k] - offset[k]
        lw[i] = -math.log(n)
    normalise_into(lw, weights)


#: The zero mean of the navigation noise's draw.
_NO_MEAN = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


@njit
def _six(v: np.ndarray) -> tuple:  # pragma: no cover - compiled
    """The six values of ``v`` as a tuple."""
    return (v[0], v[1], v[2], v[3], v[4], v[5])


@njit
def lower_entries(L: np.ndarray) -> tuple:  # pragma: no cover - compiled
    """The 21 entries of a lower-triangular 6×6 ``L``, row by row, as a tuple: the draws take
    their factor as values, not as an array (see :func:`gaussian_draw`)."""
    return (
        L[0, 0],
        L[1, 0], L[1, 1],
        L[2, 0], L[2, 1], L[2, 2],
        L[3, 0], L[3, 1], L[3, 2], L[3, 3],
        L[4, 0], L[4, 1], L[4, 2], L[4, 3], L[4, 4],
        L[5, 0], L[5, 1], L[5, 2], L[5, 3], L[5, 4], L[5, 5],
    )  # fmt: skip


@njit(fastmath=CONTRACT)
def gaussian_draw(
    key: np.uint64, particle: int, slot: int, mean: tuple, L: tuple
) -> tuple:  # pragma: no cover - compiled
    """A draw of ``N(mean, L Lᵀ)`` from six slots of a particle (``mean`` 6 values, ``L`` the
    21 of :func:`lower_entries`, lower triangular as :func:`psd_factor` gives it).

    Values in and out, no arrays: a compiled function that takes arrays and branches (the
    ziggurat's rare second try does) keeps their reference counts' atomic operations on every
    call, which cost a particle's loop more than its draws."""
    e0 = normal(key, slot_counter(particle, slot))
    e1 = normal(key, slot_counter(particle, slot + 1))
    e2 = normal(key, slot_counter(particle, slot + 2))
    e3 = normal(key, slot_counter(particle, slot + 3))
    e4 = normal(key, slot_counter(particle, slot + 4))
    e5 = normal(key, slot_counter(particle, slot + 5))
    return (
        mean[0] + L[0] * e0,
        mean[1] + (L[1] * e0 + L[2] * e1),
        mean[2] + (L[3] * e0 + L[4] * e1 + L[5] * e2),
        mean[3] + (L[6] * e0 + L[7] * e1 + L[8] * e2 + L[9] * e3),
        mean[4] + (L[10] * e0 + L[11] * e1 + L[12] * e2 + L[13] * e3 + L[14] * e4),
        mean[5] + (
            L[15] * e0 + L[16] * e1 + L[17] * e2 + L[18] * e3 + L[19] * e4 + L[20] * e5
        ),
    )  # fmt: skip


@njit
def _systematic_into(
    weights: np.ndarray, u: float, chosen: np.ndarray
) -> None:  # pragma: no cover - compiled
    """Systematic resampling's ancestors with offset ``u`` in ``chosen``: particle j is copied
    ``⌈N cdf_j − u⌉ − ⌈N cdf_{j−1} − u⌉`` times (the last edge N: rounding loses no copy)."""
    n = weights.shape[0]
    cdf = 0.0
    filled = 0
    for j in range(n):
        cdf += weights[j]
        edge = n if j == n - 1 else min(max(int(math.ceil(cdf * n - u)), 0), n)
        while filled < edge:
            chosen[filled] = j
            filled += 1


@njit(fastmath=CONTRACT)
def _prepare_resampling(
    source: np.ndarray,
    drawn: np.ndarray,
    use_drawn: bool,
    weights: np.ndarray,
    have_moments: bool,
    mean: np.ndarray,
    cov: np.ndarray,
    key: np.uint64,
    bandwidth: float,
    L: np.ndarray,
    shift: np.ndarray,
    chosen: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """Systematic resampling's ancestors in ``chosen``, and the shrinkage kernel's ``h L``
    (``L Lᵀ`` the cloud's covariance before resampling: ``cov``, or computed unless
    ``have_moments``) and ``(1 − a) x̄`` in ``shift``."""
    n = weights.shape[0]
    if bandwidth > 0.0:
        if not have_moments:
            if use_drawn:
                moments_into(drawn, np.zeros(6), weights, mean, cov)
            else:
                moments_into(source, np.zeros(6), weights, mean, cov)
        psd_factor(cov, L)
        shrink = math.sqrt(1.0 - bandwidth * bandwidth)
        for k in range(6):
            shift[k] = (1.0 - shrink) * mean[k]
            for m in range(6):
                L[k, m] *= bandwidth
    _systematic_into(weights, uniform(key, resampling_counter(n)), chosen)


@njit(fastmath=CONTRACT)
def _range_bearing_cloud(
    on: bool,
    cloud: np.ndarray,
    offset: np.ndarray,
    weights: np.ndarray,
    E: np.ndarray,
    local: np.ndarray,
) -> float:  # pragma: no cover - compiled
    """With ``on``, the cloud (N×6, stored) in range–bearing coordinates in ``local``, the
    frame's rotation in ``E`` (first row: the weighted mean position's direction); returns the
    mean range, or 0 where the Cartesian kernel applies (not ``on``, a mean at the origin, or
    a particle at or behind the plane normal to that direction): > 0, the kernel moves the
    range–bearing coordinates."""
    if not on:
        return 0.0
    n = cloud.shape[0]
    m = np.zeros(3)
    for i in range(n):
        for k in range(3):
            m[k] += weights[i] * (cloud[i, k] + offset[k])
    radius = math.sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2])
    if not radius > 0.0:
        return 0.0
    u = m / radius
    axis = np.array([0.0, 0.0, 1.0]) if abs(u[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    w = np.cross(u, axis)
    w /= math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
    v = np.cross(w, u)
    for k in range(3):
        E[0, k], E[1, k], E[2, k] = u[k], v[k], w[k]
    for i in range(n):
        q0, q1, q2 = cloud[i, 0] + offset[0], cloud[i, 1] + offset[1], cloud[i, 2] + offset[2]
        d0 = E[0, 0] * q0 + E[0, 1] * q1 + E[0, 2] * q2
        if not d0 > 0.0:
            return 0.0
        d1 = E[1, 0] * q0 + E[1, 1] * q1 + E[1, 2] * q2
        d2 = E[2, 0] * q0 + E[2, 1] * q1 + E[2, 2] * q2
        r = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        local[i, 0] = r
        local[i, 1] = radius * math.atan2(d1, d0)
        local[i, 2] = radius * math.asin(d2 / r)
        for k in range(3, 6):
            local[i, k] = cloud[i, k]
    return radius


@njit(fastmath=CONTRACT)
def _kernel_from_range_bearing(
    draw: tuple,
    e: np.ndarray,
    shrink: float,
    local: np.ndarray,
    row: int,
    E: np.ndarray,
    radius: float,
    offset: np.ndarray,
    p: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """A particle's kernel move ``draw + shrink · y`` (its draw, 6 values, and its
    range–bearing coordinates ``y``, row ``row`` of ``local``) back in the stored frame, in
    ``p`` (``e`` is work space)."""
    for k in range(6):
        e[k] = draw[k] + shrink * local[row, k]
    azimuth, elevation = e[1] / radius, e[2] / radius
    d0 = e[0] * math.cos(elevation) * math.cos(azimuth)
    d1 = e[0] * math.cos(elevation) * math.sin(azimuth)
    d2 = e[0] * math.sin(elevation)
    for k in range(3):
        p[k] = E[0, k] * d0 + E[1, k] * d1 + E[2, k] * d2 - offset[k]
    for k in range(3, 6):
        p[k] = e[k]


@njit(fastmath=CONTRACT)
def _advance_run(
    source: np.ndarray,
    drawn: np.ndarray,
    use_drawn: bool,
    lw: np.ndarray,
    weights: np.ndarray,
    have_moments: bool,
    mean: np.ndarray,
    cov: np.ndarray,
    key: np.uint64,
    chosen: np.ndarray,
    L: np.ndarray,
    c: np.ndarray,
    t: float,
    W_factor: np.ndarray,
    jitter: np.ndarray,
    resample_threshold: float,
    bandwidth: float,
    range_bearing: bool,
    offset: np.ndarray,
    local: np.ndarray,
    target: np.ndarray,
    out_log_weights: np.ndarray,
    x: np.ndarray,
    P: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """One run of :func:`cloud_advance` from its cloud ``source`` (N×6, stored, read-only) or
    with ``use_drawn`` its ``drawn`` cloud (one compiled function for both), log weights ``lw``
    and ``weights`` (with ``have_moments`` their ``mean`` and ``cov``): resampled when
    degenerate, moved into ``target``; ``lw``, ``weights`` become the predicted ones. With
    ``range_bearing`` the kernel moves range–bearing coordinates (``local``, N×6) if it can."""
    n = source.shape[0]
    zero, shift = np.zeros(6), np.empty(6)
    shrink = math.sqrt(1.0 - bandwidth * bandwidth)
    resample = effective_sample_size(weights) < resample_threshold * n
    on, E = resample and bandwidth > 0.0 and range_bearing, np.empty((3, 3))
    radius = _range_bearing_cloud(on, drawn if use_drawn else source, offset, weights, E, local)
    if resample:
        if radius > 0.0:  # the coordinates' own moments (``mean``, ``cov``: the posterior's)
            source, drawn, use_drawn, have_moments = local, local, False, False
            mean, cov = np.empty(6), np.empty((6, 6))
        _prepare_resampling(
            source, drawn, use_drawn, weights, have_moments, mean, cov, key, bandwidth, L, shift,
            chosen,
        )  # fmt: skip
        for i in range(n):
            lw[i], weights[i] = -math.log(n), 1.0 / n
    jittered = np.any(jitter != 0.0)
    half, p, e, cloud = 0.5 * t * t, np.empty(6), np.empty(6), drawn if use_drawn else source
    kernel_mean, kernel_factor, jitter_factor = _six(shift), lower_entries(L), lower_entries(jitter)
    for i in range(n):
        row = chosen[i] if resample else i
        for k in range(6):  # not a view of the row: see gaussian_draw
            p[k] = cloud[row, k]
        if resample and bandwidth > 0.0:  # (a range–bearing kernel, radius > 0, only then)
            d = gaussian_draw(key, i, KERNEL_SLOT, kernel_mean, kernel_factor)
            if radius > 0.0:
                _kernel_from_range_bearing(d, e, shrink, local, row, E, radius, offset, p)
            else:
                for k in range(6):
                    p[k] = d[k] + shrink * p[k]
        e0 = normal(key, slot_counter(i, ACCELERATION_SLOT))
        e1 = normal(key, slot_counter(i, ACCELERATION_SLOT + 1))
        e2 = normal(key, slot_counter(i, ACCELERATION_SLOT + 2))
        u0 = W_factor[0, 0] * e0 + W_factor[0, 1] * e1 + W_factor[0, 2] * e2
        u1 = W_factor[1, 0] * e0 + W_factor[1, 1] * e1 + W_factor[1, 2] * e2
        u2 = W_factor[2, 0] * e0 + W_factor[2, 1] * e1 + W_factor[2, 2] * e2
        target[i, 0] = (c[0] - half * u0) + (p[0] + t * p[3])
        target[i, 1] = (c[1] - half * u1) + (p[1] + t * p[4])
        target[i, 2] = (c[2] - half * u2) + (p[2] + t * p[5])
        target[i, 3] = (c[3] - t * u0) + p[3]
        target[i, 4] = (c[4] - t * u1) + p[4]
        target[i, 5] = (c[5] - t * u2) + p[5]
        if jittered:  # the navigation's process noise, a draw per particle
            d = gaussian_draw(key, i, JITTER_SLOT, _NO_MEAN, jitter_factor)
            for k in range(6):
                target[i, k] += d[k]
    out_log_weights[:] = lw
    moments_into(target, zero, weights, x, P)
