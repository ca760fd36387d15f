"""Rotation matrices to and from unit quaternions ``[w, x, y, z]``, over a leading axis."""

import numpy as np


def quaternion_from_matrices(R: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotation matrices as (N, 4) unit quaternions ``[w, x, y, z]``, ``w ≥ 0``.

    Shepperd's method: each from the largest of ``1 + tr R`` and ``1 + 2 R_ii − tr R``, so no
    division by a small number.
    """
    R = np.asarray(R, dtype=float).reshape(-1, 3, 3)
    trace = np.trace(R, axis1=1, axis2=2)
    diagonal = np.diagonal(R, axis1=1, axis2=2)
    choice = np.argmax(np.column_stack([trace, diagonal]), axis=1)
    q = np.empty((len(R), 4))
    for c in range(4):
        rows = choice == c
        if not np.any(rows):
            continue
        m = R[rows]
        if c == 0:
            s = 2.0 * np.sqrt(1.0 + trace[rows])
            q[rows] = np.column_stack(
                [0.25 * s, (m[:, 2, 1] - m[:, 1, 2]) / s, (m[:, 0, 2] - m[:, 2, 0]) / s,
                 (m[:, 1, 0] - m[:, 0, 1]) / s]
            )  # fmt: skip
            continue
        i = c - 1
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * np.sqrt(1.0 + m[:, i, i] - m[:, j, j] - m[:, k, k])
        part = np.empty((len(m), 4))
        part[:, 0] = (m[:, k, j] - m[:, j, k]) / s
        part[:, 1 + i] = 0.25 * s
        part[:, 1 + j] = (m[:, j, i] + m[:, i, j]) / s
        part[:, 1 + k] = (m[:, k, i] + m[:, i, k]) / s
        q[rows] = part
    q *= np.where(q[:, :1] < 0.0, -1.0, 1.0)
    return q


def matrices_from_quaternions(q: np.ndarray) -> np.ndarray:
    """(N, 4) quaternions ``[w, x, y, z]`` (normalised here) as (N, 3, 3) rotation matrices."""
    q = np.asarray(q, dtype=float).reshape(-1, 4)
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        axis=1,
    )
