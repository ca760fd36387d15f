"""Controllers: the attitude generator (Algorithms 1 and 2) and the tracking controllers."""

from drake_uuv.controllers.attitude_generator import AttitudeGenerator
from drake_uuv.controllers.lqr_tracking_controller import LqrTrackingController
from drake_uuv.controllers.tracking_controller import TrackingController

__all__ = ["AttitudeGenerator", "LqrTrackingController", "TrackingController"]
