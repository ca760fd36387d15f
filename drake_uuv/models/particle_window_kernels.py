"""One run's particle cloud stepped through a window step of late ranges, compiled.

The late-range path of :class:`~drake_uuv.estimators.particle_cloud.ParticleCloud`
(:mod:`drake_uuv.estimators.particle_window`) steps each run's cloud through the window's
steps; per step and instant it moves every particle to the ping time along its own path
(``G(τ) [xᵢ + jᵢ; uᵢ] + c``, its acceleration ``uᵢ`` and navigation noise ``jᵢ`` over the
step) and weighs it by the instant's ranges. These kernels fuse those passes over the N
particles (particles ``N×6`` as the state stores them, a particle's six values contiguous;
accelerations ``3×N`` and noise ``6×N`` as the window's slots store them): one pass to move
(:func:`move_into`), the prior's weighted mean (:func:`prior_mean`, for the error model's
noise at it), the weighing (:func:`weigh`, of
:func:`~drake_uuv.models.particle_kernels.weigh_into`), the posterior's moments
(:func:`moments`).

Each kernel reads one run's arrays only and sums in its loop's order (products may fuse into
FMAs: :data:`~drake_uuv.models.particle_kernels.CONTRACT`), so a run's bits are the same alone
and in any batch on a given machine; NaN propagates without raising.
"""

import numpy as np
from numba import njit

from drake_uuv.models.particle_kernels import (
    CONTRACT,
    _mean_into,
    moments_into,
    normalise_into,
    weigh_into,
)


@njit(cache=True, fastmath=CONTRACT)
def move_into(
    particles: np.ndarray,
    jitter: np.ndarray,
    u: np.ndarray,
    tau: float,
    c: np.ndarray,
    out: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """Every particle ``xᵢ = [q, ϑ] + jᵢ`` moved over ``τ`` by its acceleration ``uᵢ``:
    ``[q + τ ϑ − ½τ² uᵢ, ϑ − τ uᵢ] + c``, i.e. ``G(τ) [xᵢ; uᵢ] + c`` with
    :func:`~drake_uuv.models.timing.transition`'s ``G = [Φ(τ), −B(τ)]`` of the double
    integrator, written out (``particles``, ``out`` N×6; ``jitter`` 6×N, or 0×N for none;
    ``u`` 3×N): :func:`move_resampled_into` of the particles' columns, none resampled."""
    move_resampled_into(particles.T, np.empty(0, dtype=np.int64), jitter, u, tau, c, out)


@njit(cache=True, fastmath=CONTRACT)
def move_resampled_into(
    particles: np.ndarray,
    chosen: np.ndarray,
    jitter: np.ndarray,
    u: np.ndarray,
    tau: float,
    c: np.ndarray,
    out: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """The periodic update's move: :func:`move_into` of the resampled ``particles`` (6×N
    columns), each with its ancestor's (``chosen``, N; empty: itself) navigation noise
    (``jitter``, 6×N, or 0×N) and acceleration (``u``, 3×N), into ``out`` (N×6)."""
    n = particles.shape[1]
    picked = chosen.shape[0] == n
    noisy = jitter.shape[0] == 6
    half = 0.5 * tau * tau
    for i in range(n):
        j = chosen[i] if picked else i
        for k in range(3):
            # Values, not a helper taking the arrays: a compiled function that takes arrays
            # and branches keeps their reference counts on every call (10x the arithmetic).
            q, v = particles[k, i], particles[3 + k, i]
            if noisy:
                q += jitter[k, j]
                v += jitter[3 + k, j]
            a = u[k, j]
            out[i, k] = q + tau * v - half * a + c[k]
            out[i, 3 + k] = v - tau * a + c[3 + k]


@njit(cache=True, fastmath=CONTRACT)
def prior_mean(
    particles: np.ndarray,
    offset: np.ndarray,
    log_weights: np.ndarray,
    prior: np.ndarray,
    mean: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """The normalised weights of ``log_weights`` in ``prior`` (N) and the weighted mean of
    ``particles + offset`` (N×6, 6) under them in ``mean`` (6)."""
    normalise_into(log_weights, prior)
    _mean_into(particles, offset, prior, mean)


@njit(cache=True, fastmath=CONTRACT)
def weigh(
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
    """:func:`~drake_uuv.models.particle_kernels.weigh_into` of ``particles + offset`` (N×6,
    in the frame of ``z`` and ``q_s``; ``prior`` the normalised weights of ``log_weights``):
    the normalised posterior log weights in ``out``, their weights in ``posterior``; returns
    the NIS. ``ranges`` (N×2) is work space."""
    return weigh_into(
        particles, offset, log_weights, prior, z, used, q_s, R, ranges, out, posterior
    )


@njit(cache=True, fastmath=CONTRACT)
def moments(
    particles: np.ndarray,
    offset: np.ndarray,
    log_weights: np.ndarray,
    weights: np.ndarray,
    x: np.ndarray,
    P: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """The weighted mean and covariance of ``particles + offset`` (N×6, 6) under the
    normalised ``log_weights`` in ``x`` (6) and ``P`` (6×6); ``weights`` (N) is work space."""
    normalise_into(log_weights, weights)
    moments_into(particles, offset, weights, x, P)
