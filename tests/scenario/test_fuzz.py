"""Property-based: random values and random YAML either load and run, or fail with one line.

Every input goes through the real loader (`load_scenario`) from a file. What loads is built and
simulated for a few steps; nothing but a ScenarioError (bad input) or a SimulationFailure (the
monitor stopping a run) may escape, and both must be one line that names a field.
"""

import dataclasses
import typing

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from drake_uuv.monitor import SimulationFailure
from drake_uuv.scenario import SLOTS, Scenario, ScenarioError, load_scenario, variants
from drake_uuv.simulation import ClosedLoopSimulation


def _leaf_fields(schema, prefix=""):
    for field in dataclasses.fields(schema):
        kind = typing.get_type_hints(schema)[field.name]
        if schema is Scenario and field.name in SLOTS:
            yield field.name  # the slot itself: set to a tag, or to anything else
            for variant in variants(Scenario, field.name).values():
                yield from _leaf_fields(variant, f"{field.name}.")
        elif dataclasses.is_dataclass(kind):
            yield from _leaf_fields(kind, f"{prefix}{field.name}.")
        else:
            yield f"{prefix}{field.name}"


FIELDS = sorted(set(_leaf_fields(Scenario)))
TAGS = sorted(f"!{tag}" for slot in SLOTS for tag in variants(Scenario, slot))
numbers = st.one_of(
    st.integers(-(10**12), 10**12),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0, 1, -1, 0.5, 1e-300, 1e300, 2**31, 2**63]),
)
scalars = st.one_of(numbers, st.booleans(), st.none(), st.text(max_size=8))
values = st.one_of(
    scalars,
    st.lists(numbers, max_size=7),
    st.lists(st.lists(numbers, min_size=0, max_size=7), max_size=7),
    st.dictionaries(st.text(max_size=5), scalars, max_size=3),
)
keys = st.one_of(st.sampled_from(FIELDS), st.text(min_size=1, max_size=12))


def _check_one_line(error: Exception) -> None:
    message = str(error)
    assert "\n" not in message and message.strip(), message


def _load_and_run(name: str, overrides: list[str] = ()) -> bool:
    """Loads a scenario and runs 4 steps of it; only one-line input or run errors may escape.

    Returns whether it loaded (and ran, or was stopped by the monitor with one line)."""
    try:
        scenario = load_scenario(name, overrides)
    except ScenarioError as e:
        _check_one_line(e)
        return False
    short = dataclasses.replace(scenario, steps=4, steady_state_start=0)
    try:
        ClosedLoopSimulation(short).run()
    except SimulationFailure as e:
        _check_one_line(e)
    return True


SETTINGS = settings(
    max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)


@pytest.mark.slow
@SETTINGS
@given(overrides=st.dictionaries(keys, values, max_size=4))
def test_random_field_values(tmp_path, overrides) -> None:
    data: dict = {}
    for key, value in overrides.items():
        node = data
        *parents, leaf = key.split(".")
        for part in parents:
            node = node.setdefault(part, {}) if isinstance(node.get(part, {}), dict) else {}
        node[leaf] = value
    path = tmp_path / "scenario.yaml"
    path.write_text(yaml.safe_dump(data, allow_unicode=True))
    _load_and_run(str(path))


@SETTINGS
@given(text=st.text(max_size=200))
def test_random_yaml_text(tmp_path, text) -> None:
    path = tmp_path / "scenario.yaml"
    path.write_text(text)
    _load_and_run(str(path))


@pytest.mark.slow
@SETTINGS
@given(key=st.sampled_from(FIELDS), text=st.one_of(st.text(max_size=30), st.sampled_from(TAGS)))
def test_random_set_overrides(key, text) -> None:
    _load_and_run("paper", [f"{key}={text}"])


@pytest.mark.parametrize("tag", TAGS)
def test_every_variant_loads_and_runs_from_a_tag(tag: str) -> None:
    """The fuzzing above would pass if every input were rejected; these must load and run."""
    slot = next(s for s in SLOTS if tag[1:] in variants(Scenario, s))
    assert _load_and_run("paper", [f"{slot}={tag}"])


@pytest.mark.parametrize(
    "override",
    ["steps=300", "tracking.alpha=1.0", "sonar.noise_variances=[0.02, 0.03]",
     "estimator.gate_probability=0.99", "attitude.max_angular_rate=1e-3", "time_step=1e-3"],
)  # fmt: skip
def test_valid_overrides_load_and_run(override: str) -> None:
    assert _load_and_run("paper", [override])
