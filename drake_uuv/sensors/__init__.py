"""Sensors: the dual monostatic sonar, its faults and its timing."""

from drake_uuv.sensors.dual_sonar import DualSonar
from drake_uuv.sensors.sonar_faults import SonarFaults

__all__ = ["DualSonar", "SonarFaults"]
