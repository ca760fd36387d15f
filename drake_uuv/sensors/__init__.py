"""Sensors: the dual monostatic sonar."""

from drake_uuv.sensors.dual_sonar import DualSonar, SonarFaults

__all__ = ["DualSonar", "SonarFaults"]
