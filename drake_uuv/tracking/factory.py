"""The tracking slot's factory: the system of each variant of ``scenario.tracking``."""

from collections.abc import Callable

from pydrake.systems.framework import LeafSystem

from drake_uuv.primitives.variant_table import build_variant
from drake_uuv.scenario import LqrTracking, PaperTracking, Scenario
from drake_uuv.tracking.lqr_tracking import LqrTrackingController
from drake_uuv.tracking.paper_tracking import PaperTrackingController

#: Variant dataclass → the constructor of its system from a scenario.
TRACKING_CONTROLLERS: dict[type, Callable[[Scenario], LeafSystem]] = {
    PaperTracking: PaperTrackingController.from_scenario,
    LqrTracking: LqrTrackingController.from_scenario,
}


def make_tracking_controller(scenario: Scenario) -> LeafSystem:
    """The tracking controller of ``scenario.tracking``'s variant."""
    return build_variant(TRACKING_CONTROLLERS, scenario, "tracking")
