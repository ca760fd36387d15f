"""The particle filter's steps over a batch of runs, compiled: B runs of N particles each.

:mod:`drake_uuv.models.particle_filter` states the filter as numpy on one 6×N cloud; this
module steps ``B`` clouds at once, each in one pass of a loop over its particles, so that the
many numpy passes over a cloud (about 40 a step, each a fresh trip through memory) become a few
fused ones and the cost of a call is shared by the batch. The layout: particles ``(B, N, 6)``
(each particle's six values contiguous), log weights ``(B, N)``. Each run's numbers are
computed by the same loop whatever B is and read nothing of another run, so a run's bits do
not depend on its batch; a run whose cloud holds NaN yields NaN, raises nothing and touches
no other run.

Randomness: the counter-based draws of :mod:`drake_uuv.models.particle_random`, keyed per
run and step, a particle's draws from its own slots.

Arithmetic: products and sums may fuse into FMA instructions (numba's ``fastmath`` flag
``contract`` alone: no reassociation), so each sum runs in its loop's order and a run's bits
are the same in any batch on a given machine. The model is the package's double integrator,
written out (``q + t ϑ``, not a 6×6 product).

The periodic update (resampling, regularisation, the move) is
:func:`drake_uuv.models.particle_advance.cloud_advance`; this module holds the measurement
update and the pieces both use.

Cost (N = 5000, the kernels alone, 4 runs a call, a loaded 2-core machine): the measurement
update about 95 µs, the periodic update about 95 µs, 245 µs when it resamples and regularises,
365 µs with the navigation's noise too (numpy's resampling prediction,
:func:`~drake_uuv.models.particle_filter.pf_predict`, about 1000 µs there).
"""

import math

import numpy as np
from numba import njit

from drake_uuv.models.particle_filter import TEMPERING_FLOOR

# Products and sums may fuse into FMAs (the same instructions for every run and batch); no
# other reordering, so each sum still runs in the loop's order.
CONTRACT = {"contract"}


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
def normalise_into(log_weights: np.ndarray, weights: np.ndarray) -> None:  # pragma: no cover
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


@njit(fastmath=CONTRACT)
def _mean_into(
    particles: np.ndarray, offset: np.ndarray, weights: np.ndarray, x: np.ndarray
) -> None:  # pragma: no cover - compiled
    """The weighted mean of ``particles + offset`` (weights sum to 1) in ``x``."""
    o0, o1, o2, o3, o4, o5 = offset[0], offset[1], offset[2], offset[3], offset[4], offset[5]
    m0 = m1 = m2 = m3 = m4 = m5 = 0.0
    for i in range(particles.shape[0]):
        w = weights[i]
        m0 += w * (particles[i, 0] + o0)
        m1 += w * (particles[i, 1] + o1)
        m2 += w * (particles[i, 2] + o2)
        m3 += w * (particles[i, 3] + o3)
        m4 += w * (particles[i, 4] + o4)
        m5 += w * (particles[i, 5] + o5)
    x[0], x[1], x[2], x[3], x[4], x[5] = m0, m1, m2, m3, m4, m5


@njit(fastmath=CONTRACT)
def moments_into(
    particles: np.ndarray, offset: np.ndarray, weights: np.ndarray, x: np.ndarray, P: np.ndarray
) -> None:  # pragma: no cover - compiled
    """Weighted mean and covariance of ``particles + offset`` (weights sum to 1), two passes.
    The sums are scalars, not array entries, so that they stay in registers."""
    _mean_into(particles, offset, weights, x)
    n = particles.shape[0]
    o0, o1, o2, o3, o4, o5 = offset[0], offset[1], offset[2], offset[3], offset[4], offset[5]
    m0, m1, m2, m3, m4, m5 = x[0], x[1], x[2], x[3], x[4], x[5]
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
    P[1, 0], P[1, 1] = c10, c11
    P[2, 0], P[2, 1], P[2, 2] = c20, c21, c22
    P[3, 0], P[3, 1], P[3, 2], P[3, 3] = c30, c31, c32, c33
    P[4, 0], P[4, 1], P[4, 2], P[4, 3], P[4, 4] = c40, c41, c42, c43, c44
    P[5, 0], P[5, 1], P[5, 2], P[5, 3], P[5, 4], P[5, 5] = c50, c51, c52, c53, c54, c55
    for k in range(6):
        for m in range(k):
            P[m, k] = P[k, m]


