"""Scenario: every number of a run, as nested dataclasses loaded from YAML.

A scenario file is loaded with Drake's ``yaml_load_typed`` after a pre-check that names the
offending field (Drake's loader does not), then validated as a whole by
:func:`validate_scenario`. Every error is a :class:`ScenarioError` whose message is one line
naming the dotted field and the value, e.g. ``sonar.noise_variances: must be > 0, got [-0.01,
0.01]``.

Defaults are the paper's §IV numbers (design.md §1), so ``Scenario()`` is the paper scenario.
"""

# No `from __future__ import annotations`: Drake's yaml loader needs the real field types.
import dataclasses
import math
import re
import types
import typing
from collections.abc import Iterable
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from pydrake.common.yaml import yaml_load_typed

NOISE_MODELS = ("derived", "paper_printed")
ATTITUDE_MODES = ("fixed", "random", "trajectory")
ESTIMATOR_TYPES = ("kf", "ekf", "iekf")
TRACKING_TYPES = ("paper", "lqr")
ALPHA_PROVEN_INTERVAL = (1.0 - 1.0 / math.sqrt(2.0), 1.0 + 1.0 / math.sqrt(2.0))


class ScenarioError(ValueError):
    """A scenario field has a bad value; the message names the field and the value.

    The message is always one line: control characters from user input are escaped.
    """

    def __init__(self, message: str) -> None:
        super().__init__("".join(c if c.isprintable() else repr(c)[1:-1] for c in message))


class _YamlLoader(yaml.SafeLoader):
    """PyYAML's safe loader with YAML 1.2 floats: ``1e-3`` is a number, not a string."""


_YamlLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(
        r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
        |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
        |\.[0-9_]+(?:[eE][-+][0-9]+)?
        |[-+]?\.(?:inf|Inf|INF)
        |\.(?:nan|NaN|NAN))$""",
        re.X,
    ),
    list("-+0123456789."),
)


def _parse_yaml(text: str) -> Any:
    return yaml.load(text, Loader=_YamlLoader)  # noqa: S506 (a SafeLoader subclass)


def _identity(n: int) -> list[list[float]]:
    return np.eye(n).tolist()


@dataclass
class UuvConfig:
    """Initial state of the vehicle (world frame W, body frame B)."""

    initial_position: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    initial_velocity: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    # Roll-pitch-yaw [rad] of R_WB(0); the paper's R(0) = I.
    initial_rpy: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])


@dataclass
class TargetConfig:
    """The non-cooperative target: a random walk in acceleration."""

    initial_position: list[float] = field(default_factory=lambda: [1.0, 2.0, 2.0])
    initial_velocity: list[float] = field(default_factory=lambda: [0.02, 0.1, 0.1])
    # W, covariance of the target's acceleration [m²/s⁴].
    acceleration_covariance: list[list[float]] = field(
        default_factory=lambda: [[0.004, 0.0, 0.0], [0.0, 0.001, 0.0], [0.0, 0.0, 0.001]]
    )


@dataclass
class SonarConfig:
    """Two monostatic sonars at ±½ baseline about the body origin."""

    # b = ᵇp_s1 − ᵇp_s2 in the body frame [m].
    baseline: list[float] = field(default_factory=lambda: [-1.0, 1.0, 0.0])
    # η1, η2: range noise variances [m²].
    noise_variances: list[float] = field(default_factory=lambda: [0.01, 0.01])
    # f: range samples per sonar and step (the first forms Y; all estimate d̄²).
    samples_per_step: int = 1
    # Faults and limits, all off by default (the paper assumes every return arrives).
    # No return beyond this range [m]; None: unlimited.
    max_range: float | None = None
    # Each pan-tilt sonar points at the predicted target; no return beyond this angle [deg].
    beam_half_angle_deg: float | None = None
    # Within a step the pan-tilt scans this many σ of the predicted position (0: no scan).
    search_sigma: float = 3.0
    # Per sonar, the probability that a step's return is lost.
    dropout_probability: list[float] = field(default_factory=lambda: [0.0, 0.0])
    # Per sonar and step, the probability of a multipath return, longer by an exponentially
    # distributed excess of mean outlier_scale [m].
    outlier_probability: float = 0.0
    outlier_scale: float = 1.0


@dataclass
class EstimatorConfig:
    """The relative-state estimator."""

    type: str = "kf"
    # Mean and variance of the Y noise: "derived" (design.md §1) or the paper's printed formula.
    noise_model: str = "derived"
    # Υ̂(0|−1) = [q̂, ϑ̂] and P(0|−1). The paper sets every unstated initial value to zero.
    initial_estimate: list[float] = field(default_factory=lambda: [0.0] * 6)
    initial_covariance: list[list[float]] = field(default_factory=lambda: _identity(6))
    # Reject a measurement whose NIS exceeds the χ² quantile of this probability; None: no gate.
    gate_probability: float | None = None
    # ekf, iekf (filters on the raw ranges): they start as the paper's linear KF and hand over
    # once trace(P_qq) ≤ linear_start_position_variance [m²], or after linear_start_max_steps
    # linear updates (None: no forced hand-over; 0: no linear start). See
    # estimators/raw_range_filter.py.
    linear_start_position_variance: float = 0.5
    linear_start_max_steps: int | None = None


@dataclass
class AttitudeConfig:
    """The attitude generator: fixed, Algorithm 1 (random) or Algorithm 2 (trajectory)."""

    mode: str = "trajectory"
    # Algorithm 2: ζ(k) = |b| [sin(ρkπ), cos(ρkπ), h(k)], h(k) = amplitude · cos(frequency·kπ).
    rho: float = 1.0 / 24.0
    h_amplitude: float = 0.5
    h_frequency: float = 1.0 / 6.0
    # Largest commanded |u2| [rad/s]; None means unlimited (the paper).
    max_angular_rate: float | None = None


@dataclass
class TrackingConfig:
    """The tracking controller holding q = R q* (q* in the body frame)."""

    # "paper" (§III-B, gain α) or "lqr" (LQR gain plus the attitude plan's feed-forward).
    type: str = "paper"
    alpha: float = 1.2
    desired_relative_position: list[float] = field(default_factory=lambda: [-2.0, -2.0, 0.0])
    # The paper proves bounded tracking only for α in (1 − 1/√2, 1 + 1/√2).
    allow_unproven_alpha: bool = False
    # lqr: Q = diag(position I, velocity I) on the relative-state error, R = input I on the
    # world acceleration (only the ratios matter; see lqr_tracking_controller.py).
    lqr_position_weight: float = 1.0
    lqr_velocity_weight: float = 0.25
    lqr_input_weight: float = 0.1
    # lqr: feed the attitude plan's reference velocity and acceleration forward (false: regulate
    # to the current point R q* only, which lags the turning reference).
    lqr_feedforward: bool = True
    # Largest |world acceleration| [m/s²], applied to either law; None means unlimited.
    max_acceleration: float | None = None


@dataclass
class AnalysisConfig:
    """Post-run analysis: figures and statistics (no effect on the simulation)."""

    # N: window length [steps] of the persistent-excitation figure, which plots the extreme
    # eigenvalues of Σ_{m=k}^{k+N−1} q_s(m) q_s(m)ᵀ (paper eq. 10).
    pe_window: int = 24


@dataclass
class Scenario:
    """One closed-loop run. ``Scenario()`` is the paper's §IV simulation."""

    time_step: float = 0.5
    steps: int = 500
    random_seed: int = 0
    # First step k of the steady-state window over which metrics are taken.
    steady_state_start: int = 200
    uuv: UuvConfig = field(default_factory=UuvConfig)
    target: TargetConfig = field(default_factory=TargetConfig)
    sonar: SonarConfig = field(default_factory=SonarConfig)
    estimator: EstimatorConfig = field(default_factory=EstimatorConfig)
    attitude: AttitudeConfig = field(default_factory=AttitudeConfig)
    tracking: TrackingConfig = field(default_factory=TrackingConfig)
    analysis: AnalysisConfig = field(default_factory=AnalysisConfig)


# ----------------------------------------------------------------------------- loading


def builtin_scenarios() -> list[str]:
    """Names of the scenario files shipped inside the package."""
    folder = resources.files("drake_uuv") / "scenarios"
    return sorted(
        p.name.removesuffix(".yaml") for p in folder.iterdir() if p.name.endswith(".yaml")
    )


