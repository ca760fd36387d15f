"""The attitude slot's factory: the system of each variant of ``scenario.attitude``."""

from collections.abc import Callable

from pydrake.systems.framework import LeafSystem

from drake_uuv.attitude.fixed_attitude import FixedAttitudeGenerator
from drake_uuv.attitude.information_seeking import InformationSeekingAttitude
from drake_uuv.attitude.random_attitude import RandomAttitudeGenerator
from drake_uuv.attitude.trajectory_attitude import TrajectoryAttitudeGenerator
from drake_uuv.primitives.variant_table import build_variant
from drake_uuv.scenario import (
    FixedAttitude,
    InformationSeeking,
    RandomAttitude,
    Scenario,
    TrajectoryAttitude,
)

#: Variant dataclass → the constructor of its system from a scenario.
ATTITUDE_GENERATORS: dict[type, Callable[[Scenario], LeafSystem]] = {
    FixedAttitude: FixedAttitudeGenerator.from_scenario,
    RandomAttitude: RandomAttitudeGenerator.from_scenario,
    TrajectoryAttitude: TrajectoryAttitudeGenerator.from_scenario,
    InformationSeeking: InformationSeekingAttitude.from_scenario,
}


def make_attitude_generator(scenario: Scenario) -> LeafSystem:
    """The attitude generator of ``scenario.attitude``'s variant."""
    return build_variant(ATTITUDE_GENERATORS, scenario, "attitude")
