"""Checks a slot's setting makes of its fields: one-line errors naming the field and the value.

A slot's setting (``PlantSetting``, ``AttitudeSetting``, ``TrackingSetting``) is a frozen
dataclass of what every system of the slot gets from the rest of the scenario; its
``__post_init__`` checks each field with these and stores arrays read-only, so a system
can keep them without copying and a setting built by hand fails where it is built.
"""

import math

import numpy as np


def time_step_field(value: float) -> float:
    """``value`` as a float, if it is a finite period > 0."""
    if not (isinstance(value, int | float) and math.isfinite(value) and value > 0.0):
        raise ValueError(f"time_step: must be > 0, got {value!r}")
    return float(value)


def array_field(name: str, value: object, shape: tuple[int, ...]) -> np.ndarray:
    """``value`` as a read-only float array of ``shape`` with finite entries."""
    try:
        array = np.array(value, dtype=float)
    except (TypeError, ValueError):
        array = None
    if array is None or array.shape != shape or not np.all(np.isfinite(array)):
        size = "×".join(map(str, shape))
        raise ValueError(f"{name}: must be {size} finite numbers, got {value!r}")
    array.setflags(write=False)
    return array


def rotation_field(name: str, value: object) -> np.ndarray:
    """``value`` as a read-only 3×3 rotation matrix (orthonormal to 1e-9, determinant +1)."""
    R = array_field(name, value, (3, 3))
    if not np.allclose(R.T @ R, np.eye(3), atol=1e-9) or np.linalg.det(R) < 0.0:
        raise ValueError(f"{name}: must be a rotation matrix, got {R.tolist()!r}")
    return R
