"""What every plant gets from the rest of the scenario: :class:`PlantSetting`."""

from dataclasses import dataclass

from drake_uuv.primitives.setting import InitialStateSetting


@dataclass(frozen=True)
class PlantSetting(InitialStateSetting):
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
