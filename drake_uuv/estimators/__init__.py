"""Estimators of the relative state ``[q, ϑ]`` of the target."""

from drake_uuv.estimators.kalman_filter import RangeDifferenceKalmanFilter

__all__ = ["RangeDifferenceKalmanFilter"]
