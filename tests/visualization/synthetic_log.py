"""Synthetic simulation logs for the visualization tests (no simulation needed)."""

from __future__ import annotations

import numpy as np
from pydrake.common.eigen_geometry import AngleAxis
from pydrake.math import RotationMatrix

TIME_STEP = 0.5
BASELINE_B = np.array([-1.0, 1.0, 0.0])
Q_STAR_B = np.array([-2.0, -2.0, 0.0])


def synthetic_log(steps: int = 100, seed: int = 0, time_step: float = TIME_STEP) -> dict:
    """A log with the keys and shapes of ``log.npz``, made without a simulation.

    The target is the paper's random walk (p̄(0) = [1, 2, 2], v̄(0) = [0.02, 0.1, 0.1],
    W = diag(0.004, 0.001, 0.001)); the UUV sits near ``p̄ + R q*`` (q* = [−2, −2, 0])
    while it rotates steadily; the estimate q̂ scatters about q with a covariance P
    that shrinks from I.
    """
    rng = np.random.default_rng(seed)
    t = time_step
    n = steps
    W = np.diag([0.004, 0.001, 0.001])
    p_target = np.zeros((n, 3))
    v_target = np.zeros((n, 3))
    p_target[0], v_target[0] = [1.0, 2.0, 2.0], [0.02, 0.1, 0.1]
    for k in range(n - 1):
        u = rng.multivariate_normal(np.zeros(3), W)
        p_target[k + 1] = p_target[k] + t * v_target[k] + 0.5 * t**2 * u
        v_target[k + 1] = v_target[k] + t * u

    axis = np.array([0.3, 0.2, 1.0]) / np.linalg.norm([0.3, 0.2, 1.0])
    R_WB = np.stack([RotationMatrix(AngleAxis(0.12 * k, axis)).matrix() for k in range(n)])
    q = np.einsum("kij,j->ki", R_WB, Q_STAR_B) + 0.05 * rng.standard_normal((n, 3))
    p_uuv = p_target + q
    v_uuv = np.gradient(p_uuv, t, axis=0)

    shape = np.array([[1.0, 0.3, 0.1], [0.3, 0.6, 0.0], [0.1, 0.0, 0.4]])
    P = np.zeros((n, 6, 6))
    q_hat = np.zeros((n, 3))
    for k in range(n):
        scale = 0.03 + np.exp(-k / 15.0)
        P[k] = scale * np.eye(6)
        P[k, :3, :3] = scale * shape
        q_hat[k] = q[k] + np.linalg.cholesky(P[k, :3, :3]) @ rng.standard_normal(3)
    q_s = np.einsum("kij,j->ki", R_WB, BASELINE_B)
    d1 = np.linalg.norm(q + 0.5 * q_s, axis=1)
    d2 = np.linalg.norm(q - 0.5 * q_s, axis=1)
    ranges = np.column_stack([d1, d2]) + 0.1 * rng.standard_normal((n, 2))
    return {
        "k": np.arange(n),
        "time": t * np.arange(n),
        "p_WU": p_uuv,
        "v_WU": v_uuv,
        "R_WB": R_WB,
        "p_WT": p_target,
        "v_WT": v_target,
        "ranges": ranges,
        "Y": 0.5 * (ranges[:, 0] ** 2 - ranges[:, 1] ** 2),
        "m": np.zeros(n),
        "Gamma": np.full(n, 0.1),
        "b_W": q_s,
        "x_TU_hat": np.column_stack([q_hat, v_uuv - v_target]),
        "P_TU": P,
        "u1_B": np.zeros((n, 3)),
        "u2_W": np.zeros((n, 3)),
        "u1_W": np.zeros((n, 3)),
    }
