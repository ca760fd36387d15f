"""Loading a scenario: YAML files, ``--set`` overrides, variant tags, one-line errors.

A scenario file is parsed with PyYAML (YAML 1.2 floats, ``!Tag`` variants), overridden,
type-checked against the schema with errors that name the field (Drake's loader does not),
then loaded with Drake's ``yaml_load_typed`` and validated as a whole.

Variants. A slot section (``plant``, ``estimator``, ``attitude``, ``tracking``) takes one of
its variant dataclasses, named by its tag: ``tracking: !LqrTracking {max_acceleration: 7}``.
An untagged section keeps the variant of the scenario's default. On the command line,
``--set tracking=LqrTracking`` switches the variant and ``--set 'tracking=LqrTracking
{max_acceleration: 7}'`` also sets fields; switching keeps the fields the two variants share
(such as ``desired_relative_position``) and resets the others to the new variant's defaults.
The tag form (``--set tracking=!LqrTracking``) works too, but ``!`` is history expansion in an
interactive bash, so messages show the bare name. ``--set tracking.alpha=1.0`` sets a field
of the variant in force.
"""

import copy
import dataclasses
import functools
import re
import types
import typing
from collections.abc import Iterable
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import yaml
from pydrake.common.yaml import yaml_load_typed

from drake_uuv.scenario.schema import SLOTS, Scenario
from drake_uuv.scenario.validation import ScenarioError


@dataclass
class Tagged:
    """A YAML node with a local tag: ``!LqrTracking {max_acceleration: 7}``."""

    tag: str
    value: Any


# libyaml's parser and emitter when PyYAML has them (its wheels do): the same documents, about
# ten times faster than the pure-Python ones, which matters to studies loading hundreds of
# variants. Resolvers and constructors stay Python, so the customisations below apply to both.
_SafeLoader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
_SafeDumper = getattr(yaml, "CSafeDumper", yaml.SafeDumper)


class _YamlLoader(_SafeLoader):
    """PyYAML's safe loader with YAML 1.2 floats (``1e-3`` is a number, not a string) and
    local tags (``!Name``) kept as :class:`Tagged`."""


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


def _construct_tagged(loader: Any, suffix: str, node: yaml.Node) -> Tagged:
    if isinstance(node, yaml.MappingNode):
        return Tagged(suffix, loader.construct_mapping(node, deep=True))
    if isinstance(node, yaml.SequenceNode):
        return Tagged(suffix, loader.construct_sequence(node, deep=True))
    scalar = loader.construct_scalar(node)
    return Tagged(suffix, {} if scalar in ("", None) else scalar)


_YamlLoader.add_multi_constructor("!", _construct_tagged)


class _YamlDumper(_SafeDumper):
    """Writes :class:`Tagged` mappings back with their tag, for Drake's loader."""


_YamlDumper.add_representer(
    Tagged, lambda dumper, node: dumper.represent_mapping(f"!{node.tag}", node.value)
)


def parse_yaml(text: str) -> Any:
    """Parses YAML text as scenario files are parsed (YAML 1.2 floats, ``!Tag`` kept)."""
    return yaml.load(text, Loader=_YamlLoader)  # noqa: S506 (a SafeLoader subclass)


def _one_line(error: BaseException) -> str:
    return " ".join(str(error).split())


# ----------------------------------------------------------------------------- variants


@functools.cache
def _type_hints(schema: type) -> dict[str, Any]:
    """The resolved field types of a schema dataclass (resolving them is slow; they never
    change)."""
    return typing.get_type_hints(schema)


def variants(schema: Any, name: str) -> dict[str, type]:
    """The variant dataclasses of field ``name`` of ``schema`` by tag, or {} if not a slot."""
    if schema is not Scenario or name not in SLOTS:
        return {}
    hint = _type_hints(Scenario)[name]
    members = (
        typing.get_args(hint)
        if typing.get_origin(hint) in (typing.Union, types.UnionType)
        else (hint,)
    )
    return {member.__name__: member for member in members}


def _names(options: dict[str, type]) -> str:
    return ", ".join(options)


def _default_variant(schema: Any, name: str) -> type:
    """The type of a slot field's default value."""
    for f in dataclasses.fields(schema):
        if f.name == name:
            default = f.default_factory() if f.default_factory is not dataclasses.MISSING else None
            return type(default)
    raise KeyError(name)  # pragma: no cover - callers pass known fields


def _variant_of(node: Any, options: dict[str, type], default: type, name: str) -> type:
    """The variant class a slot's value names (its tag, or the default when untagged)."""
    if isinstance(node, Tagged):
        if node.tag not in options:
            raise ScenarioError(f"{name}: unknown variant !{node.tag} (known: {_names(options)})")
        return options[node.tag]
    return default


