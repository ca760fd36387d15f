"""Estimators of the relative state ``[q, ϑ]`` of the target: the estimator slot.

Contract of the slot (system ``estimator``): a
:class:`~drake_uuv.estimators.base.RelativeStateEstimator`, built as ``cls(config,
setting=EstimatorSetting(...))``. It reads the sonar's ranges (``range_samples``,
``sonar_status``), the attitude ``R_WB_nav`` (for the world baseline) and the vehicle's own
motion (``u1_W``, or ``p_WU_nav``, ``v_WU_nav``), and outputs ``x_TU_hat``/``P_TU`` (the
filtered estimate at step k, a direct feedthrough of the ranges only),
``x_TU_prior``/``P_TU_prior`` (the prediction, state only), ``measurement_status`` and ``nis``.
See :mod:`drake_uuv.estimators.base` for the hooks a variant supplies and :mod:`drake_uuv.signals`
for the signals.
"""

from drake_uuv.estimators.base import (
    Estimate,
    EstimatorSetting,
    FilteredEstimate,
    MeasurementUpdate,
    Ranges,
    RelativeStateEstimator,
)
from drake_uuv.estimators.factory import ESTIMATORS, estimator_setting, make_estimator
from drake_uuv.estimators.kalman_filter import RangeDifferenceKalmanFilter
from drake_uuv.estimators.linear_start import LinearStart
from drake_uuv.estimators.marginalized_cloud import MarginalizedCloud, MarginalizedRangeFilter
from drake_uuv.estimators.particle_cloud import ParticleCloud
from drake_uuv.estimators.range_filter import RangeFilter

__all__ = [
    "ESTIMATORS",
    "Estimate",
    "EstimatorSetting",
    "FilteredEstimate",
    "LinearStart",
    "MarginalizedCloud",
    "MarginalizedRangeFilter",
    "MeasurementUpdate",
    "ParticleCloud",
    "RangeDifferenceKalmanFilter",
    "RangeFilter",
    "Ranges",
    "RelativeStateEstimator",
    "estimator_setting",
    "make_estimator",
]
