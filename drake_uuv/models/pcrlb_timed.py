"""The per-run PCRLB with each range at its ping time, counted once it has arrived.

Pure numpy; extends the recursion of :mod:`drake_uuv.models.pcrlb` (Tichavský, Muravchik,
Nehorai 1998) to sonars that ping between ticks and ranges that reach the estimator late.

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
``τ = 0`` that arrive at once (``d = 0``). The fast-forward runs for all ticks at once, ``D``
batched steps.
"""

from __future__ import annotations

import numpy as np

from drake_uuv.models.measurement import MIN_RANGE
from drake_uuv.models.pcrlb import symmetrise


def ping_rows(tau: np.ndarray, los: np.ndarray) -> np.ndarray:
    """The rows ``h = [uᵀ, τ uᵀ, −½τ² uᵀ]`` (…×9) of pings at ``tau`` (…) on ``z = [x_k, ū_k]``.

    ``los`` (…×3) are the unit lines of sight ``u``: ``∂|p_TS|/∂q`` at the ping's geometry.
    """
    tau = np.asarray(tau, dtype=float)[..., np.newaxis]
    u = np.asarray(los, dtype=float)
    return np.concatenate([u, tau * u, -0.5 * tau * tau * u], axis=-1)


def step_transition(tau: float) -> np.ndarray:
    """``G(τ) = [Φ(τ), −B(τ)]`` (6×9): ``x(τ) = G(τ) z + B(τ) a_k`` for ``z = [x_k, ū_k]``."""
    G = np.zeros((6, 9))
    G[:, :6] = np.eye(6)
    G[:3, 3:6] = tau * np.eye(3)
    G[:3, 6:] = -0.5 * tau * tau * np.eye(3)
    G[3:, 6:] = -tau * np.eye(3)
    return G


def ping_information(
    tau: np.ndarray, lag: np.ndarray, p_TS: np.ndarray, noise: np.ndarray, window: int
) -> np.ndarray:
    """Each step's information on its ``z`` (N × (window+1) × 9 × 9), by arrival lag.

    Entry ``[k, ℓ]`` is ``Hᵀ R⁻¹ H`` over the pings of step k that arrive within ``ℓ`` ticks
    (``lag ≤ ℓ``); ``ℓ = window`` counts all of them. ``tau`` (N×2) is each sonar's ping
    offset in its step (NaN: no range of that ping ever arrives, e.g. dropped), ``lag``
    (N×2, int) its arrival tick minus k, ``p_TS`` (N×2×3) its sonar's position relative to
    the target at the ping (the range is its norm), ``noise`` (N×2×2) the covariance of the
    step's two range errors. A subset of the two pings has the
    information of its own rows and the marginal of ``noise``: the absent ping's row is
    zeroed and its noise decoupled (unit variance, no cross term).
    """
    tau = np.asarray(tau, dtype=float)
    present = np.isfinite(tau)
    p_TS = np.where(present[..., None], p_TS, 1.0)
    los = p_TS / np.maximum(np.linalg.norm(p_TS, axis=-1, keepdims=True), MIN_RANGE)
    rows = ping_rows(np.where(present, tau, 0.0), los)
    noise = np.asarray(noise, dtype=float)
    out = np.empty((tau.shape[0], window + 1, 9, 9))
    for ell in range(window + 1):
        counted = present & (np.asarray(lag) <= ell)
        h = np.where(counted[..., None], rows, 0.0)
        both = counted[:, :, None] & counted[:, None, :]
        R = np.where(both, noise, np.eye(2))
        out[:, ell] = np.swapaxes(h, -1, -2) @ np.linalg.solve(R, h)
    return out


def _check(tau: np.ndarray, lag: np.ndarray, time_step: float) -> tuple[np.ndarray, int]:
    """Checks the pings' timing; returns the lags as ints and the window ``D``."""
    tau = np.asarray(tau, dtype=float)
    if tau.ndim != 2 or tau.shape[1] != 2:
        raise ValueError(f"tau must have shape (N, 2), got {tau.shape}")
    lag = np.asarray(lag)
    if lag.shape != tau.shape:
        raise ValueError(f"lag shape {lag.shape} differs from tau shape {tau.shape}")
    present = np.isfinite(tau)
    lags = np.where(present, lag, 0).astype(int)
    if np.any(present & ((tau < 0.0) | (tau >= time_step))):
        raise ValueError(f"tau must be in [0, time_step = {time_step:g}), got {tau[present]}")
    if np.any(lags < 0):
        raise ValueError(f"lag must be ≥ 0, got {lags.min()}")
    if np.any(present & (tau > 0.0) & (lags == 0)):
        raise ValueError("a ping at tau > 0 cannot arrive at its own step's tick (lag 0)")
    return lags, int(lags.max(initial=0))


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

    ``tau``, ``lag``, ``p_TS``, ``noise`` as in :func:`ping_information` (N steps, sonar i of
    step k in entry ``[k, i]``); ``P0`` (6×6) the prior ``P(0|−1)``; ``W`` (3×3, or N×3×3
    per step) the covariance of the step's unknown acceleration; ``position_noise`` a position
    covariance added over each step: a per-axis variance (scalar, or N per step) or a 3×3
    matrix (or N×3×3 per step). See the module docstring.
    """
    lags, window = _check(tau, lag, time_step)
    steps = lags.shape[0]
    info = ping_information(tau, lags, p_TS, noise, window)
    W_inv = np.linalg.inv(np.broadcast_to(np.asarray(W, dtype=float), (steps, 3, 3)))
    Qp = np.zeros((steps, 6, 6))
    position_noise = np.asarray(position_noise, dtype=float)
    if position_noise.ndim < 2:  # per-axis variances
        position_noise = position_noise[..., None, None] * np.eye(3)
    Qp[:, :3, :3] = np.broadcast_to(position_noise, (steps, 3, 3))
    G = step_transition(time_step)

    def advance(P: np.ndarray, k: np.ndarray, information: np.ndarray) -> np.ndarray:
        """``P⁻_{k+1}`` from ``P⁻_k`` through step k with the given information (batched)."""
        J = np.zeros(P.shape[:-2] + (9, 9))
        J[..., :6, :6] = np.linalg.inv(P)
        J[..., 6:, 6:] = W_inv[k]
        P_z = symmetrise(np.linalg.inv(symmetrise(J + information)))
        return symmetrise(G @ P_z @ G.T + Qp[k])

    complete = np.empty((steps, 6, 6))
    complete[0] = symmetrise(np.asarray(P0, dtype=float).reshape(6, 6))
    for k in range(steps - 1):
        complete[k + 1] = advance(complete[k], np.array(k), info[k, window])
    ticks = np.arange(steps)
    start = np.maximum(ticks - window, 0)
    P = complete[start]
    for m in range(window):  # the last steps, with what has arrived by each tick
        k = start + m
        active = k < ticks
        k = np.minimum(k, steps - 1)
        ell = np.clip(ticks - k, 0, window)
        P = np.where(active[:, None, None], advance(P, k, info[k, ell]), P)
    J = np.linalg.inv(P) + info[:, 0, :6, :6]  # the tick's own pings (τ = 0, lag 0)
    return symmetrise(np.linalg.inv(symmetrise(J)))
