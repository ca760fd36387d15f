"""The loop as two halves over LCM, as Drake's hardware station: the onboard half (estimator,
attitude, tracking) and the vehicle half (plant, target, sonars, navigation), built from one
scenario, talking over Drake's LCM systems (:mod:`.channels` documents the channels)."""

from drake_uuv.hardware.channels import (
    INITIALIZED,
    ONBOARD,
    READY,
    VEHICLE,
    Channel,
    SplitError,
    channels,
    check_url,
)
from drake_uuv.hardware.halves import Half, LcmTimeout
from drake_uuv.hardware.loop import run_lcm, run_onboard, run_vehicle

__all__ = [
    "INITIALIZED",
    "ONBOARD",
    "READY",
    "VEHICLE",
    "Channel",
    "Half",
    "SplitError",
    "check_url",
    "LcmTimeout",
    "channels",
    "run_lcm",
    "run_onboard",
    "run_vehicle",
]
