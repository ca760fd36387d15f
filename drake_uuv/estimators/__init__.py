"""Estimators of the relative state ``[q, ϑ]`` of the target.

Contract of the slot (system ``estimator``): every estimator is a
:class:`~drake_uuv.estimators.base.RelativeStateEstimator`. It reads the sonar's outputs it
needs by name (``Y``, ``m``, ``Gamma``, ``b_W``, ``range_samples``), ``sonar_status`` and
``u1_W`` (the vehicle's applied world acceleration), and outputs ``x_TU_hat``/``P_TU`` (the
filtered estimate at step k, direct feedthrough of the measurement only),
``x_TU_prior``/``P_TU_prior`` (the prediction, state only), ``measurement_status`` and
``nis``. See :mod:`drake_uuv.signals`.
"""

from drake_uuv.estimators.base import RelativeStateEstimator
from drake_uuv.estimators.factory import make_estimator
from drake_uuv.estimators.kalman_filter import RangeDifferenceKalmanFilter
from drake_uuv.estimators.linear_start import LinearStartEstimator
from drake_uuv.estimators.particle_filter import ParticleRangeEstimator
from drake_uuv.estimators.raw_range_filter import RawRangeEstimator
from drake_uuv.estimators.unscented_filter import UnscentedRangeEstimator

__all__ = [
    "LinearStartEstimator",
    "ParticleRangeEstimator",
    "RangeDifferenceKalmanFilter",
    "RawRangeEstimator",
    "RelativeStateEstimator",
    "UnscentedRangeEstimator",
    "make_estimator",
]
