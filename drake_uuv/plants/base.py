"""What every plant gets from the rest of the scenario: :class:`PlantSetting`."""

from dataclasses import dataclass

import numpy as np

from drake_uuv.primitives.setting import array_field, rotation_field, time_step_field


@dataclass(frozen=True)
class PlantSetting:
    """What every system of the plant slot gets besides its own configuration.

    A plant is built as ``cls(config, setting=PlantSetting(...))``; the slot's factory
    (:func:`drake_uuv.plants.make_plant`) makes the setting from the scenario
    (:func:`drake_uuv.plants.factory.plant_setting`). Fields:

    - ``time_step``: t [s], the outer loop's period (the scenario's ``time_step``): the
      commands ``u1_B``, ``u2_W`` change at its ticks.
    - ``initial_position``: ``p_WU(0)`` (3) [m], the body origin U in the world
      (``uuv.initial_position``).
    - ``initial_velocity``: ``v_WU(0)`` (3) [m/s] (``uuv.initial_velocity``).
    - ``initial_R_WB``: ``R_WB(0)`` (3×3), body to world (``uuv.initial_rpy`` as Drake's
      ``RollPitchYaw``).

    Arrays are stored read-only; a bad field raises ``ValueError`` naming it and its value.
    """

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
