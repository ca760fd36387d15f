"""Sensors: the dual monostatic sonar."""

from drake_uuv.sensors.dual_sonar import DualSonar, range_difference_noise

__all__ = ["DualSonar", "range_difference_noise"]
