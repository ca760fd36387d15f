"""Where a ping's sonar is and where its pan-tilt points, per run, compiled with numba.

The attitude at a ping between two ticks (:func:`interpolate_attitude`, the geodesic by
``Log`` and ``Exp`` on one run's 3×3 matrices as 9-vectors), the direction the pan-tilt points
(:func:`beam_axis`) and whether the target is off its cone (:func:`_out_of_beam`), for
:func:`drake_uuv.sensors.sonar_kernels.measure`. Rotations interpolated between ticks
multiply 3×3 matrices without fused operations: their last bits differ from the BLAS
products of the single-run numpy of before (a range by ~1e-13 m).

numba's cache keys a compiled kernel on its own file's source only: after changing this file,
delete the cache of the files whose kernels call these (``sonar_kernels.py``: its
``__pycache__/sonar_kernels.*.nb[ci]``), or they keep the old code.
"""

import math

import numpy as np
from numba import njit

from drake_uuv.sensors.sonar_sums import _clip_at_zero, _fma, dot3

_SMALL_ANGLE = 1e-9

#: Every kernel: compiled once and cached on disk; IEEE division (a run's 0/0 gives NaN
#: instead of raising, which would stop the batch).
_jit = njit(cache=True, error_model="numpy")


# --- Rotations: one run's 3×3 matrices as 9-vectors, row-major (no reshape per run) --------


@_jit
def _copy9(A: np.ndarray, out: np.ndarray) -> None:
    for c in range(9):
        out[c] = A[c]


@_jit
def _matmul33(A: np.ndarray, B: np.ndarray, C: np.ndarray) -> None:
    """``C = A B``."""
    for i in range(3):
        for j in range(3):
            C[3 * i + j] = A[3 * i] * B[j] + A[3 * i + 1] * B[3 + j] + A[3 * i + 2] * B[6 + j]


@_jit
def _matmul33_bt(A: np.ndarray, B: np.ndarray, C: np.ndarray) -> None:
    """``C = A Bᵀ``."""
    for i in range(3):
        for j in range(3):
            C[3 * i + j] = (
                A[3 * i] * B[3 * j] + A[3 * i + 1] * B[3 * j + 1] + A[3 * i + 2] * B[3 * j + 2]
            )


@_jit
def _log_so3(R: np.ndarray, q: np.ndarray, out: np.ndarray) -> None:
    """``out = Log(R)`` as :func:`~drake_uuv.models.so3.log_so3` (Shepperd's quaternion,
    then its angle); ``q`` is scratch (4)."""
    d0, d1, d2 = R[0], R[4], R[8]
    trace = d0 + d1 + d2
    if d0 != d0:  # NaN: the first NaN, as np.argmax
        i = 0
    elif d1 != d1:
        i = 1
    elif d2 != d2:
        i = 2
    else:
        i = 0 if d0 >= d1 else 1
        if d2 > R[4 * i]:
            i = 2
    if trace >= R[4 * i]:
        w = 0.5 * math.sqrt(_clip_at_zero(1.0 + trace))
        s = 0.25 / w
        q[0] = w
        q[1] = (R[7] - R[5]) * s
        q[2] = (R[2] - R[6]) * s
        q[3] = (R[3] - R[1]) * s
    else:
        j, k = (i + 1) % 3, (i + 2) % 3
        v = 0.5 * math.sqrt(_clip_at_zero(1.0 + R[4 * i] - R[4 * j] - R[4 * k]))
        s = 0.25 / v
        q[0] = (R[3 * k + j] - R[3 * j + k]) * s
        q[1 + i] = v
        q[1 + j] = (R[3 * j + i] + R[3 * i + j]) * s
        q[1 + k] = (R[3 * k + i] + R[3 * i + k]) * s
    if q[0] < 0.0:
        for c in range(4):
            q[c] = -q[c]
    n = math.sqrt(_fma(q[3], q[3], dot3(q[0], q[1], q[2], q[0], q[1], q[2])))
    for c in range(4):
        q[c] = q[c] / n
    s = math.sqrt(dot3(q[1], q[2], q[3], q[1], q[2], q[3]))
    factor = 2.0 if s < _SMALL_ANGLE else 2.0 * math.atan2(s, q[0]) / s
    for c in range(3):
        out[c] = factor * q[1 + c]


