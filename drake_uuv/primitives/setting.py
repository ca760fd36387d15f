"""Checks a slot's setting makes of its fields: one-line errors naming the field and the value.

A slot's setting (``PlantSetting``, ``NavigationSetting``, ``AttitudeSetting``,
``TrackingSetting``) is a frozen dataclass of what every system of the slot gets from the rest
of the scenario; its ``__post_init__`` checks each field with these and stores arrays
read-only, so a system can keep them without copying and a setting built by hand fails where
it is built. :class:`InitialStateSetting` is the fields two slots share: the period and the
vehicle's state at k = 0.
"""

import math
from dataclasses import dataclass
from typing import Self

import numpy as np
from pydrake.math import RollPitchYaw, RotationMatrix

from drake_uuv.scenario.schema import UuvConfig


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


@dataclass(frozen=True)
class InitialStateSetting:
    """The loop's period and the vehicle's state at k = 0: ``time_step`` t [s],
    ``initial_position`` ``p_WU(0)`` (3) [m], ``initial_velocity`` ``v_WU(0)`` (3) [m/s],
    ``initial_R_WB`` ``R_WB(0)`` (3×3, body to world); checked and stored read-only."""

    time_step: float
    initial_position: np.ndarray
    initial_velocity: np.ndarray
    initial_R_WB: np.ndarray

    def __post_init__(self) -> None:
        object.__setattr__(self, "time_step", time_step_field(self.time_step))
        p, v = self.initial_position, self.initial_velocity
        object.__setattr__(self, "initial_position", array_field("initial_position", p, (3,)))
        object.__setattr__(self, "initial_velocity", array_field("initial_velocity", v, (3,)))
        object.__setattr__(self, "initial_R_WB", rotation_field("initial_R_WB", self.initial_R_WB))

    @classmethod
    def of(cls, time_step: float, uuv: UuvConfig) -> Self:
        """The setting of period ``time_step`` and ``uuv``'s initial state (its
        ``initial_rpy`` as Drake's ``RollPitchYaw``)."""
        rpy = RollPitchYaw(np.asarray(uuv.initial_rpy, dtype=float))
        return cls(
            time_step, uuv.initial_position, uuv.initial_velocity, RotationMatrix(rpy).matrix()
        )
