"""The marginalised (Rao-Blackwellised) particle filter's periodic update, compiled: B runs of N
particles, each carrying the relative position ``q`` and the mean ``m`` of the velocity given
its position track, with one conditional velocity covariance ``Σ`` per run.

The model (Schön, Gustafsson & Nordlund 2005, "Marginalized particle filters for mixed
linear/nonlinear state-space models", IEEE TSP 53(7), the case where the nonlinear state's
dynamics are linear in the linear state): in the stored frame
``q' = q + t v + c_q + n_q``, ``v' = v + c_v + n_v`` with ``c_q = t²/2 a``, ``c_v = t a`` and
``[n_q, n_v] ~ N(0, Q)``, ``Q = B W Bᵀ`` (plus the navigation's process noise, when modelled);
the ranges depend on ``q`` only. Given a particle's position track its velocity is
linear-Gaussian, ``v ~ N(m, Σ)``; ``Σ`` depends on the model alone, the same for every particle.
One step of a particle (:func:`marginal_gain`, then the move of :func:`marginalized_advance`):

* ``q' ~ N(q + t m + c_q, S)``, ``S = t² Σ + Q_qq``, drawn as ``q' = q + t m + c_q + L e``
  (``L Lᵀ = S``, ``e`` three normals of the particle's acceleration slots);
* the velocity's Kalman update on ``z = q' − q − c_q``, which the draw makes
  ``z − t m = L e``: ``m' = m + c_v + C S⁻¹ L e = m + c_v + K e`` with ``C = t Σ + Q_vq`` and
  ``K = C L⁻ᵀ``; ``Σ' = Σ + Q_vv − C S⁻¹ Cᵀ = Σ + Q_vv − K Kᵀ``.

(With ``Q = B W Bᵀ``: ``S = t² Σ + t⁴/4 W``, ``C = t Σ + t³/2 W``, ``Σ' = Σ + t² W − C S⁻¹ Cᵀ``.)
:func:`condition_on_track` is the same update given ``q'`` (a Kalman filter's measurement of
the position, exact): the tests hold the kernel to a Kalman filter on the true track.

The rest is the particle filter's own (:mod:`~drake_uuv.models.particle_advance`): the weights
(the ranges' likelihood of ``q``, :func:`~drake_uuv.models.particle_kernels.weigh_into`),
systematic resampling carrying ``[q, m]``, the shrinkage kernel on the ``[q, m]`` cloud
(``bandwidth`` 0: none), and the draws (:mod:`~drake_uuv.models.particle_random`: the initial
draw from the draw slot, the move's three normals from the acceleration slots, so that a
particle's draws are those of the particle filter's particle of the same index and key).

A drawn cloud (a run entering its particles from a Gaussian ``N(x, P)``): ``q`` from the
position's marginal, ``m = E[v | q]`` and ``Σ = P_vv − P_vq P_qq⁻¹ P_qv``: with ``L`` the
factor of ``P``, the particle filter's draw with ``L_vv`` set to zero, and ``Σ = L_vv L_vvᵀ``.
"""

import math

import numpy as np
from numba import njit

from drake_uuv.models.particle_advance import (
    _kernel_from_range_bearing,
    _prepare_resampling,
    _range_bearing_cloud,
    _six,
    gaussian_draw,
    lower_entries,
    starting_weights,
)
from drake_uuv.models.particle_kernels import (
    CONTRACT,
    effective_sample_size,
    moments_into,
    normalise_into,
    psd_factor,
)
from drake_uuv.models.particle_random import (
    ACCELERATION_SLOT,
    DRAW_SLOT,
    KERNEL_SLOT,
    normal,
    slot_counter,
)