def resolve_scenario_path(name_or_path: str) -> Path:
    """A shipped scenario name (``paper``) or a path to a YAML file."""
    path = Path(name_or_path)
    if path.suffix in (".yaml", ".yml") or path.exists():
        if not path.is_file():
            raise ScenarioError(f"scenario: no such file, got {name_or_path!r}")
        return path
    shipped = resources.files("drake_uuv") / "scenarios" / f"{name_or_path}.yaml"
    if not shipped.is_file():
        raise ScenarioError(
            f"scenario: no shipped scenario or file named {name_or_path!r} "
            f"(shipped: {', '.join(builtin_scenarios())})"
        )
    return Path(str(shipped))


def load_scenario(
    name_or_path: str = "paper",
    overrides: Iterable[str] = (),
    seed: int | None = None,
) -> Scenario:
    """Loads, overrides (``dotted.key=value`` strings) and validates a scenario."""
    path = resolve_scenario_path(name_or_path)
    try:
        data = _parse_yaml(path.read_text())
    except yaml.YAMLError as e:
        raise ScenarioError(f"scenario file {str(path)!r}: not valid YAML ({_one_line(e)})") from e
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ScenarioError(f"scenario file {str(path)!r}: must be a mapping, got {data!r}")
    for override in overrides:
        apply_override(data, override)
    if seed is not None:
        data["random_seed"] = seed
    return scenario_from_dict(data)


def scenario_from_dict(data: dict[str, Any]) -> Scenario:
    """Type-checks a plain dict against the schema, loads it with Drake and validates it."""
    _check_types(Scenario, data, prefix="")
    try:
        scenario = yaml_load_typed(schema=Scenario, data=yaml.safe_dump(data))
    except Exception as e:  # Drake's loader: the pre-check should already have caught it.
        raise ScenarioError(f"scenario: {_one_line(e)}") from e
    validate_scenario(scenario)
    return scenario


def apply_override(data: dict[str, Any], override: str) -> None:
    """Applies one ``dotted.key=value`` (value parsed as YAML) to a scenario dict in place."""
    if "=" not in override:
        raise ScenarioError(f"--set: expected dotted.key=value, got {override!r}")
    key, _, text = override.partition("=")
    key = key.strip()
    try:
        value = _parse_yaml(text)
    except yaml.YAMLError as e:
        raise ScenarioError(f"{key}: value is not valid YAML, got {text!r}") from e
    schema: Any = Scenario
    node = data
    parts = key.split(".")
    for depth, part in enumerate(parts):
        fields = {f.name: f for f in dataclasses.fields(schema)}
        if part not in fields:
            prefix = ".".join(parts[:depth])
            raise ScenarioError(
                f"{key}: unknown field {part!r}"
                + (f" in {prefix!r}" if prefix else "")
                + f" (known: {', '.join(fields)})"
            )
        field_type = _resolved_type(schema, part)
        if depth == len(parts) - 1:
            if dataclasses.is_dataclass(field_type):
                raise ScenarioError(f"{key}: is a section; set one of its fields, got {text!r}")
            node[part] = value
            return
        if not dataclasses.is_dataclass(field_type):
            raise ScenarioError(f"{key}: {'.'.join(parts[: depth + 1])!r} has no sub-fields")
        child = node.setdefault(part, {})
        if not isinstance(child, dict):
            child = node[part] = {}
        node, schema = child, field_type


def _resolved_type(schema: Any, name: str) -> Any:
    return typing.get_type_hints(schema)[name]


def _check_types(schema: Any, data: Any, prefix: str) -> None:
    if not isinstance(data, dict):
        raise ScenarioError(f"{prefix.rstrip('.') or 'scenario'}: must be a mapping, got {data!r}")
    hints = typing.get_type_hints(schema)
    for key, value in data.items():
        name = f"{prefix}{key}" if str(key).isidentifier() else f"{prefix}{key!r}"
        if key not in hints:
            raise ScenarioError(f"{name}: unknown field (known: {', '.join(hints)})")
        _check_value(hints[key], value, name)


