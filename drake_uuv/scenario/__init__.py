"""Configuration: the scenario's dataclasses, one per slot variant, loaded from YAML.

``load_scenario("paper", ["tracking=LqrTracking", "tracking.max_acceleration=7"])`` loads a
shipped scenario (``drake_uuv/scenarios/*.yaml``) or a file, applies ``--set`` overrides and
validates it; every error is a one-line :class:`ScenarioError` naming the field and the value.
"""

from drake_uuv.scenario.attitude import (
    AttitudeConfig,
    FixedAttitude,
    InformationSeeking,
    RandomAttitude,
    RateLimitedAttitude,
    TrajectoryAttitude,
)
from drake_uuv.scenario.estimators import (
    NOISE_MODELS,
    Ekf,
    EstimatorConfig,
    EstimatorOptions,
    Iekf,
    LinearizedRangeOptions,
    PaperKf,
    ParticleFilter,
    RawRangeOptions,
    Ukf,
)
from drake_uuv.scenario.loading import (
    apply_override,
    builtin_scenarios,
    load_scenario,
    parse_yaml,
    resolve_scenario_path,
    scenario_description,
    scenario_from_dict,
    validate_scenario,
    variants,
)
from drake_uuv.scenario.navigation import (
    InertialNavigation,
    NavigationConfig,
    NavigationErrors,
    PerfectNavigation,
)
from drake_uuv.scenario.plants import HoveringAuv, KinematicUuv, PlantConfig
from drake_uuv.scenario.schema import (
    SECTIONS,
    SLOTS,
    AnalysisConfig,
    Scenario,
    SonarConfig,
    TargetConfig,
    UuvConfig,
    describe,
    scenario_as_dict,
)
from drake_uuv.scenario.tracking import (
    ALPHA_PROVEN_INTERVAL,
    LqrTracking,
    PaperTracking,
    TrackingConfig,
    TrackingOptions,
)
from drake_uuv.scenario.validation import LIMIT, ScenarioError

__all__ = [
    "ALPHA_PROVEN_INTERVAL",
    "LIMIT",
    "NOISE_MODELS",
    "SECTIONS",
    "SLOTS",
    "AnalysisConfig",
    "AttitudeConfig",
    "Ekf",
    "EstimatorConfig",
    "EstimatorOptions",
    "FixedAttitude",
    "HoveringAuv",
    "InertialNavigation",
    "InformationSeeking",
    "Iekf",
    "KinematicUuv",
    "LinearizedRangeOptions",
    "LqrTracking",
    "NavigationConfig",
    "NavigationErrors",
    "PaperKf",
    "PaperTracking",
    "PerfectNavigation",
    "ParticleFilter",
    "PlantConfig",
    "RandomAttitude",
    "RateLimitedAttitude",
    "RawRangeOptions",
    "Scenario",
    "ScenarioError",
    "SonarConfig",
    "TargetConfig",
    "TrackingConfig",
    "TrackingOptions",
    "TrajectoryAttitude",
    "Ukf",
    "UuvConfig",
    "apply_override",
    "builtin_scenarios",
    "describe",
    "load_scenario",
    "parse_yaml",
    "resolve_scenario_path",
    "scenario_as_dict",
    "scenario_description",
    "scenario_from_dict",
    "validate_scenario",
    "variants",
]
