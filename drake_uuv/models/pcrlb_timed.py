"""The per-run PCRLB with each range at its ping time, counted once it has arrived.

Extends the recursion of :mod:`drake_uuv.models.pcrlb` (Tichavský, Muravchik, Nehorai 1998)
to sonars that ping between ticks and ranges that reach the estimator late. The recursion is a
compiled loop over runs and steps (:mod:`drake_uuv.models.pcrlb_timed_kernels`: numpy's cost
per call would dominate its small matrices); the rest is numpy.

Ranges at their ping times
--------------------------
The paper's model holds each step's accelerations constant (the vehicle's ``a_k = R u1(k)``
and the target's ``ū_k``), so the relative state at ``t_k + τ``, ``0 ≤ τ < t``, is::

    x(τ) = Φ(τ) x_k + B(τ)(a_k − ū_k),   Φ(τ) = [[I, τI], [0, I]],   B(τ) = [[τ²/2 I], [τ I]]

and ``x_{k+1} = x(t)``. Step k's pings measure the *augmented* state ``z = [x_k, ū_k]`` (9),
whose prior is ``blkdiag(P⁻_k, W_k)`` (``ū_k`` is independent of everything before it). A
ping of sonar i at ``τ`` with unit line of sight ``u_i`` (from the target to the sonar at the
ping) has the row ``h = u_iᵀ [I, 0] G(τ) = [u_iᵀ, τ u_iᵀ, −½τ² u_iᵀ]``, ``G(τ) = [Φ(τ),
−B(τ)]``; the known ``a_k`` does not enter the information. With ``R_k`` the 2×2 covariance
of the step's two range errors (the cross term carries a noise both share), the step's exact
information on ``z`` is ``Hᵀ R_k⁻¹ H`` over the pings counted, and::

    P_z      = (blkdiag(P⁻_k, W_k)⁻¹ + Hᵀ R_k⁻¹ H)⁻¹
    P⁻_{k+1} = G(t) P_z G(t)ᵀ + blkdiag(σ²_p,k I, 0)

(``σ²_p,k``: a position process noise of the step, the dead-reckoned vehicle's). With every
ping at ``τ = 0`` the information sits in the ``x_k`` block, ``P_z`` is block diagonal and
this is the recursion of :func:`~drake_uuv.models.pcrlb.pcrlb_recursion`
(``P⁻_{k+1} = A P_k Aᵀ + B W Bᵀ``) to rounding.

Latency
-------
A ping of step k that arrives at tick ``k + d`` informs the estimate at tick j only if
``d ≤ j − k``. Every ping of the run arrives within ``D = max d`` ticks, so steps
``k ≤ j − D`` are *complete* at tick j: the bound at j is the recursion over all complete
steps (one run, shared by every tick), fast-forwarded through steps ``j − D .. j − 1`` with
only the pings that have arrived by j, then the tick's own update with its pings at
``τ = 0`` that arrive at once (``d = 0``). Step ``j − D`` is complete at j, so the
fast-forward starts from the complete recursion's ``P⁻_{j−D+1}``: ``D − 1`` steps a tick
(none without latency). ``D`` is each run's own.
"""

from __future__ import annotations

import numpy as np

from drake_uuv.models.measurement import MIN_RANGE
from drake_uuv.models.pcrlb import symmetrise
from drake_uuv.models.pcrlb_timed_kernels import timed_bound_kernel


def ping_rows(tau: np.ndarray, los: np.ndarray) -> np.ndarray:
    """The rows ``h = [uᵀ, τ uᵀ, −½τ² uᵀ]`` (…×9) of pings at ``tau`` (…) on ``z = [x_k, ū_k]``.

    ``los`` (…×3) are the unit lines of sight ``u``: ``∂|p_TS|/∂q`` at the ping's geometry.
    """
    tau = np.asarray(tau, dtype=float)[..., np.newaxis]
    u = np.asarray(los, dtype=float)
    return np.concatenate([u, tau * u, -0.5 * tau * tau * u], axis=-1)


