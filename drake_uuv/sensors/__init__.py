"""Sensors: the dual monostatic sonar."""

from drake_uuv.sensors.dual_sonar import DualSonar, SonarFaults, range_difference_noise

__all__ = ["DualSonar", "SonarFaults", "range_difference_noise"]
