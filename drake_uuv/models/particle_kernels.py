"""The particle filter's steps over a batch of runs, compiled: B runs of N particles each.

:mod:`drake_uuv.models.particle_filter` states the filter as numpy on one 6×N cloud; this
module steps ``B`` clouds at once, each in one pass of a loop over its particles, so that the
many numpy passes over a cloud (about 40 a step, each a fresh trip through memory) become a few
fused ones and the cost of a call is shared by the batch. The layout: particles ``(B, N, 6)``
(each particle's six values contiguous), log weights ``(B, N)``. Each run's numbers are
computed by the same loop whatever B is and read nothing of another run, so a run's bits do
not depend on its batch; a run whose cloud holds NaN yields NaN, raises nothing and touches
no other run.

Randomness, counter-based: run i's draws of a step are a pure function of a 64-bit key (from
the run's uniform of the step, :func:`cloud_keys`) and a counter. Particle j's draws use their
own counters (:data:`SLOTS` slots of 64 counters each: a draw of the initial cloud, the
regularisation, the target's acceleration, the navigation's noise), so every draw is the same
whatever the particle count of the other runs, whether the step resampled or not, and whatever
order the loop takes. The generator is SplitMix64 (as :mod:`drake_uuv.primitives.run_noise`),
the normals Marsaglia and Tsang's ziggurat with 256 layers (Marsaglia & Tsang 2000, "The
ziggurat method for generating random variables"; the tables as numpy's legacy generator
builds them): one 64-bit output gives a normal 99 % of the time, about 2 ns here, where the
Box–Muller transform took 15-35 ns and numpy's generator 10-20 ns (the draws were half of a
step's cost).

Arithmetic: products and sums may fuse into FMA instructions (numba's ``fastmath`` flag
``contract`` alone: no reassociation), so each sum runs in its loop's order and a run's bits
are the same in any batch on a given machine. The model is the package's double integrator,
written out (``q + t ϑ``, not a 6×6 product).

Cost (N = 5000, one run, a loaded 2-core machine): the measurement update about 110 µs, the
periodic update about 120 µs, 230 µs when it resamples and regularises (numpy's resampling
prediction, :func:`~drake_uuv.models.particle_filter.pf_predict`, about 1000 µs there).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from drake_uuv.primitives.run_noise import source_id

#: Per particle, this many draw slots; slot ``s`` of particle ``j`` starts at counter
#: ``(j · SLOTS + s) · 64`` (a normal takes one counter, a few more on the 1 % rejected).
SLOTS = 32
#: The slots: the initial draw (6), the regularisation kernel (6), the target's acceleration
#: (3), the navigation's process noise (6).
DRAW_SLOT, KERNEL_SLOT, ACCELERATION_SLOT, JITTER_SLOT = 0, 6, 12, 15
_SLOT_SHIFT = np.uint64(6)
_GAMMA = np.uint64(0x9E3779B97F4A7C15)
# Products and sums may fuse into FMAs (the same instructions for every run and batch); no
# other reordering, so each sum still runs in the loop's order.
_CONTRACT = {"contract"}
#: The key's source: a cloud's stream differs from any RunNoise source's.
CLOUD_SOURCE = source_id("particle cloud")


def _ziggurat_tables() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Marsaglia and Tsang's tables for 256 layers and 52-bit uniforms (numpy's legacy)."""
    m1 = 2.0**52
    dn = tn = 3.6541528853610088
    vn = 0.00492867323399
    ki = np.zeros(256, np.uint64)
    wi = np.zeros(256)
    fi = np.zeros(256)
    q = vn / math.exp(-0.5 * dn * dn)
    ki[0] = np.uint64((dn / q) * m1)
    wi[0], wi[255] = q / m1, dn / m1
    fi[0], fi[255] = 1.0, math.exp(-0.5 * dn * dn)
    for i in range(254, 0, -1):
        dn = math.sqrt(-2.0 * math.log(vn / dn + math.exp(-0.5 * dn * dn)))
        ki[i + 1] = np.uint64((dn / tn) * m1)
        tn = dn
        fi[i] = math.exp(-0.5 * dn * dn)
        wi[i] = dn / m1
    return ki, wi, fi


