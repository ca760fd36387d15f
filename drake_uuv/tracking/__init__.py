"""Tracking controllers: the law that holds the target at the desired relative position q*.

Contract of the slot (system ``tracking_controller``): inputs ``x_TU_hat`` and ``R_WB_nav``
(the navigated attitude), and any other signal it needs by name (the LQR law reads
``R_WB_plan``); outputs ``u1_B`` (the paper's u1, body frame) and ``u1_W = R_WB_nav u1_B``
(the filter's known input). A ``gain`` property, the law's 3×6 world-frame gain on the
relative state, gives the closed-loop eigenvalues the metrics report (optional: without it
the metric is NaN). See :mod:`drake_uuv.signals`. Each system is built as
``cls(config, setting=TrackingSetting(...), batch_size=B)``
(:class:`~drake_uuv.tracking.base.TrackingSetting`); with ``batch_size`` B every port holds B
runs row-major (:mod:`drake_uuv.primitives.batch`) and ``gain`` is the same for every run.
"""

from drake_uuv.tracking.base import TrackingSetting
from drake_uuv.tracking.factory import make_tracking_controller, tracking_setting
from drake_uuv.tracking.lqr_tracking import LqrTrackingController
from drake_uuv.tracking.paper_tracking import PaperTrackingController

__all__ = [
    "LqrTrackingController",
    "PaperTrackingController",
    "TrackingSetting",
    "make_tracking_controller",
    "tracking_setting",
]