@njit(cache=True, fastmath=CONTRACT, error_model="numpy")
def marginal_gain(
    Sigma: np.ndarray, t: float, Q: np.ndarray, L: np.ndarray, K: np.ndarray, Sigma_next: np.ndarray
) -> None:  # pragma: no cover - compiled
    """The step's gains for the conditional covariance ``Sigma`` (3×3) and process noise ``Q``
    (6×6, ``[q, v]``): ``L`` the lower factor of ``S = t² Σ + Q_qq``, ``K = C L⁻ᵀ`` with
    ``C = t Σ + Q_vq``, ``Sigma_next = Σ + Q_vv − K Kᵀ`` (each 3×3, written). NaN in: NaN out."""
    S = np.empty((3, 3))
    C = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            S[i, j] = t * t * Sigma[i, j] + Q[i, j]
            C[i, j] = t * Sigma[i, j] + Q[3 + i, j]
    psd_factor(S, L)
    # K Lᵀ = C: row i of K solves L kᵢ = cᵢ (forward substitution).
    for i in range(3):
        for j in range(3):
            s = C[i, j]
            for k in range(j):
                s -= L[j, k] * K[i, k]
            K[i, j] = s / L[j, j]
    for i in range(3):
        for j in range(3):
            s = Sigma[i, j] + Q[3 + i, 3 + j]
            for k in range(3):
                s -= K[i, k] * K[j, k]
            Sigma_next[i, j] = s
    for i in range(3):  # exactly symmetric
        for j in range(i):
            mean = 0.5 * (Sigma_next[i, j] + Sigma_next[j, i])
            Sigma_next[i, j] = mean
            Sigma_next[j, i] = mean


@njit(cache=True, fastmath=CONTRACT, error_model="numpy")
def condition_on_track(
    q: np.ndarray,
    m: np.ndarray,
    Sigma: np.ndarray,
    q_next: np.ndarray,
    acceleration: np.ndarray,
    t: float,
    Q: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """One particle's velocity update given its next position ``q_next`` (3 each; ``Sigma``
    3×3, ``Q`` 6×6): ``(m', Σ')``, the Kalman filter's on ``z = q' − q − t²/2 a``."""
    L, K, Sigma_next = np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3))
    marginal_gain(Sigma, t, Q, L, K, Sigma_next)
    e = np.empty(3)
    for j in range(3):  # L e = z − t m
        s = q_next[j] - q[j] - 0.5 * t * t * acceleration[j] - t * m[j]
        for k in range(j):
            s -= L[j, k] * e[k]
        e[j] = s / L[j, j]
    m_next = np.empty(3)
    for i in range(3):
        m_next[i] = (t * acceleration[i] + (K[i, 0] * e[0] + K[i, 1] * e[1] + K[i, 2] * e[2])) + m[
            i
        ]
    return m_next, Sigma_next


@njit(cache=True, fastmath=CONTRACT, error_model="numpy")
def marginalized_advance(
    particles: np.ndarray,
    log_weights: np.ndarray,
    Sigma: np.ndarray,
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
    Q: np.ndarray,
    resample_threshold: float,
    bandwidth: float,
    range_bearing: bool,
    out: np.ndarray,
    out_log_weights: np.ndarray,
    out_Sigma: np.ndarray,
    x: np.ndarray,
    P: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """:func:`~drake_uuv.models.particle_advance.cloud_advance` (the same arguments) with
    particles ``[q, m]`` (B×N×6) and each run's ``Sigma`` (B×3×3; a ``drawn`` run draws both
    from ``N(draw_x, draw_P)``), ``posterior_P`` without ``Σ``, ``Q`` (B×6×6) the process
    noise; writes ``out_Sigma`` (``Σ'``) too, and ``P`` with ``Σ'`` in its velocity block."""
    B, n = log_weights.shape
    weights, lw, chosen = np.empty(n), np.empty(n), np.empty(n, dtype=np.int64)
    ranges, drawn_cloud = np.empty((n, 2)), np.empty((n, 6))
    L, mean, c = np.empty((6, 6)), np.empty(6), np.empty(6)
    L_S, K, Sig = np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3))
    local = np.empty((n if range_bearing else 0, 6))
    for b in range(B):
        if not moving[b]:
            x[b, :] = math.nan
            P[b, :, :] = math.nan
            continue
        key = keys[b]
        for k in range(3):
            c[k] = 0.5 * time_step * time_step * acceleration[b, k]
            c[k + 3] = time_step * acceleration[b, k]
        for i in range(3):
            for j in range(3):
                Sig[i, j] = Sigma[b, i, j]
        if drawn[b]:
            _draw_marginal(key, draw_x[b], draw_P[b], offset[b], L, drawn_cloud, lw, weights, Sig)
        known = starting_weights(
            b, drawn, weigh_draw, reweigh, drawn_cloud, offset, z, used, q_s, R, ranges,
            log_weights, posterior_log_weights, posterior_weights, posterior_x, lw, weights, mean,
        )  # fmt: skip
        cov = posterior_P[b] if known else P[b]  # P[b] is work space without the moments
        marginal_gain(Sig, time_step, Q[b], L_S, K, out_Sigma[b])
        _move_run(
            particles[b], drawn_cloud, drawn[b], lw, weights, known, mean, cov, key, chosen, L, c,
            time_step, L_S, K, resample_threshold, bandwidth, range_bearing, offset[b], local,
            out[b], out_log_weights[b], x[b],
            P[b],
        )  # fmt: skip
        for i in range(3):
            for j in range(3):
                P[b, 3 + i, 3 + j] += out_Sigma[b, i, j]