@_jit
def _exp_so3(w: np.ndarray, K: np.ndarray, K2: np.ndarray, R: np.ndarray) -> None:
    """``R = Exp(w)`` as :func:`~drake_uuv.models.so3.exp_so3` (Rodrigues); ``K``, ``K2``
    are scratch (9)."""
    theta = math.sqrt(dot3(w[0], w[1], w[2], w[0], w[1], w[2]))
    K[0], K[1], K[2] = 0.0, -w[2], w[1]
    K[3], K[4], K[5] = w[2], 0.0, -w[0]
    K[6], K[7], K[8] = -w[1], w[0], 0.0
    _matmul33(K, K, K2)
    if theta < _SMALL_ANGLE:
        a, b = 1.0, 0.5
    else:
        a, b = math.sin(theta) / theta, (1.0 - math.cos(theta)) / (theta * theta)
    for c in range(9):
        R[c] = (1.0 if c % 4 == 0 else 0.0) + a * K[c] + b * K2[c]


@_jit
def interpolate_attitude(
    R0: np.ndarray, R1: np.ndarray, s: float, scratch: np.ndarray, out: np.ndarray
) -> None:
    """``out``: the attitude at fraction ``s`` of the geodesic from ``R0`` to ``R1`` (9 each,
    row-major), ``Exp(s Log(R1 R0ᵀ)) R0`` (:func:`~drake_uuv.models.ping_geometry.
    interpolate_attitude`); ``scratch`` (5, 9), ``out`` not ``R0``."""
    if s == 0.0:
        _copy9(R0, out)
        return
    relative, K, K2, step, vectors = scratch[0], scratch[1], scratch[2], scratch[3], scratch[4]
    _matmul33_bt(R1, R0, relative)
    w = vectors[:3]
    _log_so3(relative, vectors[3:7], w)
    for c in range(3):
        w[c] = s * w[c]
    _exp_so3(w, K, K2, step)
    _matmul33(step, R0, out)


def beam_axis(
    R_WB: np.ndarray, R_point: np.ndarray, q_prior: np.ndarray, offset: np.ndarray, sign: float,
    baseline: np.ndarray,
) -> np.ndarray:  # fmt: skip
    """The world direction a ping's pan-tilt points along, from the sonar to the predicted
    target (``R_WB``, ``R_point`` 3×3).

    The vehicle aims from the sonar at the predicted target, ``−(q_prior + offset)`` with the
    offset ``± ½ R_point b`` it believes; the pan-tilt turns that into the body frame by the
    attitude it believes (``R_point``, the navigated one) and the true attitude carries it
    back to the world: ``R_WB R_pointᵀ (−(q_prior ± ½ R_point b))``. Pointing by the true
    attitude, the axis is the predicted direction itself (computed as such)."""
    axis = np.empty(3)
    _beam_axis(
        np.ascontiguousarray(R_WB, dtype=float).ravel(),
        np.ascontiguousarray(R_point, dtype=float).ravel(),
        np.asarray(q_prior, dtype=float), np.asarray(offset, dtype=float), float(sign),
        np.asarray(baseline, dtype=float), axis,
    )  # fmt: skip
    return axis


@_jit
def _beam_axis(
    R_WB: np.ndarray, R_point: np.ndarray, q_prior: np.ndarray, offset: np.ndarray, sign: float,
    baseline: np.ndarray, axis: np.ndarray,
) -> None:  # fmt: skip
    """:func:`beam_axis` into ``axis``, the matrices as 9-vectors."""
    same = True
    for c in range(9):
        if R_point[c] != R_WB[c]:
            same = False
    if same:
        for k in range(3):
            axis[k] = -(q_prior[k] + offset[k])
        return
    aim = np.empty(3)
    for k in range(3):
        aim[k] = (
            R_point[k] * -q_prior[0] + R_point[3 + k] * -q_prior[1] + R_point[6 + k] * -q_prior[2]
        ) - sign * 0.5 * baseline[k]
    for k in range(3):
        axis[k] = R_WB[3 * k] * aim[0] + R_WB[3 * k + 1] * aim[1] + R_WB[3 * k + 2] * aim[2]


@_jit
def _out_of_beam(p_TS: np.ndarray, axis: np.ndarray, radius: float, beam_half_angle: float) -> bool:
    """Whether the target (``−p_TS`` from the sonar) is off the pan-tilt's cone about
    ``axis``: the wider of the beam and the scanned region's angular radius."""
    distance = math.sqrt(dot3(axis[0], axis[1], axis[2], axis[0], axis[1], axis[2]))
    scanned = math.pi if radius >= distance else math.asin(radius / distance)
    half_angle = scanned if scanned > beam_half_angle else beam_half_angle
    t0, t1, t2 = -p_TS[0], -p_TS[1], -p_TS[2]
    to_target = math.sqrt(dot3(t0, t1, t2, t0, t1, t2))
    cos_angle = dot3(t0, t1, t2, axis[0], axis[1], axis[2]) / (to_target * distance + 1e-300)
    return cos_angle < math.cos(half_angle)
