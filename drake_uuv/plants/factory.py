"""The plant slot's factory: the system of each variant of ``scenario.plant``."""

from pydrake.systems.framework import System

from drake_uuv.plants.base import PlantSetting
from drake_uuv.plants.hovering_auv import HoveringAuvPlant
from drake_uuv.plants.kinematic_uuv import KinematicUuvPlant
from drake_uuv.primitives.variant_table import variant_system
from drake_uuv.scenario import HoveringAuv, KinematicUuv, Scenario

#: Variant dataclass → its system, built as
#: ``cls(config, setting=PlantSetting(...), batch_size=B)``.
PLANTS: dict[type, type[System]] = {
    KinematicUuv: KinematicUuvPlant,
    HoveringAuv: HoveringAuvPlant,
}


def plant_setting(scenario: Scenario) -> PlantSetting:
    """What a plant gets from ``scenario``: its period and ``scenario.uuv``'s initial state."""
    return PlantSetting.of(scenario.time_step, scenario.uuv)


def make_plant(scenario: Scenario, *, batch_size: int = 1) -> System:
    """The vehicle of ``scenario.plant``'s variant, at ``scenario.uuv``'s initial state, for
    ``batch_size`` runs."""
    cls = variant_system(PLANTS, scenario.plant, "plant")
    return cls(scenario.plant, setting=plant_setting(scenario), batch_size=batch_size)
