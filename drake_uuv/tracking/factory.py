"""The tracking slot's factory: the system of each variant of ``scenario.tracking``."""

from pydrake.systems.framework import LeafSystem

from drake_uuv.models.information import PlannedMeasurement
from drake_uuv.primitives.variant_table import variant_system
from drake_uuv.scenario import LqrTracking, PaperTracking, Scenario
from drake_uuv.tracking.base import TrackingSetting
from drake_uuv.tracking.lqr_tracking import LqrTrackingController
from drake_uuv.tracking.paper_tracking import PaperTrackingController

#: Variant dataclass → its system, built as
#: ``cls(config, setting=TrackingSetting(...), batch_size=B)``.
TRACKING_CONTROLLERS: dict[type, type[LeafSystem]] = {
    PaperTracking: PaperTrackingController,
    LqrTracking: LqrTrackingController,
}


def tracking_setting(scenario: Scenario) -> TrackingSetting:
    """What a tracking law gets from ``scenario``: the period, the plant's top speed and
    whether the estimator hands over from a linear start (a raw-range filter's)."""
    measurement = scenario.estimator.planning_model().measurement
    return TrackingSetting(
        time_step=scenario.time_step,
        max_speed=scenario.plant.top_speed(),
        estimator_hands_over=measurement == PlannedMeasurement.RANGES,
    )


def make_tracking_controller(scenario: Scenario, *, batch_size: int = 1) -> LeafSystem:
    """The tracking controller of ``scenario.tracking``'s variant, stepping ``batch_size``
    runs."""
    cls = variant_system(TRACKING_CONTROLLERS, scenario.tracking, "tracking")
    return cls(scenario.tracking, setting=tracking_setting(scenario), batch_size=batch_size)
