"""Rotation helpers on SO(3) used by the plant, the attitude generator and the sensor.

Plain numpy on purpose: they run inside per-step calcs, where constructing pydrake
``RotationMatrix``/``AngleAxis`` objects costs more than the arithmetic. The tests check
every function against Drake's ``RotationMatrix(AngleAxis(...))`` and ``ToAngleAxis()``.

Quaternions are ``[w, x, y, z]`` (Drake's order), unit norm, ``w ≥ 0`` where it matters.
"""

from __future__ import annotations

import math

import numpy as np

_SMALL_ANGLE = 1e-9
_I3 = np.eye(3)


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a × b`` for 3-vectors (``np.cross`` costs ~20× more on this size)."""
    return np.array(
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    )


def norm(v: np.ndarray) -> float:
    """Euclidean norm of a small vector."""
    return math.sqrt(float(v @ v))


def hat(w: np.ndarray) -> np.ndarray:
    """Skew-symmetric matrix with ``hat(w) @ v == cross(w, v)``."""
    w0, w1, w2 = np.asarray(w).tolist()
    return np.array([[0.0, -w2, w1], [w2, 0.0, -w0], [-w1, w0, 0.0]])


def exp_so3(rotation_vector: np.ndarray) -> np.ndarray:
    """Exp: rotation vector (axis × angle) → rotation matrix (Rodrigues)."""
    theta = math.sqrt(float(rotation_vector @ rotation_vector))
    K = hat(rotation_vector)
    if theta < _SMALL_ANGLE:
        return _I3 + K + 0.5 * (K @ K)
    return (
        _I3 + (math.sin(theta) / theta) * K + ((1.0 - math.cos(theta)) / (theta * theta)) * (K @ K)
    )


def quaternion_from_matrix(R: np.ndarray) -> np.ndarray:
    """Unit quaternion ``[w, x, y, z]`` with ``w ≥ 0`` (Shepperd's method, stable everywhere)."""
    # Scalar arithmetic on Python floats: the same IEEE operations as on numpy scalars, faster.
    M = np.asarray(R, dtype=float).tolist()
    d0, d1, d2 = diagonal = (M[0][0], M[1][1], M[2][2])
    trace = d0 + d1 + d2
    if d0 != d0 or d1 != d1 or d2 != d2:
        i = int(np.argmax(diagonal))  # NaN: argmax's choice (the first NaN)
    else:
        i = 0 if d0 >= d1 else 1  # the first largest, as np.argmax
        if d2 > diagonal[i]:
            i = 2
    if trace >= diagonal[i]:
        w = 0.5 * math.sqrt(max(1.0 + trace, 0.0))
        s = 0.25 / w
        q = [w, (M[2][1] - M[1][2]) * s, (M[0][2] - M[2][0]) * s, (M[1][0] - M[0][1]) * s]
    else:
        j, k = (i + 1) % 3, (i + 2) % 3
        v = 0.5 * math.sqrt(max(1.0 + M[i][i] - M[j][j] - M[k][k], 0.0))
        s = 0.25 / v
        q = [0.0] * 4
        q[0] = (M[k][j] - M[j][k]) * s
        q[1 + i] = v
        q[1 + j] = (M[j][i] + M[i][j]) * s
        q[1 + k] = (M[k][i] + M[i][k]) * s
    if q[0] < 0.0:
        q = [-c for c in q]
    q = np.array(q)
    return q / math.sqrt(float(q @ q))


def matrix_from_quaternion(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of a unit quaternion ``[w, x, y, z]``."""
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def log_so3(R: np.ndarray) -> np.ndarray:
    """Log: rotation matrix → rotation vector with angle in [0, π]."""
    q = quaternion_from_matrix(R)
    v = q[1:]
    s = math.sqrt(float(v @ v))
    if s < _SMALL_ANGLE:
        return 2.0 * v
    return (2.0 * math.atan2(s, q[0]) / s) * v


def minimal_rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The rotation of least angle taking the direction of ``a`` to the direction of ``b``.

    Axis ``a × b`` normalised, angle ``arccos(aᵀb / (|a||b|))`` (Algorithm 2 of the paper, whose
    "product of b and ζ" is this cross product). When ``a`` and ``b`` are parallel it is the
    identity; when antiparallel, a half-turn about any axis perpendicular to ``a``.
    """
    a_unit = a / norm(a)
    b_unit = b / norm(b)
    axis = cross(a_unit, b_unit)
    sin_angle = norm(axis)
    cos_angle = float(a_unit @ b_unit)
    if sin_angle < _SMALL_ANGLE:
        if cos_angle > 0.0:
            return np.eye(3)
        # Antiparallel: any axis perpendicular to a; take the one from the least-aligned basis axis.
        basis = np.eye(3)[int(np.argmin(np.abs(a_unit)))]
        perpendicular = cross(a_unit, basis)
        return exp_so3(math.pi * perpendicular / norm(perpendicular))
    angle = math.atan2(sin_angle, cos_angle)
    return exp_so3(axis * (angle / sin_angle))


def is_rotation(R: np.ndarray, tolerance: float = 1e-9) -> bool:
    """True when ``R`` is orthonormal with determinant +1 to within ``tolerance``."""
    return bool(
        np.all(np.isfinite(R))
        and np.max(np.abs(R.T @ R - np.eye(3))) < tolerance
        and abs(np.linalg.det(R) - 1.0) < tolerance
    )


# --------------------------------------------------------------- over a leading run axis
# The batched systems hold one rotation per run: these take ``(..., 3)`` vectors and
# ``(..., 3, 3)`` matrices and work element by element over the leading axes, so run i's
# numbers do not depend on the other runs (the same bits alone or in any batch). The
# single-rotation functions above stay for code that holds one rotation (analysis, tests).


def hat_runs(w: np.ndarray) -> np.ndarray:
    """``hat`` of each ``(..., 3)`` vector: ``(..., 3, 3)``."""
    w = np.asarray(w, dtype=float)
    K = np.zeros((*w.shape[:-1], 3, 3))
    K[..., 0, 1], K[..., 0, 2] = -w[..., 2], w[..., 1]
    K[..., 1, 0], K[..., 1, 2] = w[..., 2], -w[..., 0]
    K[..., 2, 0], K[..., 2, 1] = -w[..., 1], w[..., 0]
    return K


def cross_runs(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a × b`` over leading axes (broadcast), written out (no ``np.cross`` dispatch)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return np.stack(
        (
            a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
            a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
            a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0],
        ),
        axis=-1,
    )


def norm_runs(v: np.ndarray) -> np.ndarray:
    """Euclidean norm of each ``(..., n)`` vector, summed in index order."""
    v = np.asarray(v, dtype=float)
    total = v[..., 0] * v[..., 0]
    for j in range(1, v.shape[-1]):
        total = total + v[..., j] * v[..., j]
    return np.sqrt(total)


def exp_so3_runs(rotation_vector: np.ndarray) -> np.ndarray:
    """Exp of each ``(..., 3)`` rotation vector (Rodrigues): ``(..., 3, 3)``."""
    w = np.asarray(rotation_vector, dtype=float)
    theta = norm_runs(w)
    K = hat_runs(w)
    KK = K @ K
    small = theta < _SMALL_ANGLE
    safe = np.where(small, 1.0, theta)
    a = np.where(small, 1.0, np.sin(safe) / safe)
    b = np.where(small, 0.5, (1.0 - np.cos(safe)) / (safe * safe))
    return _I3 + a[..., None, None] * K + b[..., None, None] * KK


def matrix_from_quaternion_runs(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of each unit quaternion ``(..., 4)`` ``[w, x, y, z]``: ``(..., 3, 3)``."""
    q = np.asarray(q, dtype=float)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    R = np.empty((*q.shape[:-1], 3, 3))
    R[..., 0, 0], R[..., 0, 1], R[..., 0, 2] = (
        1 - 2 * (y * y + z * z),
        2 * (x * y - w * z),
        2 * (x * z + w * y),
    )
    R[..., 1, 0], R[..., 1, 1], R[..., 1, 2] = (
        2 * (x * y + w * z),
        1 - 2 * (x * x + z * z),
        2 * (y * z - w * x),
    )
    R[..., 2, 0], R[..., 2, 1], R[..., 2, 2] = (
        2 * (x * z - w * y),
        2 * (y * z + w * x),
        1 - 2 * (x * x + y * y),
    )
    return R


def quaternion_from_matrix_runs(R: np.ndarray) -> np.ndarray:
    """Unit quaternion ``[w, x, y, z]``, ``w ≥ 0``, of each ``(..., 3, 3)`` rotation
    (Shepperd's method: the largest of the four candidates, as :func:`quaternion_from_matrix`)."""
    R = np.asarray(R, dtype=float)
    d0, d1, d2 = R[..., 0, 0], R[..., 1, 1], R[..., 2, 2]
    trace = d0 + d1 + d2
    i = np.where(d0 >= d1, 0, 1)
    i = np.where(d2 > np.where(i == 0, d0, d1), 2, i)
    largest = np.choose(i, (d0, d1, d2))
    shape = (*R.shape[:-2], 4)
    candidates = np.empty((4, *shape))
    # trace branch
    w = 0.5 * np.sqrt(np.maximum(1.0 + trace, 0.0))
    s = 0.25 / np.where(w > 0.0, w, 1.0)
    candidates[0] = np.stack(
        (w, (R[..., 2, 1] - R[..., 1, 2]) * s, (R[..., 0, 2] - R[..., 2, 0]) * s,
         (R[..., 1, 0] - R[..., 0, 1]) * s), axis=-1,
    )  # fmt: skip
    for axis in range(3):
        j, k = (axis + 1) % 3, (axis + 2) % 3
        v = 0.5 * np.sqrt(np.maximum(1.0 + R[..., axis, axis] - R[..., j, j] - R[..., k, k], 0.0))
        s = 0.25 / np.where(v > 0.0, v, 1.0)
        q = np.empty(shape)
        q[..., 0] = (R[..., k, j] - R[..., j, k]) * s
        q[..., 1 + axis] = v
        q[..., 1 + j] = (R[..., j, axis] + R[..., axis, j]) * s
        q[..., 1 + k] = (R[..., k, axis] + R[..., axis, k]) * s
        candidates[1 + axis] = q
    choice = np.where(trace >= largest, 0, 1 + i)
    q = np.take_along_axis(candidates, choice[None, ..., None], axis=0)[0]
    q = np.where(q[..., :1] < 0.0, -q, q)
    return q / norm_runs(q)[..., None]


def log_so3_runs(R: np.ndarray) -> np.ndarray:
    """Log of each ``(..., 3, 3)`` rotation: ``(..., 3)`` rotation vectors, angle in [0, π]."""
    q = quaternion_from_matrix_runs(R)
    v = q[..., 1:]
    s = norm_runs(v)
    small = s < _SMALL_ANGLE
    safe = np.where(small, 1.0, s)
    scale = np.where(small, 2.0, 2.0 * np.arctan2(s, q[..., 0]) / safe)
    return scale[..., None] * v


def minimal_rotation_runs(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """:func:`minimal_rotation` of each pair (``a``, ``b`` broadcast over leading axes):
    the least rotation taking ``a``'s direction to ``b``'s, ``(..., 3, 3)``."""
    a, b = np.broadcast_arrays(np.asarray(a, dtype=float), np.asarray(b, dtype=float))
    a_unit = a / norm_runs(a)[..., None]
    b_unit = b / norm_runs(b)[..., None]
    axis = cross_runs(a_unit, b_unit)
    sin_angle = norm_runs(axis)
    cos_angle = (a_unit * b_unit).sum(axis=-1)
    aligned = sin_angle < _SMALL_ANGLE
    angle = np.arctan2(sin_angle, cos_angle)
    rotation = axis * (angle / np.where(aligned, 1.0, sin_angle))[..., None]
    # Antiparallel: a half-turn about the axis perpendicular to a from its least-aligned basis axis.
    basis = np.eye(3)[np.argmin(np.abs(a_unit), axis=-1)]
    perpendicular = cross_runs(a_unit, basis)
    half_turn = math.pi * perpendicular / norm_runs(perpendicular)[..., None]
    flip = aligned & (cos_angle <= 0.0)
    rotation = np.where(flip[..., None], half_turn, np.where(aligned[..., None], 0.0, rotation))
    return exp_so3_runs(rotation)
