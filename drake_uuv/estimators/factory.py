"""The estimator slot's factory: the system of each variant of ``scenario.estimator``."""

from collections.abc import Callable

from drake_uuv.estimators.base import RelativeStateEstimator
from drake_uuv.estimators.kalman_filter import RangeDifferenceKalmanFilter
from drake_uuv.estimators.particle_filter import ParticleRangeEstimator
from drake_uuv.estimators.raw_range_filter import RawRangeEstimator
from drake_uuv.estimators.unscented_filter import UnscentedRangeEstimator
from drake_uuv.primitives.variant_table import build_variant
from drake_uuv.scenario import Ekf, Iekf, PaperKf, ParticleFilter, Scenario, Ukf

#: Variant dataclass → the constructor of its system from a scenario.
ESTIMATORS: dict[type, Callable[[Scenario], RelativeStateEstimator]] = {
    PaperKf: RangeDifferenceKalmanFilter.from_scenario,
    Ekf: RawRangeEstimator.from_scenario,
    Iekf: RawRangeEstimator.from_scenario,
    Ukf: UnscentedRangeEstimator.from_scenario,
    ParticleFilter: ParticleRangeEstimator.from_scenario,
}


def make_estimator(scenario: Scenario) -> RelativeStateEstimator:
    """The estimator of ``scenario.estimator``'s variant."""
    return build_variant(ESTIMATORS, scenario, "estimator")