@njit
def _normalise_log_into(log_weights: np.ndarray, weights: np.ndarray) -> None:  # pragma: no cover
    """``log_weights`` less their log-sum-exp (in place), and their weights (sum 1) in
    ``weights``: one exponential per particle for both."""
    n = log_weights.shape[0]
    top = log_weights[0]
    bad = False
    for i in range(n):
        top = max(top, log_weights[i])
        bad |= log_weights[i] != log_weights[i]
    if bad:
        top = math.nan
    total = 0.0
    for i in range(n):
        w = math.exp(log_weights[i] - top)
        weights[i] = w
        total += w
    norm = top + math.log(total)
    scale = 1.0 / total
    for i in range(n):
        log_weights[i] -= norm
        weights[i] *= scale


@njit(fastmath=CONTRACT)
def weigh_into(
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
    ``ranges`` (N×2) is work space. No sonar used: ``out`` the log weights, NIS NaN.

    A posterior that keeps fewer than :data:`TEMPERING_FLOOR` particles (a cloud drawn from
    a loose Gaussian meeting precise ranges: a handful of 5000 particles fall inside the
    ranges' shell, the weighted covariance loses rank and the run is lost) is tempered to keep
    that many (:func:`_temper_into`): the cloud keeps its diversity and takes the rest of the
    ranges' information over the next steps. ``out`` must not be ``log_weights``."""
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
    _normalise_log_into(out, posterior)
    if effective_sample_size(posterior) < TEMPERING_FLOOR:
        _temper_into(log_weights, out, posterior)
    return nis


@njit(fastmath=CONTRACT)
def effective_sample_size(weights: np.ndarray) -> float:  # pragma: no cover - compiled
    """``1 / Σ w²`` of normalised weights (NaN weights: NaN): the measurement update's
    tempering test and the periodic updates' resampling test."""
    squares = 0.0
    for i in range(weights.shape[0]):
        squares += weights[i] * weights[i]
    return 1.0 / squares


@njit
def _tempered_size(log_weights: np.ndarray, log_posterior: np.ndarray, power: float) -> float:
    """The effective sample size of ``log_weights + power · ℓ`` with ``ℓ`` the likelihood
    ``log_posterior − log_weights`` (a particle of zero prior weight keeps none)."""
    n = log_weights.shape[0]
    top = -math.inf
    for i in range(n):
        if log_weights[i] > -math.inf:
            top = max(top, log_weights[i] + power * (log_posterior[i] - log_weights[i]))
    total = squares = 0.0
    for i in range(n):
        if log_weights[i] > -math.inf:
            w = math.exp(log_weights[i] + power * (log_posterior[i] - log_weights[i]) - top)
            total += w
            squares += w * w
    return total * total / squares


@njit
def _temper_into(
    log_weights: np.ndarray, log_posterior: np.ndarray, posterior: np.ndarray
) -> None:  # pragma: no cover - compiled
    """Replaces a posterior that kept fewer than :data:`TEMPERING_FLOOR` particles by the
    prior times the likelihood to the largest power ``λ ≤ 1`` that keeps that many (bisection,
    40 halvings), when the prior itself keeps them: ``log_posterior`` and ``posterior``
    rewritten, normalised. A prior below the floor is left to the likelihood (tempering could
    not restore it). One stage of Oudjane & Musso's progressive correction ("Progressive
    correction for regularized particle filters", FUSION 2000): the rest of the likelihood is
    not applied at this tick; the next ticks' ranges carry the same information."""
    if not _tempered_size(log_weights, log_posterior, 0.0) >= TEMPERING_FLOOR:
        return
    low, high = 0.0, 1.0
    for _ in range(40):
        middle = 0.5 * (low + high)
        if _tempered_size(log_weights, log_posterior, middle) >= TEMPERING_FLOOR:
            low = middle
        else:
            high = middle
    for i in range(log_weights.shape[0]):
        if log_weights[i] > -math.inf:
            log_posterior[i] = log_weights[i] + low * (log_posterior[i] - log_weights[i])
        else:
            log_posterior[i] = -math.inf
    _normalise_log_into(log_posterior, posterior)


@njit(cache=True, fastmath=CONTRACT)
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
        normalise_into(log_weights[b], prior)
        nis[b] = weigh_into(
            particles[b], offset[b], log_weights[b], prior, z[b], used[b], q_s[b], R[b], ranges,
            log_posterior[b], posterior_weights[b],
        )  # fmt: skip
        moments_into(particles[b], offset[b], posterior_weights[b], x[b], P[b])


@njit(cache=True)
def cloudmoments_into(
    particles: np.ndarray, log_weights: np.ndarray, offset: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """Each run's weighted mean and covariance of ``particles + offset`` (B×N×6, offset B×6)
    under its normalised ``log_weights`` (B×N): ``(B×6, B×6×6)``."""
    B, n = log_weights.shape
    x = np.empty((B, 6))
    P = np.empty((B, 6, 6))
    weights = np.empty(n)
    for b in range(B):
        normalise_into(log_weights[b], weights)
        moments_into(particles[b], offset[b], weights, x[b], P[b])
    return x, P
