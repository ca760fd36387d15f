"""Estimators of the relative state ``[q, ϑ]`` of the target."""

from drake_uuv.estimators.kalman_filter import RangeDifferenceKalmanFilter
from drake_uuv.estimators.raw_range_filter import RawRangeEstimator

__all__ = ["RangeDifferenceKalmanFilter", "RawRangeEstimator"]
