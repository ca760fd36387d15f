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

from drake_uuv.models.so3 import exp_so3, exp_so3_runs, log_so3, log_so3_runs


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
    """:func:`interpolate_attitude` of each run: ``R0``, ``R1`` (B, 3, 3), ``s`` (B)."""
    s = np.asarray(s, dtype=float)
    turn = exp_so3_runs(s[:, np.newaxis] * log_so3_runs(R1 @ np.swapaxes(R0, -1, -2))) @ R0
    return np.where((s == 0.0)[:, np.newaxis, np.newaxis], R0, turn)
