"""Where the vehicle, its attitude and the target are at a ping between two ticks.

The paper's models are discrete: the vehicle and the target move with an acceleration held
over each step (``R(k) u1(k)``, ``ū(k)``), and the attitude turns by ``Exp(u2(k) t)``, a
constant world angular velocity over the step. Between ticks k and k+1 the positions are then
quadratic in time and the attitude a geodesic, and both follow from the two ticks' states:

- position: the cubic Hermite interpolant of ``(p, v)`` at both ticks, which is exact for a
  quadratic (constant acceleration): ``p(s) = h00 p0 + h10 t v0 + h01 p1 + h11 t v1``;
- velocity: its derivative;
- attitude: ``Exp(s · Log(R1 R0ᵀ)) R0``, exact for a constant world angular velocity ``u2``
  with ``|u2 t| < π`` (the attitude generators command ``u2 = Log(R̄ Rᵀ)/t``).

``s = τ / t`` is the fraction of the step. A continuous plant (the hovering UUV) is not
exactly quadratic over a step; there these are the interpolants of its states at the ticks.
"""

import numpy as np
from numba import njit

from drake_uuv.models.so3 import exp_so3, log_so3


def hermite_weights(s: float) -> tuple[float, float, float, float]:
    """``(h00, h10, h01, h11)`` of the cubic Hermite basis at ``s ∈ [0, 1]``."""
    s2, s3 = s * s, s * s * s
    return 2 * s3 - 3 * s2 + 1, s3 - 2 * s2 + s, -2 * s3 + 3 * s2, s3 - s2


def interpolate_position(
    p0: np.ndarray, v0: np.ndarray, p1: np.ndarray, v1: np.ndarray, s: float, time_step: float
) -> np.ndarray:
    """The position at fraction ``s`` of a step of ``time_step`` from its ends' (p, v)."""
    h00, h10, h01, h11 = hermite_weights(s)
    return h00 * p0 + h10 * time_step * v0 + h01 * p1 + h11 * time_step * v1


def interpolate_velocity(
    p0: np.ndarray, v0: np.ndarray, p1: np.ndarray, v1: np.ndarray, s: float, time_step: float
) -> np.ndarray:
    """The velocity at fraction ``s``: the Hermite interpolant's time derivative."""
    s2 = s * s
    d00, d10, d01, d11 = 6 * s2 - 6 * s, 3 * s2 - 4 * s + 1, -6 * s2 + 6 * s, 3 * s2 - 2 * s
    return (d00 * p0 + d01 * p1) / time_step + d10 * v0 + d11 * v1


def interpolate_attitude(R0: np.ndarray, R1: np.ndarray, s: float) -> np.ndarray:
    """The attitude at fraction ``s`` of the geodesic from ``R0`` to ``R1``."""
    if s == 0.0:
        return R0
    return exp_so3(s * log_so3(R1 @ R0.T)) @ R0


def interpolate_attitude_runs(R0: np.ndarray, R1: np.ndarray, s: np.ndarray) -> np.ndarray:
    """:func:`interpolate_attitude` of each run: ``R0``, ``R1`` (B, 3, 3), ``s`` (B); one
    compiled loop over the runs (Log through the quaternion, as :func:`~drake_uuv.models.so3.
    log_so3_runs`; Exp by Rodrigues' formula)."""
    out = np.empty(np.shape(R0))
    _interpolate_attitudes(
        np.ascontiguousarray(R0), np.ascontiguousarray(R1), np.asarray(s, dtype=float), out
    )
    return out


@njit(cache=True, error_model="numpy")
def _interpolate_attitudes(R0, R1, s, out):
    M = np.empty((3, 3))
    E = np.empty((3, 3))
    for r in range(R0.shape[0]):
        if s[r] == 0.0:
            out[r] = R0[r]
            continue
        for i in range(3):  # M = R1 R0ᵀ
            for j in range(3):
                M[i, j] = (
                    R1[r, i, 0] * R0[r, j, 0]
                    + R1[r, i, 1] * R0[r, j, 1]
                    + (R1[r, i, 2] * R0[r, j, 2])
                )
        # Shepperd's quaternion [w, x, y, z] of M, w ≥ 0
        trace = M[0, 0] + M[1, 1] + M[2, 2]
        if trace >= M[0, 0] and trace >= M[1, 1] and trace >= M[2, 2]:
            w = 0.5 * np.sqrt(1.0 + trace)
            x = (M[2, 1] - M[1, 2]) / (4.0 * w)
            y = (M[0, 2] - M[2, 0]) / (4.0 * w)
            z = (M[1, 0] - M[0, 1]) / (4.0 * w)
        elif M[0, 0] >= M[1, 1] and M[0, 0] >= M[2, 2]:
            x = 0.5 * np.sqrt(1.0 + M[0, 0] - M[1, 1] - M[2, 2])
            w = (M[2, 1] - M[1, 2]) / (4.0 * x)
            y = (M[0, 1] + M[1, 0]) / (4.0 * x)
            z = (M[0, 2] + M[2, 0]) / (4.0 * x)
        elif M[1, 1] >= M[2, 2]:
            y = 0.5 * np.sqrt(1.0 - M[0, 0] + M[1, 1] - M[2, 2])
            w = (M[0, 2] - M[2, 0]) / (4.0 * y)
            x = (M[0, 1] + M[1, 0]) / (4.0 * y)
            z = (M[1, 2] + M[2, 1]) / (4.0 * y)
        else:
            z = 0.5 * np.sqrt(1.0 - M[0, 0] - M[1, 1] + M[2, 2])
            w = (M[1, 0] - M[0, 1]) / (4.0 * z)
            x = (M[0, 2] + M[2, 0]) / (4.0 * z)
            y = (M[1, 2] + M[2, 1]) / (4.0 * z)
        if w < 0.0:
            w, x, y, z = -w, -x, -y, -z
        n = np.sqrt(x * x + y * y + z * z)
        scale = 2.0 * np.arctan2(n, w) / n if n > 1e-12 else 2.0 / w
        # Exp(s · Log M) by Rodrigues, then · R0
        v0, v1, v2 = s[r] * scale * x, s[r] * scale * y, s[r] * scale * z
        theta = np.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
        if theta < 1e-8:
            a, b = 1.0, 0.5
        else:
            a, b = np.sin(theta) / theta, (1.0 - np.cos(theta)) / (theta * theta)
        K = ((0.0, -v2, v1), (v2, 0.0, -v0), (-v1, v0, 0.0))
        for i in range(3):
            for j in range(3):
                kk = K[i][0] * K[0][j] + K[i][1] * K[1][j] + K[i][2] * K[2][j]
                E[i, j] = (1.0 if i == j else 0.0) + a * K[i][j] + b * kk
        for i in range(3):
            for j in range(3):
                out[r, i, j] = E[i, 0] * R0[r, 0, j] + E[i, 1] * R0[r, 1, j] + E[i, 2] * R0[r, 2, j]
