"""The estimator slot's factory: the system of each variant of ``scenario.estimator``."""

import numpy as np

from drake_uuv.estimators.base import EstimatorSetting, RelativeStateEstimator
from drake_uuv.estimators.kalman_filter import RangeDifferenceKalmanFilter
from drake_uuv.estimators.marginalized_cloud import MarginalizedRangeFilter
from drake_uuv.estimators.range_filter import RangeFilter
from drake_uuv.models.timing import PingSchedule
from drake_uuv.primitives.variant_table import variant_system
from drake_uuv.scenario import Ekf, Iekf, PaperKf, ParticleFilter, Scenario, Ukf
from drake_uuv.scenario.estimators import MarginalizedParticleFilter

#: Variant dataclass → the class of its system, built as
#: ``cls(config, setting=..., batch_size=B)``.
ESTIMATORS: dict[type, type[RelativeStateEstimator]] = {
    PaperKf: RangeDifferenceKalmanFilter,
    Ekf: RangeFilter,
    Iekf: RangeFilter,
    Ukf: RangeFilter,
    ParticleFilter: RangeFilter,
    MarginalizedParticleFilter: MarginalizedRangeFilter,
}


def estimator_setting(scenario: Scenario) -> EstimatorSetting:
    """What every estimator gets from the rest of ``scenario``: the time step, the target's
    acceleration covariance, the sonars' noise, samples, baseline, timing and sound-speed
    error, and the navigation's error figures."""
    return EstimatorSetting(
        time_step=scenario.time_step,
        acceleration_covariance=np.asarray(scenario.target.acceleration_covariance),
        noise_variances=np.asarray(scenario.sonar.noise_variances),
        samples_per_step=scenario.sonar.samples_per_step,
        baseline_B=np.asarray(scenario.sonar.baseline),
        ping_schedule=PingSchedule(
            scenario.time_step, tuple(scenario.sonar.ping_offsets), scenario.sonar.latency
        ),
        navigation_errors=scenario.navigation.error_figures(),
        sound_speed_error=scenario.sonar.sound_speed_error,
    )


def make_estimator(scenario: Scenario, *, batch_size: int = 1) -> RelativeStateEstimator:
    """The estimator of ``scenario.estimator``'s variant, stepping ``batch_size`` runs."""
    cls = variant_system(ESTIMATORS, scenario.estimator, "estimator")
    return cls(scenario.estimator, setting=estimator_setting(scenario), batch_size=batch_size)