def _fields_of(node: Any) -> dict[str, Any]:
    value = node.value if isinstance(node, Tagged) else node
    return value if isinstance(value, dict) else {}


# ------------------------------------------------------------------------------ loading


def builtin_scenarios() -> list[str]:
    """Names of the scenario files shipped inside the package."""
    folder = resources.files("drake_uuv") / "scenarios"
    return sorted(
        p.name.removesuffix(".yaml") for p in folder.iterdir() if p.name.endswith(".yaml")
    )


# A scenario file describes itself in a comment, so that a new file needs no code edit.
_DESCRIPTION = re.compile(r"^#\s*description:\s*(.*?)\s*$", re.MULTILINE)


def scenario_description(name_or_path: str) -> str:
    """The ``# description: ...`` comment of a scenario file (shipped name or path), or ''."""
    found = _DESCRIPTION.search(resolve_scenario_path(name_or_path).read_text())
    return found.group(1) if found else ""


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
        text = path.read_text()
    except OSError as e:
        raise ScenarioError(f"scenario file {str(path)!r}: cannot read it ({e.strerror})") from e
    overrides = tuple(overrides)
    for override in overrides:
        if not isinstance(override, str):
            raise ScenarioError(f"--set: expected dotted.key=value, got {override!r}")
    return copy.deepcopy(_loaded_scenario(str(path), text, overrides, seed))


@functools.lru_cache(maxsize=512)
def _loaded_scenario(
    path: str, text: str, overrides: tuple[str, ...], seed: int | None
) -> Scenario:
    """A scenario file's text with its overrides and seed, loaded; cached by all four, as
    tests and studies load the same scenario many times (the file's text is in the key, so an
    edited file is loaded again). Errors are raised, not cached."""
    try:
        data = parse_yaml(text)
    except yaml.YAMLError as e:
        raise ScenarioError(f"scenario file {path!r}: not valid YAML ({_one_line(e)})") from e
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ScenarioError(f"scenario file {path!r}: must be a mapping, got {data!r}")
    for override in overrides:
        apply_override(data, override)
    if seed is not None:
        data["random_seed"] = seed
    return _checked_scenario(data)


def scenario_from_dict(data: dict[str, Any]) -> Scenario:
    """Type-checks a plain dict against the schema, loads it with Drake and validates it."""
    return copy.deepcopy(_checked_scenario(data))


def _checked_scenario(data: dict[str, Any]) -> Scenario:
    """:func:`scenario_from_dict` without the copy: the cached scenario itself, which the
    public loaders copy before handing it out (so a caller may change its own)."""
    tagged = _check_types(Scenario, data, prefix="")
    return _typed_scenario(yaml.dump(tagged, Dumper=_YamlDumper, allow_unicode=True))


@functools.lru_cache(maxsize=512)
def _typed_scenario(text: str) -> Scenario:
    """Drake's typed load of a checked scenario document, validated; cached by its text, as
    studies and tests load the same variants many times (Drake's loader is pure Python)."""
    try:
        scenario = yaml_load_typed(schema=Scenario, data=text)
    except Exception as e:  # Drake's loader: the pre-check should already have caught it.
        raise ScenarioError(f"scenario: {_one_line(e)}") from e
    scenario.validate()
    return scenario


def validate_scenario(scenario: Scenario) -> None:
    """Checks every field of a scenario; raises :class:`ScenarioError` on the first bad one."""
    scenario.validate()


def apply_override(data: dict[str, Any], override: str) -> None:
    """Applies one ``dotted.key=value`` (value parsed as YAML) to a scenario dict in place."""
    if "=" not in override:
        raise ScenarioError(f"--set: expected dotted.key=value, got {override!r}")
    key, _, text = override.partition("=")
    key = key.strip()
    schema: Any = Scenario
    node = data
    parts = key.split(".")
    slot_options: dict[str, type] = {}  # the variants of the slot ``schema`` belongs to
    for depth, part in enumerate(parts):
        fields = {f.name: f for f in dataclasses.fields(schema)}
        where = ".".join(parts[:depth])
        if part not in fields:
            known = f"known: {', '.join(fields)}"
            hint = ""
            if slot_options:
                known = f"fields of {schema.__name__}: {', '.join(fields) or 'none'}"
                hint = f"; to change the variant, --set {where}=Name ({_names(slot_options)})"
            raise ScenarioError(
                f"{key}: unknown field {part!r}"
                + (f" in {where!r}" if where else "")
                + f" ({known}){hint}"
            )
        field_type = _resolved_type(schema, part)
        options = variants(schema, part)
        last = depth == len(parts) - 1
        if last:
            if options:
                value = _variant_value(key, text, options)
                node[part] = _switch_variant(node.get(part), value, options, key)
            elif dataclasses.is_dataclass(field_type):
                raise ScenarioError(f"{key}: is a section; set one of its fields, got {text!r}")
            else:
                node[part] = _parse_value(key, text)
            return
        if not dataclasses.is_dataclass(field_type) and not options:
            raise ScenarioError(f"{key}: {'.'.join(parts[: depth + 1])!r} has no sub-fields")
        child = node.get(part)
        if options:
            variant = _variant_of(child, options, _default_variant(schema, part), key)
            if not isinstance(child, Tagged) or not isinstance(child.value, dict):
                child = node[part] = Tagged(variant.__name__, _fields_of(child))
            node, schema, slot_options = child.value, variant, options
        else:
            if not isinstance(child, dict):
                child = node[part] = {}
            node, schema = child, field_type


