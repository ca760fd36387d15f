"""Candidate attitudes within a rotation budget, and the rotation geometry they need.

The information-seeking planner (:mod:`drake_uuv.models.information_planner`) chooses the
next attitude among these candidates.

Candidates: the cheapest rotations within the budget
----------------------------------------------------
The budget ``max_angle_per_step`` bounds the angle of ``R(k+1) R(k)ᵀ``. The two sonars see
the target through the world baseline ``q_s = R b`` alone, so for a given target position
two attitudes with the same ``R b`` measure the same; the cheapest rotation taking the
baseline from direction ``u0`` to ``u`` is the minimal one (axis ``u0 × u``), whose angle is
the angle between the directions. The sign of the baseline carries no information either
(``Y`` changes sign, the two ranges swap), so every baseline *line* lies within π/2 of
``±u0``: the candidates are the minimal rotations to a polar grid of the spherical cap of
half-angle ``min(max_angle_per_step, π/2)`` about ``u0`` (:func:`cap_directions`; for one
scalar measurement the optimum in a cap is the top eigenvector of the prior position
covariance when the cap holds it, else a boundary point, which the grid's outer ring is).

That holds while the target's position does not depend on the attitude. A tracking law
that holds ``q = R q*`` turns the target with the body, and then the whole attitude matters:
with ``position_prediction="reference"`` the candidates are all rotations of the budget's
ball (:func:`ball_rotations`). It matters for the raw-range filters, whose strong
information is along the line of sight ``R q*`` (range noise 0.1 m against a bearing across
a 1.4 m baseline at 2.8 m); in the numpy Riccati loop of the paper scenario, baseline-only
candidates gave the EKF's position 0.26 m at 0.39 rad per step against Algorithm 2's 0.234 m,
whole-attitude candidates 0.173 m.
"""

import math

import numpy as np

from drake_uuv.models.so3 import cross_runs

_SMALL = 1e-12


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def frame_about(u0: np.ndarray) -> np.ndarray:
    """A rotation whose third column is the unit vector ``u0`` (its first two complete it)."""
    helper = np.eye(3)[int(np.argmin(np.abs(u0)))]
    e1 = _unit(cross_runs(u0, helper))
    return np.column_stack([e1, cross_runs(u0, e1), u0])


def cap_directions(u0: np.ndarray, max_angle: float, rings: int = 6) -> np.ndarray:
    """Unit directions of a polar grid of the cap of half-angle ``max_angle`` about ``u0``.

    The first row is ``u0`` itself; ring ``j = 1..rings`` lies at the angle ``j·max_angle/rings``
    from it with points spaced about ``max_angle/rings`` apart along the ring (at least 6), so
    the outer ring is the cap's boundary, where a budget-limited optimum usually lies.
    """
    u0 = _unit(np.asarray(u0, dtype=float).reshape(3))
    frame = frame_about(u0)
    e1, e2 = frame[:, 0], frame[:, 1]
    spacing = max_angle / rings
    rows = [u0[np.newaxis, :]]
    for j in range(1, rings + 1):
        alpha = j * spacing
        count = max(6, math.ceil(2.0 * math.pi * math.sin(alpha) / spacing))
        beta = 2.0 * math.pi * np.arange(count) / count
        ring = (
            math.cos(alpha) * u0
            + math.sin(alpha) * np.cos(beta)[:, np.newaxis] * e1
            + math.sin(alpha) * np.sin(beta)[:, np.newaxis] * e2
        )
        rows.append(ring)
    return np.vstack(rows)


def ball_rotations(max_angle: float, rings: int = 4) -> np.ndarray:
    """Rotation vectors of a grid of the ball ``|φ| ≤ max_angle`` (n×3, the zero vector first).

    Shell ``j = 1..rings`` has radius ``j·max_angle/rings`` and about ``4π j²`` points (at
    least 8) of a Fibonacci sphere, so neighbours are about ``max_angle/rings`` apart; the
    outer shell is the budget's boundary.
    """
    golden = math.pi * (3.0 - math.sqrt(5.0))
    rows = [np.zeros((1, 3))]
    for j in range(1, rings + 1):
        count = max(8, round(4.0 * math.pi * j * j))
        i = np.arange(count) + 0.5
        z = 1.0 - 2.0 * i / count
        radius = np.sqrt(1.0 - z * z)
        azimuth = golden * i + j  # a different twist per shell: no shell-to-shell alignment
        shell = np.stack([radius * np.cos(azimuth), radius * np.sin(azimuth), z], axis=1)
        rows.append(shell * (j * max_angle / rings))
    return np.vstack(rows)


def minimal_rotation_vectors(u0: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Rotation vectors (axis × angle) of the minimal rotations taking ``u0`` to each direction.

    ``u0`` and ``directions`` (n×3) are unit vectors at less than π from each other (the
    planner's cap is at most π/2); a direction equal to ``u0`` gives the zero vector.
    """
    cross = cross_runs(u0, directions)
    sin_angle = np.linalg.norm(cross, axis=1)
    angle = np.arctan2(sin_angle, directions @ u0)
    scale = np.where(sin_angle > _SMALL, angle / np.maximum(sin_angle, _SMALL), 1.0)
    return cross * scale[:, np.newaxis]


def rotate_vectors(rotation_vectors: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``Exp(φ_i) v`` for each rotation vector ``φ_i`` (n×3) and one vector ``v`` (Rodrigues)."""
    angle = np.linalg.norm(rotation_vectors, axis=1)
    axis = rotation_vectors / np.maximum(angle, _SMALL)[:, np.newaxis]
    cos, sin = np.cos(angle)[:, np.newaxis], np.sin(angle)[:, np.newaxis]
    return v * cos + cross_runs(axis, v) * sin + axis * (axis @ v)[:, np.newaxis] * (1.0 - cos)


def rotation_angles(R: np.ndarray) -> np.ndarray:
    """The angle of ``R(k+1) R(k)ᵀ`` for each step of a sequence of rotations (n×3×3 → n−1)."""
    relative = np.einsum("kij,kil->kjl", R[1:], R[:-1])  # R(k+1)ᵀ R(k): same angle
    cos = (np.trace(relative, axis1=1, axis2=2) - 1.0) / 2.0
    # arccos loses precision near 0; the skew part gives sin exactly enough.
    skew = relative - np.transpose(relative, (0, 2, 1))
    sin = 0.5 * np.sqrt(0.5 * np.sum(skew * skew, axis=(1, 2)))
    return np.arctan2(sin, cos)
