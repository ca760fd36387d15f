"""The attitude slot's factory: the system of each variant of ``scenario.attitude``.

The wiring across slots lives here: an attitude planner plans for the scenario's estimator
and tracking law, through what their configurations say a planner may assume of them
(their ``planning_model()``).
"""

from pydrake.systems.framework import LeafSystem

from drake_uuv.attitude.base import AttitudeSetting
from drake_uuv.attitude.fixed_attitude import FixedAttitudeGenerator
from drake_uuv.attitude.information_seeking import InformationSeekingAttitude
from drake_uuv.attitude.random_attitude import RandomAttitudeGenerator
from drake_uuv.attitude.trajectory_attitude import TrajectoryAttitudeGenerator
from drake_uuv.primitives.variant_table import variant_system
from drake_uuv.scenario import (
    FixedAttitude,
    InformationSeeking,
    RandomAttitude,
    Scenario,
    TrajectoryAttitude,
)

#: Variant dataclass → its system, built as
#: ``cls(config, setting=AttitudeSetting(...), batch_size=B)``.
ATTITUDE_GENERATORS: dict[type, type[LeafSystem]] = {
    FixedAttitude: FixedAttitudeGenerator,
    RandomAttitude: RandomAttitudeGenerator,
    TrajectoryAttitude: TrajectoryAttitudeGenerator,
    InformationSeeking: InformationSeekingAttitude,
}


def attitude_setting(scenario: Scenario) -> AttitudeSetting:
    """What an attitude generator gets from ``scenario``: the period, the sonars, the target's
    W, and what the estimator and the tracking law let a planner assume of them."""
    return AttitudeSetting(
        time_step=scenario.time_step,
        baseline_B=scenario.sonar.baseline,
        noise_variances=scenario.sonar.noise_variances,
        samples_per_step=scenario.sonar.samples_per_step,
        acceleration_covariance=scenario.target.acceleration_covariance,
        estimator=scenario.estimator.planning_model(),
        tracking=scenario.tracking.planning_model(),
    )


def make_attitude_generator(scenario: Scenario, *, batch_size: int = 1) -> LeafSystem:
    """The attitude generator of ``scenario.attitude``'s variant, stepping ``batch_size``
    runs."""
    cls = variant_system(ATTITUDE_GENERATORS, scenario.attitude, "attitude")
    return cls(scenario.attitude, setting=attitude_setting(scenario), batch_size=batch_size)
