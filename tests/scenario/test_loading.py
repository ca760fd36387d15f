"""Scenario loading, overrides and validation: every error names the field and the value."""

import dataclasses
import math
import re
from pathlib import Path

import pytest

from drake_uuv.scenario import (
    SLOTS,
    Ekf,
    FixedAttitude,
    KinematicUuv,
    LqrTracking,
    PaperKf,
    PaperTracking,
    Scenario,
    ScenarioError,
    TrajectoryAttitude,
    builtin_scenarios,
    load_scenario,
    variants,
)


def test_paper_file_is_the_papers_numbers() -> None:
    scenario = load_scenario("paper")
    assert scenario == Scenario()
    assert "paper" in builtin_scenarios()
    assert scenario.time_step == 0.5 and scenario.steps == 500
    assert scenario.target.acceleration_covariance == [
        [0.004, 0.0, 0.0],
        [0.0, 0.001, 0.0],
        [0.0, 0.0, 0.001],
    ]
    assert scenario.sonar.noise_variances == [0.01, 0.01]
    assert isinstance(scenario.plant, KinematicUuv)
    assert isinstance(scenario.estimator, PaperKf)
    assert isinstance(scenario.attitude, TrajectoryAttitude)
    assert scenario.attitude.rho == pytest.approx(1 / 24)
    assert isinstance(scenario.tracking, PaperTracking) and scenario.tracking.alpha == 1.2


def test_overrides_and_seed() -> None:
    scenario = load_scenario(
        "paper",
        ["estimator.noise_model=paper_printed", "steps=2000",
         "sonar.noise_variances=[0.02, 0.03]", "attitude.max_angular_rate=0.5"],
        seed=9,
    )  # fmt: skip
    assert scenario.estimator.noise_model == "paper_printed"
    assert scenario.steps == 2000 and scenario.random_seed == 9
    assert scenario.sonar.noise_variances == [0.02, 0.03]
    assert scenario.attitude.max_angular_rate == 0.5


def test_yaml_file_path(tmp_path) -> None:
    path = tmp_path / "short.yaml"
    path.write_text("steps: 50\nsteady_state_start: 10\nsonar:\n  samples_per_step: 4\n")
    scenario = load_scenario(str(path))
    assert scenario.steps == 50 and scenario.sonar.samples_per_step == 4
    assert scenario.target == Scenario().target  # unspecified fields keep the paper's values


def _names(slot: str) -> str:
    """The slot's variants as the loader lists them, regex-escaped: ``PaperTracking, Lqr…``."""
    return re.escape(", ".join(variants(Scenario, slot)))