def _check(
    tau: np.ndarray, lag: np.ndarray, time_step: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Checks the pings' timing (…×N×2); returns which pings arrive, the lags as ints (0
    where absent) and each run's window ``D`` (…)."""
    if tau.ndim < 2 or tau.shape[-1] != 2:
        raise ValueError(f"tau must have shape (N, 2) or (B, N, 2), got {tau.shape}")
    lag = np.asarray(lag)
    if lag.shape != tau.shape:
        raise ValueError(f"lag shape {lag.shape} differs from tau shape {tau.shape}")
    present = np.isfinite(tau)
    lags = np.where(present, lag, 0).astype(np.int64)
    if np.any(present & ((tau < 0.0) | (tau >= time_step))):
        raise ValueError(f"tau must be in [0, time_step = {time_step:g}), got {tau[present]}")
    if np.any(lags < 0):
        raise ValueError(f"lag must be ≥ 0, got {lags.min()}")
    if np.any(present & (tau > 0.0) & (lags == 0)):
        raise ValueError("a ping at tau > 0 cannot arrive at its own step's tick (lag 0)")
    return present, lags, lags.max(axis=(-2, -1), initial=0)


def _per_step(value: np.ndarray, shape: tuple[int, ...], variances: bool = False) -> np.ndarray:
    """A 3×3 covariance for each step of each run (…×N×3×3, C-contiguous) from one 3×3, one a
    step (N×3×3) or one a step of each run; with ``variances``, a scalar or N per-axis
    variances."""
    value = np.asarray(value, dtype=float)
    if variances and value.ndim < 2:
        value = value[..., None, None] * np.eye(3)
    return _owned(value, (*shape, 3, 3))


def _owned(value: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """``value`` broadcast to ``shape``, as a new C-contiguous writable array (one type for
    the kernel whatever the caller passed: one compiled version)."""
    return np.array(np.broadcast_to(value, shape), dtype=float, order="C")


def pcrlb_timed(
    tau: np.ndarray,
    lag: np.ndarray,
    p_TS: np.ndarray,
    noise: np.ndarray,
    P0: np.ndarray,
    W: np.ndarray,
    time_step: float,
    position_noise: np.ndarray | float = 0.0,
) -> np.ndarray:
    """The bound (N×6×6) on the estimate at each tick from the ranges arrived by then.

    ``tau`` (N×2) is each sonar's ping offset in its step [s] (NaN: no range of that ping
    ever arrives, e.g. dropped), ``lag`` (N×2, int) its arrival tick minus k, ``p_TS``
    (N×2×3) its sonar's position relative to the target at the ping (the range is its norm),
    ``noise`` (N×2×2) the covariance of the step's two range errors (sonar i of step k in
    entry ``[k, i]``); ``P0`` (6×6) the prior ``P(0|−1)``; ``W`` (3×3, or N×3×3 per step)
    the covariance of the step's unknown acceleration; ``position_noise`` a position
    covariance added over each step: a per-axis variance (scalar, or N per step) or a 3×3
    matrix (or N×3×3 per step). See the module docstring.

    A step's information on its ``z`` is ``Hᵀ R⁻¹ H`` over the pings counted: a subset of the
    two pings has the information of its own rows and the marginal of ``noise``.

    Runs: ``tau``, ``lag``, ``p_TS``, ``noise`` with a leading run axis (B×N×…; ``W`` and
    ``position_noise`` as above, or a 3×3 matrix per step of each run, B×N×3×3) give each
    run's bound (B×N×6×6), each the same bits as alone. The recursion is compiled
    (:mod:`drake_uuv.models.pcrlb_timed_kernels`); a run whose matrix to invert is not
    positive definite (NaN in its trajectory) is NaN from that step on.
    """
    tau = np.asarray(tau, dtype=float)
    present, lags, windows = _check(tau, lag, time_step)
    steps = tau.shape[-2]
    p_TS = np.where(present[..., None], np.asarray(p_TS, dtype=float), 1.0)
    los = p_TS / np.maximum(np.linalg.norm(p_TS, axis=-1, keepdims=True), MIN_RANGE)
    rows = np.where(present[..., None], ping_rows(np.where(present, tau, 0.0), los), 0.0)
    shape = tau.shape[:-1]
    bounds = np.empty((*shape, 6, 6))
    timed_bound_kernel(
        np.ascontiguousarray(rows).reshape(-1, steps, 2, 9),
        _owned(noise, (*shape, 2, 2)).reshape(-1, steps, 2, 2),
        np.ascontiguousarray(present).reshape(-1, steps, 2),
        np.ascontiguousarray(lags).reshape(-1, steps, 2),
        np.ascontiguousarray(windows).reshape(-1),
        symmetrise(np.asarray(P0, dtype=float).reshape(6, 6)),
        _per_step(W, shape).reshape(-1, steps, 3, 3),
        _per_step(position_noise, shape, variances=True).reshape(-1, steps, 3, 3),
        float(time_step),
        bounds.reshape(-1, steps, 6, 6),
    )
    return bounds