_KI, _WI, _FI = _ziggurat_tables()
_TAIL = 3.6541528853610088


@njit(inline="always")
def _mix(z: np.uint64) -> np.uint64:  # pragma: no cover - compiled
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


@njit(inline="always")
def _raw(key: np.uint64, counter: np.uint64) -> np.uint64:  # pragma: no cover - compiled
    return _mix(key + (counter + np.uint64(1)) * _GAMMA)


@njit(inline="always")
def _uniform(key: np.uint64, counter: np.uint64) -> float:  # pragma: no cover - compiled
    """In [0, 1) on a 2⁻⁵³ grid."""
    return float(_raw(key, counter) >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@njit
def _normal_loop(key: np.uint64, counter: np.uint64) -> float:  # pragma: no cover - compiled
    """A standard normal from the counters ``counter, counter + 1, …`` (the whole ziggurat)."""
    while True:
        r = _raw(key, counter)
        counter += np.uint64(1)
        layer = r & np.uint64(0xFF)
        r >>= np.uint64(8)
        negative = (r & np.uint64(1)) != np.uint64(0)
        rabs = (r >> np.uint64(1)) & np.uint64(0x000FFFFFFFFFFFFF)
        x = float(rabs) * _WI[layer]
        if negative:
            x = -x
        if rabs < _KI[layer]:
            return x
        if layer == 0:  # the tail beyond the base strip
            while True:
                xx = -(1.0 / _TAIL) * math.log1p(-_uniform(key, counter))
                yy = -math.log1p(-_uniform(key, counter + np.uint64(1)))
                counter += np.uint64(2)
                if yy + yy > xx * xx:
                    return -(_TAIL + xx) if negative else _TAIL + xx
        elif (_FI[layer - 1] - _FI[layer]) * _uniform(key, counter) + _FI[layer] < math.exp(
            -0.5 * x * x
        ):
            return x
        counter += np.uint64(1)


@njit(inline="always")
def _normal(key: np.uint64, counter: np.uint64) -> float:  # pragma: no cover - compiled
    """A standard normal from the counters ``counter, counter + 1, …``: the ziggurat's first
    try inline (accepted 99 % of the time), the rest in :func:`_normal_loop` (which takes the
    same first try again, so the value does not depend on where it was computed)."""
    r = _raw(key, counter) >> np.uint64(8)
    layer = _raw(key, counter) & np.uint64(0xFF)
    rabs = (r >> np.uint64(1)) & np.uint64(0x000FFFFFFFFFFFFF)
    if rabs < _KI[layer]:
        x = float(rabs) * _WI[layer]
        return -x if (r & np.uint64(1)) != np.uint64(0) else x
    return _normal_loop(key, counter)


@njit(inline="always")
def _slot(particle: int, slot: int) -> np.uint64:  # pragma: no cover - compiled
    return np.uint64(particle * SLOTS + slot) << _SLOT_SHIFT


@njit(cache=True)
def cloud_keys(uniforms: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """Each run's key of a step from its uniform draw ``u`` in [0, 1) (53 bits)."""
    keys = np.empty(uniforms.shape[0], dtype=np.uint64)
    for b in range(uniforms.shape[0]):
        u = uniforms[b]
        seed = np.uint64(u * 9007199254740992.0) if 0.0 <= u < 1.0 else np.uint64(0)
        keys[b] = _mix(_mix(seed) ^ CLOUD_SOURCE)
    return keys


@njit(cache=True)
def standard_normals(
    keys: np.ndarray, count: int, slot: int, size: int
) -> np.ndarray:  # pragma: no cover - compiled
    """The normals of slots ``slot … slot + size − 1`` of particles ``0 … count − 1`` of each
    key: ``(B, count, size)`` (for tests: the draws the steps use)."""
    out = np.empty((keys.shape[0], count, size))
    for b in range(keys.shape[0]):
        for j in range(count):
            for k in range(size):
                out[b, j, k] = _normal(keys[b], _slot(j, slot + k))
    return out


@njit(cache=True)
def resampling_uniforms(keys: np.ndarray, count: int) -> np.ndarray:  # pragma: no cover
    """Each key's offset of systematic resampling for a cloud of ``count`` particles (for
    tests: the offset the steps use)."""
    out = np.empty(keys.shape[0])
    for b in range(keys.shape[0]):
        out[b] = _uniform(keys[b], _resampling_counter(count))
    return out


@njit(inline="always")
def _resampling_counter(count: int) -> np.uint64:  # pragma: no cover - compiled
    """The counter of the resampling's offset: the first after every particle's slots."""
    return np.uint64(count * SLOTS) << _SLOT_SHIFT


@njit(cache=True)
def psd_factor(M: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover - compiled
    """A lower factor ``L Lᵀ = M`` of a symmetric positive semidefinite ``M`` (n×n), in ``out``:
    Cholesky, a pivot at or below ``n ε`` times the largest diagonal taken as zero (its column
    then zero), so that a singular cloud or a rank-3 noise has a factor. NaN in: NaN out."""
    n = M.shape[0]
    top = 0.0
    for i in range(n):
        top = max(top, M[i, i])
    tol = n * 2.220446049250313e-16 * top
    for j in range(n):
        for i in range(n):
            out[i, j] = 0.0
    for j in range(n):
        d = M[j, j]
        for k in range(j):
            d -= out[j, k] * out[j, k]
        if d > tol:
            root = math.sqrt(d)
            out[j, j] = root
            for i in range(j + 1, n):
                s = M[i, j]
                for k in range(j):
                    s -= out[i, k] * out[j, k]
                out[i, j] = s / root
        elif not d <= tol:  # NaN
            for i in range(j, n):
                out[i, j] = math.nan


@njit(cache=True)
def psd_factors(M: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """:func:`psd_factor` of each of a stack of matrices (B×n×n)."""
    out = np.empty_like(M)
    for b in range(M.shape[0]):
        psd_factor(M[b], out[b])
    return out


@njit
def _normalise(log_weights: np.ndarray, weights: np.ndarray) -> None:  # pragma: no cover
    """``weights = exp(log_weights − max) / Σ``; equal log weights (a resampled cloud): 1/N
    each, without the exponentials."""
    n = log_weights.shape[0]
    top = log_weights[0]
    low = top
    bad = False
    for i in range(n):
        v = log_weights[i]
        top = max(top, v)
        low = min(low, v)
        bad |= v != v
    if top == low and math.isfinite(top) and not bad:
        for i in range(n):
            weights[i] = 1.0 / n
        return
    if bad or not math.isfinite(top):
        for i in range(n):
            weights[i] = math.nan
        return
    total = 0.0
    for i in range(n):
        w = math.exp(log_weights[i] - top)
        weights[i] = w
        total += w
    scale = 1.0 / total
    for i in range(n):
        weights[i] *= scale


@njit(fastmath=_CONTRACT)
def _moments(
    particles: np.ndarray, offset: np.ndarray, weights: np.ndarray, x: np.ndarray, P: np.ndarray
) -> None:  # pragma: no cover - compiled
    """Weighted mean and covariance of ``particles + offset`` (weights sum to 1), two passes.
    The sums are scalars, not array entries, so that they stay in registers."""
    n = particles.shape[0]
    o0, o1, o2, o3, o4, o5 = offset[0], offset[1], offset[2], offset[3], offset[4], offset[5]
    m0 = m1 = m2 = m3 = m4 = m5 = 0.0
    for i in range(n):
        w = weights[i]
        m0 += w * (particles[i, 0] + o0)
        m1 += w * (particles[i, 1] + o1)
        m2 += w * (particles[i, 2] + o2)
        m3 += w * (particles[i, 3] + o3)
        m4 += w * (particles[i, 4] + o4)
        m5 += w * (particles[i, 5] + o5)
    x[0], x[1], x[2], x[3], x[4], x[5] = m0, m1, m2, m3, m4, m5
    c00 = c10 = c11 = c20 = c21 = c22 = c30 = c31 = c32 = c33 = c40 = 0.0
    c41 = c42 = c43 = c44 = c50 = c51 = c52 = c53 = c54 = c55 = 0.0
    for i in range(n):
        w = weights[i]
        d0 = particles[i, 0] + o0 - m0
        d1 = particles[i, 1] + o1 - m1
        d2 = particles[i, 2] + o2 - m2
        d3 = particles[i, 3] + o3 - m3
        d4 = particles[i, 4] + o4 - m4
        d5 = particles[i, 5] + o5 - m5
        w0 = w * d0
        w1 = w * d1
        w2 = w * d2
        w3 = w * d3
        w4 = w * d4
        w5 = w * d5
        c00 += w0 * d0
        c10 += w1 * d0
        c11 += w1 * d1
        c20 += w2 * d0
        c21 += w2 * d1
        c22 += w2 * d2
        c30 += w3 * d0
        c31 += w3 * d1
        c32 += w3 * d2
        c33 += w3 * d3
        c40 += w4 * d0
        c41 += w4 * d1
        c42 += w4 * d2
        c43 += w4 * d3
        c44 += w4 * d4
        c50 += w5 * d0
        c51 += w5 * d1
        c52 += w5 * d2
        c53 += w5 * d3
        c54 += w5 * d4
        c55 += w5 * d5
    P[0, 0] = c00
    P[1, 0] = c10
    P[0, 1] = c10
    P[1, 1] = c11
    P[2, 0] = c20
    P[0, 2] = c20
    P[2, 1] = c21
    P[1, 2] = c21
    P[2, 2] = c22
    P[3, 0] = c30
    P[0, 3] = c30
    P[3, 1] = c31
    P[1, 3] = c31
    P[3, 2] = c32
    P[2, 3] = c32
    P[3, 3] = c33
    P[4, 0] = c40
    P[0, 4] = c40
    P[4, 1] = c41
    P[1, 4] = c41
    P[4, 2] = c42
    P[2, 4] = c42
    P[4, 3] = c43
    P[3, 4] = c43
    P[4, 4] = c44
    P[5, 0] = c50
    P[0, 5] = c50
    P[5, 1] = c51
    P[1, 5] = c51
    P[5, 2] = c52
    P[2, 5] = c52
    P[5, 3] = c53
    P[3, 5] = c53
    P[5, 4] = c54
    P[4, 5] = c54
    P[5, 5] = c55


@njit(fastmath=_CONTRACT)
def _weigh(
    particles: np.ndarray,
    offset: np.ndarray,
    log_weights: np.ndarray,
    prior: np.ndarray,
    z: np.ndarray,
    used: np.ndarray,
    q_s: np.ndarray,
    R: np.ndarray,
    ranges: np.ndarray,
    out: np.ndarray,
    posterior: np.ndarray,
) -> float:  # pragma: no cover - compiled
    """Bayes' rule for the used sonars' mean ranges ``z`` (noise ``R`` of both, 2×2) on the
    particles ``particles + offset`` with ``log_weights`` (``prior`` their normalised
    weights): the normalised posterior log weights in ``out``; returns the NIS of ``z``
    against the particles' predicted ranges (mean and covariance under ``prior``, plus the
    noise), and the posterior's normalised weights in ``posterior`` (may be ``prior``).
    ``ranges`` (N×2) is work space. No sonar used: ``out`` the log weights, NIS NaN."""
    n = particles.shape[0]
    s0, s1 = used[0], used[1]
    if not (s0 or s1):
        for i in range(n):
            out[i] = log_weights[i]
            posterior[i] = prior[i]
        return math.nan
    h0, h1, h2 = 0.5 * q_s[0], 0.5 * q_s[1], 0.5 * q_s[2]
    m0 = m1 = 0.0
    for i in range(n):
        q0 = particles[i, 0] + offset[0]
        q1 = particles[i, 1] + offset[1]
        q2 = particles[i, 2] + offset[2]
        a0, a1, a2 = q0 + h0, q1 + h1, q2 + h2
        b0, b1, b2 = q0 - h0, q1 - h1, q2 - h2
        d0 = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
        d1 = math.sqrt(b0 * b0 + b1 * b1 + b2 * b2)
        ranges[i, 0] = d0
        ranges[i, 1] = d1
        m0 += prior[i] * d0
        m1 += prior[i] * d1
    c00 = c01 = c11 = 0.0
    for i in range(n):
        e0 = ranges[i, 0] - m0
        e1 = ranges[i, 1] - m1
        c00 += prior[i] * e0 * e0
        c01 += prior[i] * e0 * e1
        c11 += prior[i] * e1 * e1
    nu0, nu1 = z[0] - m0, z[1] - m1
    if s0 and s1:
        S00, S01, S11 = c00 + R[0, 0], c01 + 0.5 * (R[0, 1] + R[1, 0]), c11 + R[1, 1]
        nis = (nu0 * nu0 * S11 - 2.0 * nu0 * nu1 * S01 + nu1 * nu1 * S00) / (S00 * S11 - S01 * S01)
        r01 = 0.5 * (R[0, 1] + R[1, 0])
        det = R[0, 0] * R[1, 1] - r01 * r01
        i00, i01, i11 = 0.5 * R[1, 1] / det, -0.5 * r01 / det, 0.5 * R[0, 0] / det
        for i in range(n):
            e0 = ranges[i, 0] - z[0]
            e1 = ranges[i, 1] - z[1]
            out[i] = log_weights[i] - (i00 * e0 * e0 + 2.0 * i01 * e0 * e1 + i11 * e1 * e1)
    else:
        s = 0 if s0 else 1
        nu = nu0 if s0 else nu1
        nis = nu * nu / ((c00 if s0 else c11) + R[s, s])
        half = 0.5 / R[s, s]
        for i in range(n):
            e = ranges[i, s] - z[s]
            out[i] = log_weights[i] - half * e * e
    top = out[0]
    bad = False
    for i in range(n):
        top = max(top, out[i])
        bad |= out[i] != out[i]
    if bad:
        top = math.nan
    total = 0.0
    for i in range(n):
        w = math.exp(out[i] - top)
        posterior[i] = w
        total += w
    norm = top + math.log(total)
    scale = 1.0 / total
    for i in range(n):
        out[i] -= norm
        posterior[i] *= scale
    return nis


@njit(cache=True, fastmath=_CONTRACT)
def cloud_posterior(
    particles: np.ndarray,
    log_weights: np.ndarray,
    offset: np.ndarray,
    z: np.ndarray,
    used: np.ndarray,
    q_s: np.ndarray,
    R: np.ndarray,
    live: np.ndarray,
    x: np.ndarray,
    P: np.ndarray,
    nis: np.ndarray,
    log_posterior: np.ndarray,
    posterior_weights: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """The measurement update of every live run (deterministic): the particles
    ``particles + offset`` (B×N×6, with ``log_weights`` B×N) reweighted by the used sonars'
    ranges ``z`` (B×2; ``used`` B×2, ``q_s`` B×3, ``R`` B×2×2). Writes the posterior's weighted
    mean and covariance (``x`` B×6, ``P`` B×6×6), the NIS (``nis`` B, NaN without a range)
    and the normalised log weights (``log_posterior`` B×N) and weights
    (``posterior_weights``); a run not ``live`` gets NaN moments, NIS and weights and its log
    weights unchanged."""
    B, n = log_weights.shape
    prior = np.empty(n)
    ranges = np.empty((n, 2))
    for b in range(B):
        if not live[b]:
            x[b, :] = math.nan
            P[b, :, :] = math.nan
            nis[b] = math.nan
            log_posterior[b, :] = log_weights[b, :]
            posterior_weights[b, :] = math.nan
            continue
        _normalise(log_weights[b], prior)
        nis[b] = _weigh(
            particles[b], offset[b], log_weights[b], prior, z[b], used[b], q_s[b], R[b], ranges,
            log_posterior[b], posterior_weights[b],
        )  # fmt: skip
        _moments(particles[b], offset[b], posterior_weights[b], x[b], P[b])


@njit(cache=True, fastmath=_CONTRACT)
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
    out: np.ndarray,
    out_log_weights: np.ndarray,
    x: np.ndarray,
    P: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """The periodic update of every ``moving`` run.

    A run's cloud of this step: for a ``drawn`` run, N draws of ``N(draw_x, draw_P)``
    (relative, B×6 and B×6×6) less ``offset`` (B×6), weighed by the ranges ``z``, ``used``,
    ``q_s``, ``R`` where ``weigh_draw``; else its ``particles`` (B×N×6, stored frame) with
    ``log_weights`` (B×N), or where ``reweigh`` the posterior's (:func:`cloud_posterior`'s
    ``posterior_log_weights``, their normalised ``posterior_weights`` and moments
    ``posterior_x``, ``posterior_P``, relative frame; unread elsewhere). Resampled when its
    effective sample size is below ``resample_threshold · N`` (systematic, then Liu and West's
    shrinkage kernel of ``bandwidth``), then moved by the double integrator of ``time_step``
    ``t``: ``q⁺ = q + t ϑ + ½t² (a − ū)``, ``ϑ⁺ = ϑ + t (a − ū)``, ``ū = W_factor ε``
    (``acceleration`` a, B×3), plus ``jitter[b] ε'`` (B×6×6 factors of the navigation's
    process noise; zeros: none). Writes the particles to ``out`` (B×N×6; not ``particles``),
    their log weights to ``out_log_weights`` and the predicted mean and covariance to ``x``,
    ``P``. A run not moving is not written (``x``, ``P`` NaN). Draws: run b's ``keys[b]``."""
    B, n = log_weights.shape
    weights = np.empty(n)
    ranges = np.empty((n, 2))
    chosen = np.empty(n, dtype=np.int64)
    drawn_cloud = np.empty((n, 6))
    lw = np.empty(n)
    L = np.empty((6, 6))
    mean = np.empty(6)
    c = np.empty(6)
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
            psd_factor(draw_P[b], L)
            for i in range(n):
                _draw_gaussian_call(key, i, DRAW_SLOT, draw_x[b], L, offset[b], drawn_cloud[i])
                lw[i] = -math.log(n)
            _normalise(lw, weights)
            if weigh_draw[b]:
                _weigh(
                    drawn_cloud, offset[b], lw, weights, z[b], used[b], q_s[b], R[b], ranges, lw,
                    weights,
                )  # fmt: skip
            _advance_run(
                particles[b], drawn_cloud, True, lw, weights, False, mean, P[b], key, chosen, L,
                c, time_step,
                W_factor, jitter[b], resample_threshold, bandwidth, out[b], out_log_weights[b],
                x[b], P[b],
            )  # fmt: skip
        elif reweigh[b]:  # the posterior's weights and moments (stored frame: less offset)
            lw[:] = posterior_log_weights[b]
            weights[:] = posterior_weights[b]
            for k in range(6):
                mean[k] = posterior_x[b, k] - offset[b, k]
            _advance_run(
                particles[b], drawn_cloud, False, lw, weights, True, mean, posterior_P[b], key,
                chosen, L, c,
                time_step, W_factor, jitter[b], resample_threshold, bandwidth, out[b],
                out_log_weights[b], x[b], P[b],
            )  # fmt: skip
        else:
            lw[:] = log_weights[b]
            _normalise(lw, weights)
            _advance_run(
                particles[b], drawn_cloud, False, lw, weights, False, mean, P[b], key, chosen, L,
                c, time_step,
                W_factor, jitter[b], resample_threshold, bandwidth, out[b], out_log_weights[b],
                x[b], P[b],
            )  # fmt: skip


@njit(inline="always", fastmath=_CONTRACT)
def _draw_gaussian(
    key: np.uint64,
    particle: int,
    slot: int,
    mean: np.ndarray,
    L: np.ndarray,
    offset: np.ndarray,
    out: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """A draw of ``N(mean, L Lᵀ)`` (``L`` lower triangular, as :func:`psd_factor` gives it)
    less ``offset`` from six slots of a particle, in ``out``."""
    e0 = _normal(key, _slot(particle, slot))
    e1 = _normal(key, _slot(particle, slot + 1))
    e2 = _normal(key, _slot(particle, slot + 2))
    e3 = _normal(key, _slot(particle, slot + 3))
    e4 = _normal(key, _slot(particle, slot + 4))
    e5 = _normal(key, _slot(particle, slot + 5))
    out[0] = mean[0] + L[0, 0] * e0 - offset[0]
    out[1] = mean[1] + (L[1, 0] * e0 + L[1, 1] * e1) - offset[1]
    out[2] = mean[2] + (L[2, 0] * e0 + L[2, 1] * e1 + L[2, 2] * e2) - offset[2]
    out[3] = mean[3] + (L[3, 0] * e0 + L[3, 1] * e1 + L[3, 2] * e2 + L[3, 3] * e3) - offset[3]
    out[4] = (
        mean[4] + (L[4, 0] * e0 + L[4, 1] * e1 + L[4, 2] * e2 + L[4, 3] * e3 + L[4, 4] * e4)
        - offset[4]
    )  # fmt: skip
    out[5] = (
        mean[5] + (
            L[5, 0] * e0 + L[5, 1] * e1 + L[5, 2] * e2 + L[5, 3] * e3 + L[5, 4] * e4
            + L[5, 5] * e5
        ) - offset[5]
    )  # fmt: skip


@njit(fastmath=_CONTRACT)
def _draw_gaussian_call(
    key: np.uint64,
    particle: int,
    slot: int,
    mean: np.ndarray,
    L: np.ndarray,
    offset: np.ndarray,
    out: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """:func:`_draw_gaussian` compiled once, for the draws off the hot path (a drawn cloud,
    the navigation's noise): inlined everywhere it made the update's first compilation twice
    as long."""
    _draw_gaussian(key, particle, slot, mean, L, offset, out)


@njit(fastmath=_CONTRACT)
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
    target: np.ndarray,
    out_log_weights: np.ndarray,
    x: np.ndarray,
    P: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """One run of :func:`cloud_advance` from its cloud ``source`` (N×6, stored frame; the
    context's, read-only) or with ``use_drawn`` its ``drawn`` cloud (work space: one compiled
    function for both, the particles read through a branch), with
    log weights ``lw`` and their normalised ``weights`` (with ``have_moments``, their ``mean``
    and ``cov``; else those are work space): resampled and regularised when degenerate, moved
    into ``target``; ``lw`` and ``weights`` become the predicted ones."""
    n = source.shape[0]
    zero = np.zeros(6)
    shift = np.empty(6)
    shrink = math.sqrt(1.0 - bandwidth * bandwidth)
    squares = 0.0
    for i in range(n):
        squares += weights[i] * weights[i]
    resample = 1.0 / squares < resample_threshold * n
    if resample:
        if bandwidth > 0.0:  # the kernel's covariance: the cloud's before resampling
            if not have_moments:
                moments = np.empty((6, 6))
                if use_drawn:
                    _moments(drawn, zero, weights, mean, moments)
                else:
                    _moments(source, zero, weights, mean, moments)
                psd_factor(moments, L)
            else:
                psd_factor(cov, L)
            for k in range(6):
                for m in range(6):
                    L[k, m] *= bandwidth
            for k in range(6):
                shift[k] = (1.0 - shrink) * mean[k]
        # Systematic: particle j is copied ⌈N cdf_j − u⌉ − ⌈N cdf_{j−1} − u⌉ times.
        u = _uniform(key, _resampling_counter(n))
        cdf = 0.0
        filled = 0
        for j in range(n):
            cdf += weights[j]
            edge = n if j == n - 1 else min(max(int(math.ceil(cdf * n - u)), 0), n)
            while filled < edge:
                chosen[filled] = j
                filled += 1
        for i in range(n):
            lw[i] = -math.log(n)
            weights[i] = 1.0 / n
    jittered = False
    for k in range(6):
        for m in range(6):
            jittered |= jitter[k, m] != 0.0
    half = 0.5 * t * t
    p = np.empty(6)
    e = np.empty(6)
    for i in range(n):
        row = chosen[i] if resample else i
        if use_drawn:
            for k in range(6):
                p[k] = drawn[row, k]
        else:
            for k in range(6):
                p[k] = source[row, k]
        if resample and bandwidth > 0.0:
            _draw_gaussian(key, i, KERNEL_SLOT, shift, L, zero, e)
            for k in range(6):
                p[k] = e[k] + shrink * p[k]
        e0 = _normal(key, _slot(i, ACCELERATION_SLOT))
        e1 = _normal(key, _slot(i, ACCELERATION_SLOT + 1))
        e2 = _normal(key, _slot(i, ACCELERATION_SLOT + 2))
        u0 = W_factor[0, 0] * e0 + W_factor[0, 1] * e1 + W_factor[0, 2] * e2
        u1 = W_factor[1, 0] * e0 + W_factor[1, 1] * e1 + W_factor[1, 2] * e2
        u2 = W_factor[2, 0] * e0 + W_factor[2, 1] * e1 + W_factor[2, 2] * e2
        # The double integrator: q + t ϑ + ½t² (a − ū), ϑ + t (a − ū).
        target[i, 0] = (c[0] - half * u0) + (p[0] + t * p[3])
        target[i, 1] = (c[1] - half * u1) + (p[1] + t * p[4])
        target[i, 2] = (c[2] - half * u2) + (p[2] + t * p[5])
        target[i, 3] = (c[3] - t * u0) + p[3]
        target[i, 4] = (c[4] - t * u1) + p[4]
        target[i, 5] = (c[5] - t * u2) + p[5]
        if jittered:  # the navigation's process noise, a draw per particle
            _draw_gaussian_call(key, i, JITTER_SLOT, zero, jitter, zero, p)
            for k in range(6):
                target[i, k] += p[k]
    out_log_weights[:] = lw
    _moments(target, zero, weights, x, P)


@njit(cache=True)
def cloud_moments(
    particles: np.ndarray, log_weights: np.ndarray, offset: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """Each run's weighted mean and covariance of ``particles + offset`` (B×N×6, offset B×6)
    under its normalised ``log_weights`` (B×N): ``(B×6, B×6×6)``."""
    B, n = log_weights.shape
    x = np.empty((B, 6))
    P = np.empty((B, 6, 6))
    weights = np.empty(n)
    for b in range(B):
        _normalise(log_weights[b], weights)
        _moments(particles[b], offset[b], weights, x[b], P[b])
    return x, P
