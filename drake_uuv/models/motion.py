"""The sampled double integrator shared by the vehicle, the target and the relative state.

``X = [p, v] ∈ R⁶``, ``X(k+1) = A X(k) + B a(k)`` with ``A = [[I, tI], [0, I]]`` and
``B = [[t²/2 I], [t I]]`` (paper eq. 1). The relative state ``x = [q, ϑ]`` with
``q = p_WU − p_WT`` and ``ϑ = v_WU − v_WT`` obeys the same model driven by
``a_W − ū``: the vehicle's known world acceleration ``a_W = R u1`` and the target's unknown
acceleration ``ū ~ N(0, W)``, whose effect is the process noise ``Q = B W Bᵀ`` (rank 3).
"""

import numpy as np


def double_integrator(time_step: float) -> tuple[np.ndarray, np.ndarray]:
    """``(A, B)`` of ``X(k+1) = A X(k) + B a(k)`` for ``X = [p, v]`` in R⁶ (paper eq. 1)."""
    t = float(time_step)
    if not t > 0.0:
        raise ValueError(f"time_step: must be > 0, got {time_step!r}")
    A = np.block([[np.eye(3), t * np.eye(3)], [np.zeros((3, 3)), np.eye(3)]])
    B = np.vstack([0.5 * t * t * np.eye(3), t * np.eye(3)])
    return A, B


def double_integrator_step(
    p: np.ndarray, v: np.ndarray, a: np.ndarray, time_step: float
) -> tuple[np.ndarray, np.ndarray]:
    """``(p(k+1), v(k+1))`` of ``X(k+1) = A X(k) + B a``, without forming ``X``, ``A`` or ``B``:
    ``p + t v + ½t² a`` and ``v + t a`` (the same numbers as the matrix form, to the bit)."""
    t = time_step
    return p + t * v + (0.5 * t * t) * a, v + t * a


def process_noise_covariance(W: np.ndarray, time_step: float) -> np.ndarray:
    """``Q = B W Bᵀ`` (6×6, rank 3) for the target's acceleration covariance ``W`` (3×3)."""
    _, B = double_integrator(time_step)
    return B @ np.asarray(W, dtype=float).reshape(3, 3) @ B.T
