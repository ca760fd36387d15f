"""The plant slot's factory: the system of each variant of ``scenario.plant``."""

from collections.abc import Callable

from pydrake.systems.framework import System

from drake_uuv.plants.hovering_auv import HoveringAuvPlant
from drake_uuv.plants.kinematic_uuv import KinematicUuvPlant
from drake_uuv.primitives.variant_table import build_variant
from drake_uuv.scenario import HoveringAuv, KinematicUuv, Scenario

#: Variant dataclass → the constructor of its system from a scenario.
PLANTS: dict[type, Callable[[Scenario], System]] = {
    KinematicUuv: KinematicUuvPlant.from_scenario,
    HoveringAuv: HoveringAuvPlant.from_scenario,
}


def make_plant(scenario: Scenario) -> System:
    """The vehicle of ``scenario.plant``'s variant, at ``scenario.uuv``'s initial state."""
    return build_variant(PLANTS, scenario, "plant")