@pytest.mark.parametrize(
    "override, message",
    [
        ("bogus=1", r"^bogus: unknown field 'bogus'"),
        ("sonar.bogus=1", r"^sonar.bogus: unknown field 'bogus' in 'sonar'"),
        ("steps.x=1", r"^steps.x: 'steps' has no sub-fields"),
        ("sonar=3", r"^sonar: is a section"),
        ("tracking=3", rf"^tracking: is a variant section; choose a variant by name, e.g. --set tracking=PaperTracking \(variants: {_names('tracking')}\), got 3$"),
        ("tracking={alpha: 1.0}", r"^tracking: is a variant section; .*got \{'alpha': 1.0\}$"),
        ("tracking=!Pid", rf"^tracking: unknown variant !Pid \(known: {_names('tracking')}\)$"),
        ("tracking=Pid", rf"^tracking: unknown variant Pid \(known: {_names('tracking')}\)$"),
        ("estimator=ekf {gate_probability: 0.99}", rf"^estimator: unknown variant ekf \(known: {_names('estimator')}\)$"),
        ("tracking=!LqrTracking [1, 2]", r"^tracking: LqrTracking takes a mapping of fields, got \[1, 2\]$"),
        ("tracking=LqrTracking [1, 2]", r"^tracking: LqrTracking takes a mapping of fields, got \[1, 2\]$"),
        ("tracking=LqrTracking {max_acceleration: [1}", r"^tracking: value is not valid YAML"),
        ("tracking.type=lqr", rf"^tracking.type: unknown field 'type' in 'tracking' \(fields of PaperTracking: desired_relative_position, reference_frame, max_acceleration, caution_position_std, caution_scaling, hold_until_handover, max_speed, alpha, allow_unproven_alpha\); to change the variant, --set tracking=Name \({_names('tracking')}\)$"),
        ("attitude.mode=fixed", rf"^attitude.mode: unknown field 'mode' in 'attitude'.*--set attitude=Name \({_names('attitude')}\)$"),
        ("estimator.type=ekf", rf"^estimator.type: unknown field 'type' in 'estimator'.*--set estimator=Name \({_names('estimator')}\)$"),
        ("sonar.baseline=!Foo [1, 2, 3]", r"^sonar.baseline: takes no !tag, got !Foo"),
        ("steps=abc", r"^steps: must be an integer, got 'abc'"),
        ("steps=0", r"^steps: must be in \[1, 1e8\], got 0"),
        ("time_step=-0.5", r"^time_step: must be in \[0.0001, 1000\], got -0.5"),
        ("time_step=1e-300", r"^time_step: must be in \[0.0001, 1000\], got 1e-300"),
        ("target.initial_position=[1e300, 0, 0]", r"^target.initial_position: must be at most 1e\+06 in magnitude"),
        ("time_step=.nan", r"^time_step: must be in \[0.0001, 1000\], got nan"),
        ("sonar.baseline=[1, 2]", r"^sonar.baseline: must be a list of 3 numbers, got \[1.0, 2.0\]"),
        ("sonar.baseline=[0, 0, 0]", r"^sonar.baseline: must be non-zero"),
        ("sonar.noise_variances=[-0.01, 0.01]", r"^sonar.noise_variances: must be > 0 \(at least 1e-12 m²\), got \[-0.01, 0.01\]"),
        ("sonar.samples_per_step=0", r"^sonar.samples_per_step: must be in \[1, 10000\], got 0"),
        ("target.acceleration_covariance=[[1,0,0],[0,1,0],[0,0,-1]]", r"^target.acceleration_covariance: must be positive definite"),
        ("target.acceleration_covariance=[[1,0.5,0],[0,1,0],[0,0,1]]", r"^target.acceleration_covariance: must be symmetric"),
        ("target.acceleration_covariance=[[1,0],[0,1]]", r"^target.acceleration_covariance: must be a 3×3 matrix"),
        ("estimator.noise_model=exact", r"^estimator.noise_model: must be one of derived, paper_printed, got 'exact'"),
        ("attitude.max_angular_rate=0", r"^attitude.max_angular_rate: must be > 0, got 0.0"),
        ("tracking.alpha=1.8", r"^tracking.alpha: must be in \(0.2929, 1.7071\).*got 1.8"),
        ("tracking.alpha=0.2", r"^tracking.alpha: must be in \(0.2929, 1.7071\).*got 0.2"),
        ("tracking.desired_relative_position=[1, 2, x]", r"^tracking.desired_relative_position: must be a number, got 'x'"),
        ("steady_state_start=600", r"^steady_state_start: must be in \[0, steps=500\), got 600"),
        ("random_seed=-1", r"^random_seed: must be in \[0, 2\*\*32\), got -1"),
        ("noequals", r"^--set: expected dotted.key=value, got 'noequals'"),
        ("steps=[1", r"^steps: value is not valid YAML"),
    ],
)  # fmt: skip
def test_bad_values_name_the_field_and_the_value(override: str, message: str) -> None:
    with pytest.raises(ScenarioError, match=message) as info:
        load_scenario("paper", [override])
    assert "\n" not in str(info.value)


def test_alpha_outside_the_proven_interval_is_allowed_explicitly() -> None:
    scenario = load_scenario("paper", ["tracking.alpha=1.8", "tracking.allow_unproven_alpha=true"])
    assert scenario.tracking.alpha == 1.8
    low, high = 1 - 1 / math.sqrt(2), 1 + 1 / math.sqrt(2)
    assert not low < scenario.tracking.alpha < high


@pytest.mark.parametrize(
    "text, message",
    [
        ("steps: [1, 2\n", r"not valid YAML"),
        ("- 1\n- 2\n", r"must be a mapping"),
        ("sonar: 3\n", r"^sonar: must be a mapping, got 3"),
        ("uuv:\n  initial_rpy: [0, 0]\n", r"^uuv.initial_rpy: must be a list of 3 numbers"),
    ],
)
def test_bad_files(tmp_path, text: str, message: str) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ScenarioError, match=message):
        load_scenario(str(path))


def test_missing_scenario() -> None:
    with pytest.raises(ScenarioError, match=r"no shipped scenario or file named 'nope'"):
        load_scenario("nope")
    with pytest.raises(ScenarioError, match=r"no such file, got 'missing.yaml'"):
        load_scenario("missing.yaml")


def test_every_field_has_a_default() -> None:
    def walk(cls) -> None:
        for field in dataclasses.fields(cls):
            assert field.default is not dataclasses.MISSING or (
                field.default_factory is not dataclasses.MISSING
            ), field.name

    walk(Scenario)
    for slot in SLOTS:
        for kind in variants(Scenario, slot).values():
            walk(kind)


def test_switching_a_variant_keeps_the_shared_fields() -> None:
    scenario = load_scenario(
        "paper",
        ["tracking.desired_relative_position=[-5, 0, 0]", "tracking.max_acceleration=3",
         "tracking=!LqrTracking {input_weight: 0.5}", "estimator.gate_probability=0.99",
         "estimator=!Ekf"],
    )  # fmt: skip
    assert scenario.tracking == LqrTracking(
        desired_relative_position=[-5.0, 0.0, 0.0], max_acceleration=3.0, input_weight=0.5
    )
    assert isinstance(scenario.estimator, Ekf) and scenario.estimator.gate_probability == 0.99
    # Fields the new variant does not have are dropped, not carried into it.
    switched = load_scenario("paper", ["tracking.alpha=1.0", "tracking=!LqrTracking"])
    assert switched.tracking == LqrTracking()
    # And switching back gives the new variant's defaults for its own fields.
    back = load_scenario("paper", ["tracking=!LqrTracking", "tracking=!PaperTracking"])
    assert back.tracking == PaperTracking()


