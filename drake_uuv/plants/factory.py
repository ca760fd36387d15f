"""The plant slot's factory: the system of each variant of ``scenario.plant``."""

from collections.abc import Callable

from pydrake.systems.framework import System

from drake_uuv.plants.hovering_auv import HoveringAuvPlant
from drake_uuv.plants.kinematic_uuv import KinematicUuvPlant
from drake_uuv.scenario import HoveringAuv, KinematicUuv, Scenario

#: Variant dataclass → the constructor of its system from a scenario.
PLANTS: dict[type, Callable[[Scenario], System]] = {
    KinematicUuv: KinematicUuvPlant.from_scenario,
    HoveringAuv: HoveringAuvPlant.from_scenario,
}


def make_plant(scenario: Scenario) -> System:
    """The vehicle of ``scenario.plant``'s variant, at ``scenario.uuv``'s initial state."""
    make = PLANTS.get(type(scenario.plant))
    if make is None:
        raise TypeError(f"plant: no system for !{type(scenario.plant).__name__}")
    return make(scenario)