def _check_value(expected: Any, value: Any, name: str) -> None:
    origin = typing.get_origin(expected)
    if dataclasses.is_dataclass(expected):
        _check_types(expected, value, prefix=f"{name}.")
    elif origin in (typing.Union, types.UnionType):
        options = typing.get_args(expected)
        if value is None and type(None) in options:
            return
        _check_value(next(o for o in options if o is not type(None)), value, name)
    elif origin is list:
        if not isinstance(value, list):
            raise ScenarioError(f"{name}: must be a list, got {value!r}")
        (item_type,) = typing.get_args(expected)
        for item in value:
            _check_value(item_type, item, name)
    elif expected is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ScenarioError(f"{name}: must be a number, got {value!r}")
    elif expected is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ScenarioError(f"{name}: must be an integer, got {value!r}")
    elif expected is bool:
        if not isinstance(value, bool):
            raise ScenarioError(f"{name}: must be true or false, got {value!r}")
    elif expected is str:
        if not isinstance(value, str):
            raise ScenarioError(f"{name}: must be a string, got {value!r}")


def _one_line(error: BaseException) -> str:
    return " ".join(str(error).split())


# -------------------------------------------------------------------------- validation


def _fail(name: str, requirement: str, value: Any) -> None:
    raise ScenarioError(f"{name}: {requirement}, got {value!r}")


# Largest magnitude of any number in a scenario: far beyond any physical value in SI units,
# far below where squares and products in the filter overflow.
LIMIT = 1e6


def _finite(name: str, array: np.ndarray, value: Any) -> None:
    if not np.all(np.isfinite(array)):
        _fail(name, "must be finite", value)
    if np.any(np.abs(array) > LIMIT):
        _fail(name, f"must be at most {LIMIT:g} in magnitude", value)


def _vector(name: str, value: list[float], size: int) -> np.ndarray:
    array = np.asarray(value, dtype=float)
    if array.shape != (size,):
        _fail(name, f"must be a list of {size} numbers", value)
    _finite(name, array, value)
    return array


def _matrix(name: str, value: list[list[float]], size: int) -> np.ndarray:
    if not all(isinstance(row, list) and len(row) == size for row in value) or len(value) != size:
        _fail(name, f"must be a {size}×{size} matrix (list of {size} lists of {size})", value)
    array = np.asarray(value, dtype=float)
    _finite(name, array, value)
    return array


def _positive(name: str, value: float, strict: bool = True) -> None:
    if not math.isfinite(value) or (value <= 0.0 if strict else value < 0.0):
        _fail(name, "must be > 0" if strict else "must be ≥ 0", value)
    _finite(name, np.asarray(value), value)


def _between(name: str, value: float, low: float, high: float) -> None:
    if not (math.isfinite(value) and low <= value <= high):
        _fail(name, f"must be in [{low:g}, {high:g}]", value)


def _spd(name: str, value: list[list[float]], size: int) -> np.ndarray:
    array = _matrix(name, value, size)
    if not np.allclose(array, array.T, rtol=0.0, atol=1e-12 * max(1.0, np.abs(array).max())):
        _fail(name, "must be symmetric", value)
    if np.linalg.eigvalsh(array).min() <= 0.0:
        _fail(name, "must be positive definite", value)
    return array


def _choice(name: str, value: str, options: tuple[str, ...]) -> None:
    if value not in options:
        _fail(name, f"must be one of {', '.join(options)}", value)