def _parse_value(key: str, text: str) -> Any:
    try:
        return parse_yaml(text)
    except yaml.YAMLError as e:
        raise ScenarioError(f"{key}: value is not valid YAML, got {text!r}") from e


# A variant named without its tag: ``Ekf``, ``Ekf {gate_probability: 0.99}``.
_BARE_VARIANT = re.compile(r"\s*([A-Za-z_]\w*)(?=\s|\{|$)(.*)", re.DOTALL)


def _variant_value(key: str, text: str, options: dict[str, type]) -> Any:
    """The value of ``--set slot=...``: ``Name``, ``Name {fields}`` or the tag form ``!Name``,
    as a :class:`Tagged`; anything else parsed as YAML (and refused by the caller)."""
    bare = _BARE_VARIANT.fullmatch(text)
    if bare is None:
        return _parse_value(key, text)
    name, fields = bare.groups()
    if name not in options:
        raise ScenarioError(f"{key}: unknown variant {name} (known: {_names(options)})")
    return _parse_value(key, f"!{name} {fields}")


def _switch_variant(old: Any, value: Any, options: dict[str, type], key: str) -> Tagged:
    """``--set slot=Variant {...}``: the new variant, keeping the fields both variants share."""
    if not isinstance(value, Tagged):
        raise ScenarioError(
            f"{key}: is a variant section; choose a variant by name, e.g. "
            f"--set {key}={next(iter(options))} (variants: {_names(options)}), got {value!r}"
        )
    variant = _variant_of(value, options, type(None), key)
    if not isinstance(value.value, dict):
        raise ScenarioError(f"{key}: {value.tag} takes a mapping of fields, got {value.value!r}")
    names = {f.name for f in dataclasses.fields(variant)}
    kept = {name: v for name, v in _fields_of(old).items() if name in names}
    return Tagged(variant.__name__, {**kept, **value.value})


def _resolved_type(schema: Any, name: str) -> Any:
    return _type_hints(schema)[name]


# ------------------------------------------------------------------------- type checks


def _check_types(schema: Any, data: Any, prefix: str) -> dict[str, Any]:
    """Checks ``data`` against the dataclass ``schema``; returns it with every slot tagged."""
    if not isinstance(data, dict):
        raise ScenarioError(f"{prefix.rstrip('.') or 'scenario'}: must be a mapping, got {data!r}")
    hints = _type_hints(schema)
    checked: dict[str, Any] = {}
    for key, value in data.items():
        name = f"{prefix}{key}" if str(key).isidentifier() else f"{prefix}{key!r}"
        if key not in hints:
            raise ScenarioError(f"{name}: unknown field (known: {', '.join(hints)})")
        options = variants(schema, key)
        if options:
            variant = _variant_of(value, options, _default_variant(schema, key), name)
            fields = value.value if isinstance(value, Tagged) else value
            if fields is None:
                fields = {}
            checked[key] = Tagged(variant.__name__, _check_types(variant, fields, f"{name}."))
            if len(options) == 1:  # not a union: Drake's loader takes no tag
                checked[key] = checked[key].value
        else:
            if isinstance(value, Tagged):
                raise ScenarioError(f"{name}: takes no !tag, got !{value.tag}")
            checked[key] = _check_value(hints[key], value, name)
    return checked


def _check_value(expected: Any, value: Any, name: str) -> Any:
    origin = typing.get_origin(expected)
    if isinstance(value, Tagged):
        raise ScenarioError(f"{name}: takes no !tag, got !{value.tag}")
    if dataclasses.is_dataclass(expected):
        return _check_types(expected, value, prefix=f"{name}.")
    if origin in (typing.Union, types.UnionType):
        options = typing.get_args(expected)
        if value is None and type(None) in options:
            return value
        return _check_value(next(o for o in options if o is not type(None)), value, name)
    if origin is list:
        if not isinstance(value, list):
            raise ScenarioError(f"{name}: must be a list, got {value!r}")
        (item_type,) = typing.get_args(expected)
        return [_check_value(item_type, item, name) for item in value]
    if expected is float:
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
    return value
