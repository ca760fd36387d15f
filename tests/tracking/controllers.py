"""The tracking systems of the tests, built from their configuration at the paper's period."""

import numpy as np

from drake_uuv.scenario import LqrTracking, PaperTracking
from drake_uuv.tracking import LqrTrackingController, PaperTrackingController, TrackingSetting
from tests.conftest import T

#: The paper's period t.
SETTING = TrackingSetting(time_step=T)


def lqr_controller(q_star: np.ndarray, **fields) -> LqrTrackingController:
    """The LQR law holding ``q_star`` (the shipped weights unless ``fields`` say otherwise)."""
    config = LqrTracking(desired_relative_position=list(q_star), **fields)
    return LqrTrackingController(config, setting=SETTING)


def paper_controller(q_star: np.ndarray, alpha: float, **fields) -> PaperTrackingController:
    """The paper's law with ``alpha`` holding ``q_star``."""
    config = PaperTracking(desired_relative_position=list(q_star), alpha=alpha, **fields)
    return PaperTrackingController(config, setting=SETTING)
