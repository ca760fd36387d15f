"""What the hand-over's tests measure: the prior's share of the KF's covariance, the angles.

The quantities of :mod:`drake_uuv.models.handover`'s two tests (its module notes say why
they are these), for one run and for a batch with a leading run axis: the prior's share
``S`` of the linear KF's covariance through a prediction and an update
(:func:`prior_share_predict`, :func:`prior_share_update`), the cross-range angle
``θᵢ = √tr(P⊥ᵢ) / dᵢ`` of each sonar (:func:`cross_range_angle`) and the second-order range
term a linearisation drops (:func:`second_order_range_error`). ``drake_uuv.models.handover``
re-exports them.
"""

import math

import numpy as np

_I6 = np.eye(6)


def cross_range_angle_runs(x: np.ndarray, P: np.ndarray, q_s: np.ndarray) -> np.ndarray:
    """:func:`cross_range_angle` of each run: ``x`` (B, 6), ``P`` (B, 6, 6), ``q_s`` (B, 3);
    returns (B, 2) [rad]."""
    q = x[:, :3]
    half = 0.5 * q_s
    r = np.stack([q + half, q - half], axis=1)  # (B, 2, 3)
    P_qq = P[:, :3, :3]
    trace = P_qq[:, 0, 0] + P_qq[:, 1, 1] + P_qq[:, 2, 2]
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        d = np.sqrt((r * r).sum(axis=2))
        u = r / d[:, :, np.newaxis]
        across = trace[:, np.newaxis] - ((u @ P_qq) * u).sum(axis=2)
        angle = np.sqrt(np.maximum(across, 0.0)) / d
    return np.where(d < 1e-9, math.inf, angle)


def cross_range_angle(x: np.ndarray, P: np.ndarray, q_s: np.ndarray) -> np.ndarray:
    """``θᵢ = √tr(P⊥ᵢ) / dᵢ`` for both sonars (shape (2,)) [rad].

    ``dᵢ = |q ± ½ q_s|`` and the line of sight ``uᵢ`` at the estimate ``q = x[:3]``;
    ``tr P⊥ᵢ = tr P_qq − uᵢᵀ P_qq uᵢ`` the position variance across it. A range below 1 nm
    gives an infinite angle.
    """
    x, P, q_s = _one_run(x, P, q_s)
    return cross_range_angle_runs(x, P, q_s)[0]


def _one_run(x: np.ndarray, P: np.ndarray, q_s: np.ndarray) -> tuple:
    return (
        np.asarray(x, dtype=float).reshape(1, 6),
        np.asarray(P, dtype=float).reshape(1, 6, 6),
        np.asarray(q_s, dtype=float).reshape(1, 3),
    )


def second_order_range_error_runs(
    x: np.ndarray, P: np.ndarray, q_s: np.ndarray, angles: np.ndarray | None = None
) -> np.ndarray:
    """:func:`second_order_range_error` of each run (B, 2) [m] (``angles``: the runs'
    :func:`cross_range_angle_runs`, when known)."""
    if angles is None:
        angles = cross_range_angle_runs(x, P, q_s)
    q = x[:, :3]
    half = 0.5 * q_s
    r = np.stack([q + half, q - half], axis=1)
    return 0.5 * angles * angles * np.sqrt((r * r).sum(axis=2))


def second_order_range_error(x: np.ndarray, P: np.ndarray, q_s: np.ndarray) -> np.ndarray:
    """``tr(P⊥ᵢ)/(2 dᵢ)`` for both sonars (shape (2,)) [m]: the mean of the quadratic term of
    ``d(q + e) = d + uᵀe + (|e|² − (uᵀe)²)/(2d) + …`` under ``e ~ N(0, P_qq)``, the range a
    linearisation at the estimate drops (``= θ² d / 2`` with :func:`cross_range_angle`)."""
    return second_order_range_error_runs(*_one_run(x, P, q_s))[0]


def _trace_qq(P: np.ndarray) -> np.ndarray:
    return P[:, 0, 0] + P[:, 1, 1] + P[:, 2, 2]


def prior_share_predict(S: np.ndarray, A: np.ndarray) -> np.ndarray:
    """The prior's share of the covariance through a prediction: ``A S Aᵀ`` (no process noise)."""
    return A @ S @ A.T


def prior_share_update(
    S: np.ndarray, P_filtered: np.ndarray, q_s: np.ndarray, Gamma: float
) -> np.ndarray:
    """Through the linear KF's update on ``Y = q_sᵀ q + v̄``: ``(I − K C) S (I − K C)ᵀ``.

    ``C = [q_sᵀ, 0]``; ``K = P Cᵀ Γ⁻¹`` from the KF's covariance *after* the update, which for
    the KF's gain ``K = P⁻ Cᵀ (C P⁻ Cᵀ + Γ)⁻¹`` is the same gain.
    """
    q_s = np.asarray(q_s, dtype=float).reshape(3)
    K = np.asarray(P_filtered, dtype=float)[:, :3] @ q_s / float(Gamma)
    I_KC = _I6.copy()
    I_KC[:, :3] -= K[:, None] * q_s
    S = I_KC @ np.asarray(S, dtype=float) @ I_KC.T
    return 0.5 * (S + S.T)