@njit(fastmath=CONTRACT)
def _draw_marginal(
    key: np.uint64,
    mean: np.ndarray,
    cov: np.ndarray,
    offset: np.ndarray,
    L: np.ndarray,
    out: np.ndarray,
    lw: np.ndarray,
    weights: np.ndarray,
    Sigma: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """N draws of ``[q, E[v | q]]`` under ``N(mean, cov)``, less ``offset``, in ``out`` (N×6),
    equally weighted, and the conditional covariance in ``Sigma``; ``L`` work space."""
    psd_factor(cov, L)
    for i in range(3):
        for j in range(3):
            s = 0.0
            for k in range(3):
                s += L[3 + i, 3 + k] * L[3 + j, 3 + k]
            Sigma[i, j] = s
    for i in range(3):
        for j in range(3):
            L[3 + i, 3 + j] = 0.0
    n = out.shape[0]
    m, factor = _six(mean), lower_entries(L)
    for i in range(n):
        d = gaussian_draw(key, i, DRAW_SLOT, m, factor)
        for k in range(6):
            out[i, k] = d[k] - offset[k]
        lw[i] = -math.log(n)
    normalise_into(lw, weights)


@njit(fastmath=CONTRACT)
def _move_run(
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
    L_S: np.ndarray,
    K: np.ndarray,
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
    """One run of :func:`marginalized_advance`: resampled when degenerate (ancestors and the
    shrinkage kernel as the particle filter's, with ``range_bearing`` in range–bearing
    coordinates in ``local`` where it can), each particle's ``q`` drawn and ``m`` conditioned
    on the draw, into ``target``; ``lw``, ``weights`` become the predicted ones."""
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
            lw[i] = -math.log(n)
            weights[i] = 1.0 / n
    p, e = np.empty(6), np.empty(6)
    cloud = drawn if use_drawn else source
    kernel_mean, kernel_factor = _six(shift), lower_entries(L)
    for i in range(n):
        # As the particle filter's _advance_run, written out on purpose: one helper for both,
        # taking the cloud's arrays, measured 19 -> 53 ns a particle (see gaussian_draw).
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
        for k in range(3):
            target[i, k] = (c[k] + (L_S[k, 0] * e0 + L_S[k, 1] * e1 + L_S[k, 2] * e2)) + (
                p[k] + t * p[k + 3]
            )
            target[i, k + 3] = (c[k + 3] + (K[k, 0] * e0 + K[k, 1] * e1 + K[k, 2] * e2)) + p[k + 3]
    out_log_weights[:] = lw
    moments_into(target, zero, weights, x, P)