def validate_scenario(s: Scenario) -> None:
    """Checks every field of a scenario; raises :class:`ScenarioError` on the first bad one."""
    _between("time_step", s.time_step, 1e-4, 1e3)
    if not 1 <= s.steps <= 10**8:
        _fail("steps", "must be in [1, 1e8]", s.steps)
    if s.random_seed < 0 or s.random_seed >= 2**32:
        _fail("random_seed", "must be in [0, 2**32)", s.random_seed)
    if not 0 <= s.steady_state_start < s.steps:
        _fail("steady_state_start", f"must be in [0, steps={s.steps})", s.steady_state_start)

    _vector("uuv.initial_position", s.uuv.initial_position, 3)
    _vector("uuv.initial_velocity", s.uuv.initial_velocity, 3)
    _vector("uuv.initial_rpy", s.uuv.initial_rpy, 3)

    _vector("target.initial_position", s.target.initial_position, 3)
    _vector("target.initial_velocity", s.target.initial_velocity, 3)
    _spd("target.acceleration_covariance", s.target.acceleration_covariance, 3)

    baseline = _vector("sonar.baseline", s.sonar.baseline, 3)
    if np.linalg.norm(baseline) < 1e-3:
        _fail("sonar.baseline", "must be non-zero (|b| ≥ 1 mm)", s.sonar.baseline)
    eta = _vector("sonar.noise_variances", s.sonar.noise_variances, 2)
    if np.any(eta <= 1e-12):
        _fail("sonar.noise_variances", "must be > 0 (at least 1e-12 m²)", s.sonar.noise_variances)
    if not 1 <= s.sonar.samples_per_step <= 10_000:
        _fail("sonar.samples_per_step", "must be in [1, 10000]", s.sonar.samples_per_step)

    if s.sonar.max_range is not None:
        _positive("sonar.max_range", s.sonar.max_range)
    if s.sonar.beam_half_angle_deg is not None and not 0.0 < s.sonar.beam_half_angle_deg <= 180.0:
        _fail("sonar.beam_half_angle_deg", "must be in (0, 180]", s.sonar.beam_half_angle_deg)
    _positive("sonar.search_sigma", s.sonar.search_sigma, strict=False)
    dropout = _vector("sonar.dropout_probability", s.sonar.dropout_probability, 2)
    if np.any((dropout < 0.0) | (dropout >= 1.0)):
        _fail("sonar.dropout_probability", "must be in [0, 1)", s.sonar.dropout_probability)
    if not 0.0 <= s.sonar.outlier_probability < 1.0:
        _fail("sonar.outlier_probability", "must be in [0, 1)", s.sonar.outlier_probability)
    _positive("sonar.outlier_scale", s.sonar.outlier_scale)

    _choice("estimator.type", s.estimator.type, ESTIMATOR_TYPES)
    _choice("estimator.noise_model", s.estimator.noise_model, NOISE_MODELS)
    _vector("estimator.initial_estimate", s.estimator.initial_estimate, 6)
    _spd("estimator.initial_covariance", s.estimator.initial_covariance, 6)
    gate = s.estimator.gate_probability
    if gate is not None and not (math.isfinite(gate) and 0.0 < gate < 1.0):
        _fail("estimator.gate_probability", "must be in (0, 1)", gate)
    e = s.estimator
    _positive("estimator.linear_start_position_variance", e.linear_start_position_variance)
    if e.linear_start_max_steps is not None and e.linear_start_max_steps < 0:
        _fail("estimator.linear_start_max_steps", "must be ≥ 0", e.linear_start_max_steps)

    _choice("attitude.mode", s.attitude.mode, ATTITUDE_MODES)
    for name in ("rho", "h_amplitude", "h_frequency"):
        value = getattr(s.attitude, name)
        _finite(f"attitude.{name}", np.asarray(value), value)
    if s.attitude.max_angular_rate is not None:
        _positive("attitude.max_angular_rate", s.attitude.max_angular_rate)

    _choice("tracking.type", s.tracking.type, TRACKING_TYPES)
    alpha = s.tracking.alpha
    _positive("tracking.alpha", alpha)
    low, high = ALPHA_PROVEN_INTERVAL
    if not low < alpha < high and not s.tracking.allow_unproven_alpha:
        _fail(
            "tracking.alpha",
            f"must be in ({low:.4f}, {high:.4f}) where the paper proves bounded tracking "
            "(set tracking.allow_unproven_alpha=true to run it anyway)",
            alpha,
        )
    _vector("tracking.desired_relative_position", s.tracking.desired_relative_position, 3)
    _positive("tracking.lqr_position_weight", s.tracking.lqr_position_weight)
    _positive("tracking.lqr_velocity_weight", s.tracking.lqr_velocity_weight, strict=False)
    _positive("tracking.lqr_input_weight", s.tracking.lqr_input_weight)
    if s.tracking.max_acceleration is not None:
        _positive("tracking.max_acceleration", s.tracking.max_acceleration)

    if not 1 <= s.analysis.pe_window <= 10**6:
        _fail("analysis.pe_window", "must be in [1, 1e6]", s.analysis.pe_window)