def test_a_file_chooses_variants_by_tag(tmp_path) -> None:
    path = tmp_path / "lqr.yaml"
    path.write_text(
        "attitude: !FixedAttitude {}\n"
        "tracking: !LqrTracking\n  max_acceleration: 7\n  feedforward: false\n"
        "estimator:\n  gate_probability: 0.95\n"  # untagged: the default variant's fields
    )
    scenario = load_scenario(str(path), ["tracking.position_weight=2"])
    assert scenario.attitude == FixedAttitude()
    assert scenario.tracking == LqrTracking(
        max_acceleration=7.0, feedforward=False, position_weight=2.0
    )
    assert scenario.estimator == PaperKf(gate_probability=0.95)
    with pytest.raises(ScenarioError, match=r"^tracking.alpha: unknown field \(known: "):
        path.write_text("tracking: !LqrTracking {alpha: 1.0}\n")
        load_scenario(str(path))


def test_every_slot_lists_its_variants_and_each_loads_by_name_or_tag() -> None:
    for slot in SLOTS:
        options = variants(Scenario, slot)
        assert options, slot
        for name, kind in options.items():
            by_name = load_scenario("paper", [f"{slot}={name}"])
            assert type(getattr(by_name, slot)) is kind
            assert by_name == load_scenario("paper", [f"{slot}=!{name}"])


@pytest.mark.parametrize(
    "override",
    ["estimator=Ekf {gate_probability: 0.99}", "estimator=!Ekf {gate_probability: 0.99}",
     "estimator=Ekf{gate_probability: 0.99}", " estimator = Ekf {gate_probability: 0.99} ",
     "estimator=Ekf\n  {gate_probability: 0.99}"],
)  # fmt: skip
def test_a_variant_with_fields_by_name_or_tag(override: str) -> None:
    scenario = load_scenario("paper", ["estimator.gate_probability=0.5", override])
    assert scenario.estimator == Ekf(gate_probability=0.99)


def test_the_bare_name_keeps_the_shared_fields_as_the_tag_does() -> None:
    kept = ["tracking.desired_relative_position=[-5, 0, 0]", "tracking.alpha=1.0"]
    by_name = load_scenario("paper", [*kept, "tracking=LqrTracking"])
    assert by_name.tracking == LqrTracking(desired_relative_position=[-5.0, 0.0, 0.0])
    assert by_name == load_scenario("paper", [*kept, "tracking=!LqrTracking"])


def test_a_bare_name_is_a_variant_only_where_the_key_is_a_slot() -> None:
    # A string field takes the same text as a plain string.
    scenario = load_scenario("paper", ["estimator.noise_model=paper_printed"])
    assert scenario.estimator.noise_model == "paper_printed"
    with pytest.raises(ScenarioError, match=r"^estimator.noise_model: must be one of"):
        load_scenario("paper", ["estimator.noise_model=Ekf"])


def test_a_loaded_scenario_is_the_callers_own_copy() -> None:
    """Loading the same document twice gives equal but separate scenarios: changing one (its
    nested lists too) leaves the next load as the file says."""
    first = load_scenario("paper", ["steps=40", "steady_state_start=10"])
    first.sonar.noise_variances[0] = 9.0
    first.steps = 7
    second = load_scenario("paper", ["steps=40", "steady_state_start=10"])
    assert second.sonar.noise_variances == [0.01, 0.01] and second.steps == 40
    assert second is not first and second.sonar is not first.sonar


def test_an_edited_file_loads_as_it_now_reads(tmp_path: Path) -> None:
    """Loads are cached by the file's text: a file changed between two loads is read again,
    and the same text under other overrides or another seed is another scenario."""
    path = tmp_path / "mine.yaml"
    path.write_text("steps: 40\nsteady_state_start: 10\n")
    assert load_scenario(str(path)).steps == 40
    path.write_text("steps: 50\nsteady_state_start: 10\n")
    assert load_scenario(str(path)).steps == 50
    assert load_scenario(str(path), ["steps=60"]).steps == 60
    assert load_scenario(str(path), seed=4).random_seed == 4
    assert load_scenario(str(path)).random_seed != 4
    with pytest.raises(ScenarioError, match=r"^--set: expected dotted.key=value, got 3$"):
        load_scenario(str(path), [3])


def test_every_shipped_scenario_parses_as_pure_python_yaml_does() -> None:
    """The loader's parser (libyaml's when PyYAML has it) reads the shipped files exactly as
    PyYAML's pure-Python parser with the same resolvers and tags."""
    import yaml

    from drake_uuv.scenario import loading

    class PurePython(yaml.SafeLoader):
        yaml_implicit_resolvers = loading._YamlLoader.yaml_implicit_resolvers

    PurePython.add_multi_constructor("!", loading._construct_tagged)
    for name in builtin_scenarios():
        text = loading.resolve_scenario_path(name).read_text()
        assert loading.parse_yaml(text) == yaml.load(text, Loader=PurePython), name  # noqa: S506
