"""The site's own Sphinx extension: everything the reference shows is read from the code.

- ``.. pydrake_system::`` (the directive Drake's docstrings use, which drake_uuv's carry): a
  YAML block ``name``, ``input_ports``, ``output_ports`` drawn as Drake's docs draw a system,
  inputs on the left, the system in a box, outputs on the right. A port may carry a
  parenthesised condition (``v_WU (with timing)``), shown under its name with a dashed arrow.
  A port that is a signal of :data:`drake_uuv.signals.SIGNALS` links to the signal table.
- ``.. uuv-fields:: dotted.Name``: a dataclass's fields, their types, defaults and units (the
  ``[unit]`` in the comment above each field, or where the class's docstring or comments write
  the field's name followed by ``[unit]``), and that comment. autodoc adds it to every
  dataclass it documents.
- ``.. uuv-slots::``, ``.. uuv-slot-table::``, ``.. uuv-signals::``, ``.. uuv-scenarios::``:
  the slots with each variant's system and configuration (from
  :data:`drake_uuv.diagram.SLOT_REGISTRY`), the same as one table of ports, the table of
  signals, the shipped scenario files.
- The API pages (``reference/api/*.rst``, not committed) are written at ``builder-inited``:
  one page per subpackage, one ``automodule`` per module found by walking the package; and
  the notebooks of ``tutorials/`` are copied into ``docs/tutorials/`` (not committed).
- The tutorial notebooks run at build time through MyST-NB's cache; the cache is kept only
  while the package, the scenarios and the notebooks are unchanged (a digest of them), so a
  cached output is always the output of this code.
"""

from __future__ import annotations

import ast
import dataclasses
import hashlib
import importlib
import inspect
import io
import os
import pkgutil
import re
import shutil
import sys
import textwrap
import tokenize
import types
import typing
from importlib import metadata
from pathlib import Path
from typing import Any

import yaml
from docutils import nodes
from docutils.statemachine import StringList
from sphinx import addnodes
from sphinx.application import Sphinx
from sphinx.util.docutils import SphinxDirective
from sphinx.util.nodes import nested_parse_with_titles

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = "drake_uuv"

# ---------------------------------------------------------------------------------------------
# Port blocks


_PORT = re.compile(r"^\s*(?P<name>[^\s(]+)\s*(?:\((?P<condition>.*)\))?\s*$")


def parse_ports(entries: Any) -> list[tuple[str, str | None]]:
    """``[(name, condition or None)]`` of a YAML port list (block or flow style). An entry
    that is not ``name`` or ``name (condition)`` (``<each signal of the channel>``) is a
    description of ports, drawn as written."""
    if entries is None:
        return []
    if isinstance(entries, str):
        entries = [entries]
    ports = []
    for entry in entries:
        found = _PORT.match(str(entry))
        if found:
            ports.append((found["name"], found["condition"]))
        else:
            ports.append((str(entry).strip(), None))
    return ports


def parse_system_block(text: str) -> dict[str, Any]:
    """The ``name``, ``input_ports``, ``output_ports`` of a ``pydrake_system`` YAML block."""
    data = yaml.safe_load(textwrap.dedent(text)) or {}
    if not isinstance(data, dict) or "name" not in data:
        raise ValueError("a pydrake_system block needs a YAML mapping with a name")
    unknown = set(data) - {"name", "input_ports", "output_ports"}
    if unknown:
        raise ValueError(f"unknown keys in a pydrake_system block: {sorted(unknown)}")
    return {
        "name": str(data["name"]),
        "input_ports": parse_ports(data.get("input_ports")),
        "output_ports": parse_ports(data.get("output_ports")),
    }


_BLOCK_IN_DOCSTRING = re.compile(
    r"^(?P<indent>[ \t]*)\.\. pydrake_system::[ \t]*\n"
    r"(?P<body>(?:(?P=indent)[ \t]+\S.*\n|[ \t]*\n)+)",
    re.MULTILINE,
)


def system_blocks(docstring: str) -> list[dict[str, Any]]:
    """Every ``pydrake_system`` block of a docstring, parsed."""
    text = inspect.cleandoc(docstring or "") + "\n"
    return [parse_system_block(found["body"]) for found in _BLOCK_IN_DOCSTRING.finditer(text)]


def all_signals() -> list[tuple[Any, str]]:
    """``[(signal, who outputs it)]``: the table of signals (:data:`drake_uuv.signals.SIGNALS`),
    then the ``extra_signals`` of the slots' systems (a variant's own logged outputs)."""
    from drake_uuv.diagram import SLOT_REGISTRY
    from drake_uuv.signals import SIGNALS

    found = [(signal, signal.system) for signal in SIGNALS]
    names = {signal.name for signal in SIGNALS}
    for slot in SLOT_REGISTRY:
        for system in dict.fromkeys(slot.table.values()):
            for signal in getattr(system, "extra_signals", ()):
                if signal.name not in names:
                    names.add(signal.name)
                    found.append((signal, f"{signal.system} ({system.__name__} only)"))
    return found


def _signal_names() -> set[str]:
    return {signal.name for signal, _ in all_signals()}


def signal_label(name: str) -> str:
    return f"uuv-signal-{name.lower()}"


def _port_node(name: str, condition: str | None, side: str, signals: set[str]) -> nodes.Node:
    text: nodes.Node = nodes.literal(name, name)
    if name in signals:
        text = addnodes.pending_xref(
            "", text, refdomain="std", reftype="ref", reftarget=signal_label(name),
            refexplicit=True, refwarn=True,
        )  # fmt: skip
    label = nodes.inline("", "", classes=["uuv-port-name"])
    label += text
    if condition:
        label += nodes.inline(condition, condition, classes=["uuv-port-condition"])
    arrow = nodes.inline("", "", classes=["uuv-port-arrow"])
    classes = ["uuv-port", f"uuv-port-{side}"] + (["uuv-port-optional"] if condition else [])
    port = nodes.container("", classes=classes)
    port += [label, arrow] if side == "input" else [arrow, label]
    return port


def system_block_node(block: dict[str, Any]) -> nodes.Node:
    """The drawn block: inputs, the box, outputs (a ``div`` grid styled by ``uuv.css``)."""
    signals = _signal_names()
    figure = nodes.container("", classes=["uuv-system"])
    figure["uuv_system"] = block["name"]
    inputs = nodes.container("", classes=["uuv-system-inputs"])
    for name, condition in block["input_ports"]:
        inputs += _port_node(name, condition, "input", signals)
    box = nodes.container("", classes=["uuv-system-box"])
    box += nodes.inline(block["name"], block["name"], classes=["uuv-system-name"])
    outputs = nodes.container("", classes=["uuv-system-outputs"])
    for name, condition in block["output_ports"]:
        outputs += _port_node(name, condition, "output", signals)
    figure += [inputs, box, outputs]
    return figure


class PydrakeSystemDirective(SphinxDirective):
    """``.. pydrake_system::`` with Drake's YAML: drawn as a block."""

    has_content = True

    def run(self) -> list[nodes.Node]:
        try:
            block = parse_system_block("\n".join(self.content))
        except (ValueError, yaml.YAMLError) as error:
            raise self.error(f"pydrake_system: {error}") from error
        return [system_block_node(block)]


# ---------------------------------------------------------------------------------------------
# Dataclass fields


_UNIT_ATOM = re.compile(r"^(m|s|kg|N|rad|deg|Hz|steps?|%|°|g)([²³⁴⁵⁻¹]*)$")


def looks_like_unit(text: str) -> bool:
    """Whether ``text`` (inside ``[...]``) is a unit: SI-style atoms, separated by spaces,
    ``/``, ``,`` or ``·`` (``m²/s⁴``, ``N s/m``, ``kg, kg m²``)."""
    atoms = [a for a in re.split(r"[\s/,·]+", text.strip()) if a]
    return bool(atoms) and all(_UNIT_ATOM.match(a) for a in atoms)


def unit_of(comment: str, others: frozenset[str] = frozenset()) -> str:
    """The ``[unit]``s of a field's comment (``N s/m; N m s`` where it gives a force's and a
    moment's), or '': one written right after the name of another field (``others``) is that
    field's."""
    units: list[str] = []
    for found in re.finditer(r"\[([^\[\]]+)\]", comment):
        before = re.search(r"(\w+)(?:``)?\s*$", comment[: found.start()])
        if before and before.group(1) in others:
            continue
        if looks_like_unit(found.group(1)) and found.group(1) not in units:
            units.append(found.group(1))
    if units:
        return "; ".join(units)
    if re.search(r"\bseconds\b", comment, re.IGNORECASE):
        return "s"
    return ""


def _class_comments(cls: type) -> dict[str, str]:
    """``{field name: its comment}`` for the annotated assignments in ``cls``'s own body:
    the comment lines right above it (up to a blank or ``# ---`` line) and a comment on its
    line."""
    try:
        source = textwrap.dedent(inspect.getsource(cls))
    except (OSError, TypeError):
        return {}
    comments: dict[int, str] = {}
    code_lines: set[int] = set()
    for token in tokenize.generate_tokens(io.StringIO(source).readline):
        if token.type == tokenize.COMMENT:
            comments[token.start[0]] = token.string.lstrip("#").strip()
        elif token.type not in (tokenize.NL, tokenize.NEWLINE, tokenize.INDENT,
                                tokenize.DEDENT, tokenize.ENDMARKER):  # fmt: skip
            code_lines.update(range(token.start[0], token.end[0] + 1))
    tree = ast.parse(source)
    body = tree.body[0].body if tree.body and isinstance(tree.body[0], ast.ClassDef) else []
    found: dict[str, str] = {}
    for statement in body:
        if not (isinstance(statement, ast.AnnAssign) and isinstance(statement.target, ast.Name)):
            continue
        lines = []
        line = statement.lineno - 1
        while line in comments and line not in code_lines and not comments[line].startswith("---"):
            lines.insert(0, comments[line])
            line -= 1
        for inline in range(statement.lineno, statement.end_lineno + 1):
            if inline in comments and inline in code_lines:
                lines.append(comments[inline])
        found[statement.target.id] = " ".join(lines)
    return found


def _stated_units(cls: type, names: list[str], comments: list[str]) -> dict[str, str]:
    """``{field: unit}`` where the class's docstrings (its own and its bases') or its fields'
    comments write the field's name followed by a unit: ````handover_angle`` [rad]``,
    ``mean outlier_scale [m]``."""
    text = "\n".join([*(klass.__doc__ or "" for klass in cls.__mro__), *comments])
    units: dict[str, str] = {}
    for name in names:
        for found in re.finditer(rf"\b{re.escape(name)}(?:``)?\s*\[([^\[\]]+)\]", text):
            if looks_like_unit(found.group(1)):
                units[name] = found.group(1)
                break
    return units


def format_type(hint: Any) -> str:
    """A field's type as written, without module paths (``float | None``, ``list[float]``)."""
    if isinstance(hint, type) and not isinstance(hint, types.GenericAlias):
        return hint.__name__
    text = str(hint)
    text = text.replace("typing.", "").replace("NoneType", "None")
    return re.sub(r"\b(?:[A-Za-z_]\w*\.)+([A-Za-z_]\w*)", r"\1", text)


def format_value(value: Any) -> str:
    """A default as Python would print it, floats to 6 significant digits, a dataclass that
    equals its own default as ``Name()``."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        try:
            if bool(value == type(value)()):
                return f"{type(value).__name__}()"
        except Exception:  # a field without a default, or one that does not compare
            pass
        inner = ", ".join(
            f"{f.name}={format_value(getattr(value, f.name))}" for f in dataclasses.fields(value)
        )
        return f"{type(value).__name__}({inner})"
    if isinstance(value, float):
        return f"{value:.6g}"
    if hasattr(value, "tolist") and hasattr(value, "shape"):  # a numpy array
        return format_value(value.tolist())
    if isinstance(value, list):
        return "[" + ", ".join(format_value(v) for v in value) + "]"
    if isinstance(value, tuple):
        inner = ", ".join(format_value(v) for v in value)
        return f"({inner},)" if len(value) == 1 else f"({inner})"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k!r}: {format_value(v)}" for k, v in value.items()) + "}"
    return repr(value)


@dataclasses.dataclass(frozen=True)
class FieldRow:
    name: str
    type: str
    default: str  # '' when the field is required
    unit: str
    comment: str
    owner: str  # the class that declares it


def field_rows(cls: type) -> list[FieldRow]:
    """One row per field of the dataclass ``cls``, in declaration order."""
    try:
        hints = typing.get_type_hints(cls)
    except Exception:  # a forward reference the module cannot resolve
        hints = {}
    comments: dict[str, tuple[str, str]] = {}
    for klass in reversed(cls.__mro__):
        if dataclasses.is_dataclass(klass) and "__annotations__" in vars(klass):
            for name, comment in _class_comments(klass).items():
                comments[name] = (comment, klass.__name__)
    names = [field.name for field in dataclasses.fields(cls)]
    stated = _stated_units(cls, names, [comment for comment, _ in comments.values()])
    rows = []
    for field in dataclasses.fields(cls):
        if field.default is not dataclasses.MISSING:
            default = format_value(field.default)
        elif field.default_factory is not dataclasses.MISSING:
            default = format_value(field.default_factory())
        else:
            default = ""
        comment, owner = comments.get(field.name, ("", cls.__name__))
        others = frozenset(names) - {field.name}
        unit = unit_of(comment, others) or stated.get(field.name, "")
        hint = hints.get(field.name, field.type)
        rows.append(FieldRow(field.name, format_type(hint), default, unit, comment, owner))
    return rows


def _entry(*children: nodes.Node) -> nodes.entry:
    entry = nodes.entry()
    paragraph = nodes.paragraph()
    paragraph += list(children)
    entry += paragraph
    return entry


def fields_table(cls: type) -> nodes.Node:
    """The fields of ``cls`` as a table: field, type, default, unit, meaning."""
    headers = ("field", "type", "default", "unit", "meaning")
    table = nodes.table(classes=["uuv-fields", "colwidths-given"])
    table["uuv_dataclass"] = f"{cls.__module__}.{cls.__qualname__}"
    group = nodes.tgroup(cols=len(headers))
    table += group
    for width in (20, 13, 21, 7, 39):
        group += nodes.colspec(colwidth=width)
    head = nodes.thead()
    row = nodes.row()
    for header in headers:
        row += _entry(nodes.Text(header))
    head += row
    group += head
    body = nodes.tbody()
    for field in field_rows(cls):
        row = nodes.row(classes=["uuv-field"])
        row += _entry(nodes.literal(field.name, field.name))
        row += _entry(nodes.literal(field.type, field.type))
        default = (
            nodes.literal(field.default, field.default)
            if field.default
            else nodes.emphasis("required", "required")
        )
        row += _entry(default)
        row += _entry(nodes.Text(field.unit or "—"))
        meaning = field.comment
        if field.owner != cls.__name__:
            meaning = f"(from {field.owner}) {meaning}".strip()
        row += _entry(nodes.Text(meaning))
        body += row
    group += body
    return table


def import_dotted(path: str) -> Any:
    """The object at a dotted path: the longest importable module, then attributes."""
    parts = path.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        for attribute in parts[cut:]:
            obj = getattr(obj, attribute)
        return obj
    raise ImportError(path)


class FieldsDirective(SphinxDirective):
    """``.. uuv-fields:: drake_uuv.scenario.plants.HoveringAuv``"""

    required_arguments = 1

    def run(self) -> list[nodes.Node]:
        try:
            cls = import_dotted(self.arguments[0])
        except (ImportError, AttributeError) as error:
            raise self.error(f"uuv-fields: cannot import {self.arguments[0]}") from error
        if not dataclasses.is_dataclass(cls):
            raise self.error(f"uuv-fields: {self.arguments[0]} is not a dataclass")
        _note_source(self.env, cls)
        if not dataclasses.fields(cls):
            return [nodes.paragraph("", "", nodes.emphasis("No fields.", "No fields."))]
        return [fields_table(cls)]


def _note_source(env: Any, obj: Any) -> None:
    module = inspect.getmodule(obj)
    if module is not None and getattr(module, "__file__", None):
        env.note_dependency(module.__file__)


def _is_package_dataclass(obj: Any) -> bool:
    return (
        isinstance(obj, type)
        and dataclasses.is_dataclass(obj)
        and obj.__module__.split(".")[0] == PACKAGE
    )


def add_fields_table(
    app: Sphinx, what: str, name: str, obj: Any, options: Any, lines: list
) -> None:
    """A dataclass's docstring gets its fields table (``uuv-fields``) at the end."""
    if what == "class" and _is_package_dataclass(obj):
        lines += ["", f".. uuv-fields:: {obj.__module__}.{obj.__qualname__}", ""]


def drop_dataclass_signature(
    app: Sphinx, what: str, name: str, obj: Any, options: Any, signature: Any, annotation: Any
) -> Any:
    """A dataclass's signature repeats every field (its table shows them): left out."""
    if what == "class" and _is_package_dataclass(obj):
        return "", annotation
    return None


_LITERAL = re.compile(r"(``.+?``)")


def escape_bars(app: Sphinx, what: str, name: str, obj: Any, options: Any, lines: list) -> None:
    """drake_uuv's docstrings write norms as ``|q − q̂|``, which reST reads as a substitution
    (none is defined): every ``|`` outside a literal is escaped. A docstring's own
    ``pydrake_system`` block and literals keep theirs."""
    for i, line in enumerate(lines):
        if "|" in line:
            parts = _LITERAL.split(line)
            lines[i] = "".join(
                part if part.startswith("``") else part.replace("|", "\\|") for part in parts
            )


# ---------------------------------------------------------------------------------------------
# Generated pages: slots, signals, scenarios


def _parse_rst(directive: SphinxDirective, text: str) -> list[nodes.Node]:
    container = nodes.section()
    container.document = directive.state.document
    nested_parse_with_titles(directive.state, StringList(text.splitlines(), "<uuv>"), container)
    return container.children


def _qualified(obj: Any) -> str:
    return f"{obj.__module__}.{obj.__qualname__}"


class SlotsDirective(SphinxDirective):
    """Every slot's variants: the YAML tag, the system and its drawn ports, the fields."""

    def run(self) -> list[nodes.Node]:
        from drake_uuv.diagram import SLOT_REGISTRY
        from drake_uuv.plants import TargetRandomWalk
        from drake_uuv.scenario import SonarConfig, TargetConfig
        from drake_uuv.sensors import DualSonar

        lines: list[str] = []
        singles = [("target", "target", TargetConfig, TargetRandomWalk),
                   ("sonar", "sonar", SonarConfig, DualSonar)]  # fmt: skip
        for slot in SLOT_REGISTRY:
            title = f"{slot.section} (``{slot.system}``)"
            lines += [title, "-" * len(title) * 2, ""]
            tags = ", ".join(f"``{tag}``" for tag in slot.tags)
            lines += [f"Scenario section ``{slot.section}``, system ``{slot.system}`` in the "
                      f"diagram; variants {tags} (the first is the default of an untagged "
                      "section).", ""]  # fmt: skip
            for variant, system in slot.table.items():
                lines += self._variant(f"!{variant.__name__}", variant, system)
        for section, name, config, system in singles:
            title = f"{section} (``{name}``)"
            lines += [title, "-" * len(title) * 2, "", f"Scenario section ``{section}``; "
                      "a single system, no variants.", ""]  # fmt: skip
            lines += self._variant(config.__name__, config, system)
        return _parse_rst(self, "\n".join(lines))

    def _variant(self, heading: str, config: type, system: Any) -> list[str]:
        _note_source(self.env, config)
        _note_source(self.env, system)
        title = f"``{heading}``"
        lines = [title, "~" * len(title) * 2, ""]
        lines += [f"Configuration :py:class:`~{_qualified(config)}`; system "
                  f":py:class:`~{_qualified(system)}`.", ""]  # fmt: skip
        blocks = system_blocks(getattr(system, "__doc__", ""))
        for block in blocks:
            if block["name"] == system.__name__:
                lines += [".. pydrake_system::", ""]
                lines += ["    " + line for line in yaml.safe_dump(
                    {"name": block["name"],
                     "input_ports": [_port_text(p) for p in block["input_ports"]],
                     "output_ports": [_port_text(p) for p in block["output_ports"]]},
                    sort_keys=False, allow_unicode=True).splitlines()]  # fmt: skip
                lines.append("")
                break
        lines += [f".. uuv-fields:: {_qualified(config)}", ""]
        return lines


def _port_text(port: tuple[str, str | None]) -> str:
    name, condition = port
    return f"{name} ({condition})" if condition else name


def _xref(target: str, text: str) -> nodes.Node:
    return addnodes.pending_xref(
        "", nodes.literal(text, text), refdomain="py", reftype="class", reftarget=target,
        refexplicit=True, refwarn=False,
    )  # fmt: skip


def _port_list(ports: list[tuple[str, str | None]]) -> list[nodes.Node]:
    items: list[nodes.Node] = []
    for i, (name, condition) in enumerate(ports):
        if i:
            items.append(nodes.Text(", "))
        items.append(nodes.literal(name, name))
        if condition:
            items.append(nodes.Text(f" ({condition})"))
    return items


class SlotTableDirective(SphinxDirective):
    """One table of the loop's systems: each slot's (and the target's and the sonar's)
    systems, the variants that choose each, and its ports from its ``pydrake_system`` block."""

    def run(self) -> list[nodes.Node]:
        from drake_uuv.diagram import SLOT_REGISTRY
        from drake_uuv.plants import TargetRandomWalk
        from drake_uuv.sensors import DualSonar

        rows: list[tuple[str, list[str], Any]] = []
        for slot in SLOT_REGISTRY:
            systems: dict[Any, list[str]] = {}
            for variant, system in slot.table.items():
                systems.setdefault(system, []).append(f"!{variant.__name__}")
            rows += [(f"{slot.section} ({slot.system})", tags, system)
                     for system, tags in systems.items()]  # fmt: skip
        rows += [("target (target)", [], TargetRandomWalk), ("sonar (sonar)", [], DualSonar)]
        headers = ("slot (system name)", "variants", "system", "inputs", "outputs")
        table = nodes.table(classes=["uuv-slot-table", "colwidths-given"])
        group = nodes.tgroup(cols=len(headers))
        table += group
        for width in (13, 17, 20, 24, 26):
            group += nodes.colspec(colwidth=width)
        head = nodes.thead()
        row = nodes.row()
        for header in headers:
            row += _entry(nodes.Text(header))
        head += row
        group += head
        body = nodes.tbody()
        for slot, tags, system in rows:
            _note_source(self.env, system)
            block = next(
                (b for b in system_blocks(system.__doc__ or "") if b["name"] == system.__name__),
                {"input_ports": [], "output_ports": []},
            )
            row = nodes.row()
            row += _entry(nodes.Text(slot))
            variants: list[nodes.Node] = []
            for i, tag in enumerate(tags):
                variants += [nodes.Text(", ")] if i else []
                variants.append(nodes.literal(tag, tag))
            row += _entry(*(variants or [nodes.Text("(one system)")]))
            row += _entry(_xref(_qualified(system), system.__name__))
            row += _entry(*_port_list(block["input_ports"]))
            row += _entry(*_port_list(block["output_ports"]))
            body += row
        group += body
        return [table]


class SignalsDirective(SphinxDirective):
    """The table of signals (:func:`all_signals`), each row a link target."""

    def run(self) -> list[nodes.Node]:
        import drake_uuv.signals as module

        self.env.note_dependency(module.__file__)
        from drake_uuv.diagram import SLOT_REGISTRY

        for slot in SLOT_REGISTRY:
            for system in slot.table.values():
                _note_source(self.env, system)
        headers = ("signal", "system", "shape", "logged", "meaning")
        table = nodes.table(classes=["uuv-signals", "colwidths-given"])
        group = nodes.tgroup(cols=len(headers))
        table += group
        for width in (14, 18, 8, 8, 52):
            group += nodes.colspec(colwidth=width)
        head = nodes.thead()
        row = nodes.row()
        for header in headers:
            row += _entry(nodes.Text(header))
        head += row
        group += head
        body = nodes.tbody()
        for signal, system in all_signals():
            label = signal_label(signal.name)
            target = nodes.target("", "", ids=[label], names=[label])
            self.state.document.note_explicit_target(target)
            row = nodes.row()
            row += _entry(target, nodes.literal(signal.name, signal.name))
            row += _entry(nodes.literal(system, system))
            shape = "×".join(str(n) for n in signal.shape) or "scalar"
            row += _entry(nodes.Text(shape.replace("-1", "f·2")))
            row += _entry(nodes.Text("yes" if signal.logged else "no"))
            row += _entry(nodes.Text(signal.meaning))
            body += row
        group += body
        return [table]


class ScenariosDirective(SphinxDirective):
    """Each shipped scenario: its description and its file."""

    def run(self) -> list[nodes.Node]:
        from drake_uuv.scenario import (
            builtin_scenarios,
            resolve_scenario_path,
            scenario_description,
        )

        lines: list[str] = []
        for name in builtin_scenarios():
            path = resolve_scenario_path(name)
            self.env.note_dependency(str(path))
            title = f"``{name}``"
            lines += [title, "-" * len(title) * 2, "", scenario_description(name), "",
                      f"``drake-uuv run --scenario {name}`` runs it; the file, "
                      f"``drake_uuv/scenarios/{path.name}``:", "",
                      f".. literalinclude:: {self._relative(path)}", "   :language: yaml",
                      ""]  # fmt: skip
        return _parse_rst(self, "\n".join(lines))

    def _relative(self, path: Path) -> str:
        """``path`` from this page's folder (reST reads ``/x`` as the source folder's)."""
        here = Path(self.env.doc2path(self.env.docname)).parent
        return os.path.relpath(path, here)


# ---------------------------------------------------------------------------------------------
# The API pages


#: Reference pages in this order, each ``(file stem, title, the subpackage it documents)``;
#: the top-level modules go to ``core``, and a subpackage not listed here gets a page of its
#: own after these, titled by its docstring's first line.
API_GROUPS: tuple[tuple[str, str, str], ...] = (
    ("core", "The diagram, a run and its signals", "drake_uuv"),
    ("scenario", "Scenario: the configuration dataclasses", "drake_uuv.scenario"),
    ("plants", "Plants: the vehicle and the target", "drake_uuv.plants"),
    ("navigation", "Navigation", "drake_uuv.navigation"),
    ("sensors", "Sensors: the dual sonar", "drake_uuv.sensors"),
    ("estimators", "Estimators", "drake_uuv.estimators"),
    ("attitude", "Attitude generators", "drake_uuv.attitude"),
    ("tracking", "Tracking controllers", "drake_uuv.tracking"),
    ("primitives", "Primitives", "drake_uuv.primitives"),
    ("models", "Models: the math in plain numpy", "drake_uuv.models"),
    ("analysis", "Analysis: figures", "drake_uuv.analysis"),
    ("studies", "Studies: Monte Carlo and comparisons", "drake_uuv.studies"),
    ("recordings", "Recordings: ROS bags and replay", "drake_uuv.recordings"),
    ("hardware", "Hardware: the loop's halves over LCM", "drake_uuv.hardware"),
    ("visualization", "Visualization", "drake_uuv.visualization"),
    ("cli", "Command line", "drake_uuv.cli"),
)


def package_modules() -> list[str]:
    """Every module of the package (``__main__`` left out), in walk order."""
    package = importlib.import_module(PACKAGE)
    names = [PACKAGE]
    for info in pkgutil.walk_packages(package.__path__, f"{PACKAGE}."):
        if not info.name.endswith("__main__"):
            names.append(info.name)
    return names


def api_groups(modules: list[str]) -> list[tuple[str, str, str]]:
    """:data:`API_GROUPS`, then a group for each top-level subpackage it does not list."""
    listed = {prefix for _, _, prefix in API_GROUPS}
    groups = list(API_GROUPS)
    for module in modules:
        parts = module.split(".")
        if (
            len(parts) == 2
            and module not in listed
            and hasattr(importlib.import_module(module), "__path__")
        ):
            doc = (importlib.import_module(module).__doc__ or module).strip().splitlines()[0]
            groups.append((parts[1], doc.rstrip("."), module))
    return groups


def api_pages() -> dict[str, str]:
    """``{file name: reST}`` of the API pages: each module in the page of its top-level
    subpackage (the top-level modules in ``core``), and ``index.rst`` listing the pages."""
    modules = sorted(package_modules())
    groups = api_groups(modules)
    subpackages = {prefix for _, _, prefix in groups if prefix != PACKAGE}
    grouped: dict[str, list[str]] = {prefix: [] for _, _, prefix in groups}
    for module in modules:
        owner = next((p for p in subpackages if module == p or module.startswith(p + ".")), None)
        grouped[owner or PACKAGE].append(module)
    header = ".. This page is written by docs/_ext/uuv_sphinx.py at each build."
    pages = {}
    for slug, title, prefix in groups:
        lines = [header, "", title, "=" * len(title) * 2, ""]
        for module in grouped[prefix]:
            heading = f"``{module}``"
            lines += [heading, "-" * len(heading) * 2, "", f".. automodule:: {module}"]
            is_package = hasattr(importlib.import_module(module), "__path__")
            if not is_package:
                lines += ["   :members:", "   :ignore-module-all:", "   :show-inheritance:"]
            lines.append("")
        pages[f"{slug}.rst"] = "\n".join(lines)
    title = "Modules"
    index = [header, "", title, "=" * len(title), "",
             "One page per subpackage; the package's top-level modules are on the first.", "",
             ".. toctree::", "   :maxdepth: 1", ""]  # fmt: skip
    index += [f"   {slug}" for slug, _, _ in groups] + [""]
    pages["index.rst"] = "\n".join(index)
    return pages


def write_api_pages(app: Sphinx) -> None:
    folder = Path(app.srcdir) / "reference" / "api"
    folder.mkdir(parents=True, exist_ok=True)
    pages = api_pages()
    for name, text in pages.items():
        path = folder / name
        if not path.exists() or path.read_text() != text:  # unchanged: not re-read
            path.write_text(text)
    for stale in folder.glob("*.rst"):
        if stale.name not in pages:
            stale.unlink()


def copy_tutorials(app: Sphinx) -> None:
    """The notebooks of ``tutorials/`` into ``docs/tutorials/`` (not committed: the notebooks
    live beside the package, where their tests run them), when changed."""
    folder = Path(app.srcdir) / "tutorials"
    sources = {path.name: path for path in (ROOT / "tutorials").glob("*.ipynb")}
    for name, source in sources.items():
        copy = folder / name
        if not copy.exists() or copy.read_bytes() != source.read_bytes():
            shutil.copyfile(source, copy)
    for stale in folder.glob("*.ipynb"):
        if stale.name not in sources:
            stale.unlink()


# ---------------------------------------------------------------------------------------------
# Notebook cache


#: Installed distributions whose version a notebook's outputs depend on.
DISTRIBUTIONS = ("drake", "numpy", "scipy", "matplotlib", "numba", "ipykernel")


def code_digest() -> str:
    """A digest of what a notebook's outputs depend on: the package, its scenarios, the
    notebooks, the project's declared dependencies, the Python and the installed versions of
    :data:`DISTRIBUTIONS`."""
    digest = hashlib.sha256(sys.version.encode())
    for name in DISTRIBUTIONS:
        try:
            digest.update(f"{name}=={metadata.version(name)}".encode())
        except metadata.PackageNotFoundError:
            digest.update(f"{name} absent".encode())
    files = sorted(
        [
            *ROOT.glob("drake_uuv/**/*.py"),
            *ROOT.glob("drake_uuv/scenarios/*.yaml"),
            *ROOT.glob("tutorials/*.ipynb"),
            ROOT / "pyproject.toml",
            ROOT / "docs" / "conf.py",  # the kernels' environment is set there
        ]  # fmt: skip
    )
    for path in files:
        digest.update(str(path.relative_to(ROOT)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def check_notebook_cache(app: Sphinx) -> None:
    """Empties MyST-NB's cache when the code changed since it was filled."""
    cache = Path(app.config.nb_execution_cache_path)
    stamp = cache.parent / "jupyter_cache.digest"
    digest = code_digest()
    app.env_code_changed = not stamp.exists() or stamp.read_text() != digest
    if app.env_code_changed and cache.exists():
        shutil.rmtree(cache)
    stamp.parent.mkdir(parents=True, exist_ok=True)
    stamp.write_text(digest)


def notebooks_outdated(app: Sphinx, env: Any, added: set, changed: set, removed: set) -> list:
    """Re-reads the notebooks when the code changed (their own text may not have)."""
    if not getattr(app, "env_code_changed", False):
        return []
    return [doc for doc in env.found_docs if env.doc2path(doc).suffix == ".ipynb"]


# ---------------------------------------------------------------------------------------------
# Cross-references to re-exported names


def resolve_reexport(app: Sphinx, env: Any, node: Any, contnode: nodes.Node) -> Any:
    """``:class:`drake_uuv.scenario.KinematicUuv``` (a re-export) → the defining module's
    entry, ``drake_uuv.scenario.plants.KinematicUuv``."""
    if node.get("refdomain") != "py":
        return None
    target = node.get("reftarget", "")
    if not target.startswith(PACKAGE + "."):
        return None
    try:
        obj = import_dotted(target)
    except Exception:
        return None
    module = getattr(obj, "__module__", None)
    qualname = getattr(obj, "__qualname__", None)
    if not module or not qualname or f"{module}.{qualname}" == target:
        return None
    domain = env.get_domain("py")
    return domain.resolve_xref(
        env, node["refdoc"], app.builder, node["reftype"], f"{module}.{qualname}", node, contnode
    )


def setup(app: Sphinx) -> dict[str, Any]:
    app.add_directive("pydrake_system", PydrakeSystemDirective)
    app.add_directive("uuv-fields", FieldsDirective)
    app.add_directive("uuv-slots", SlotsDirective)
    app.add_directive("uuv-slot-table", SlotTableDirective)
    app.add_directive("uuv-signals", SignalsDirective)
    app.add_directive("uuv-scenarios", ScenariosDirective)
    app.setup_extension("sphinx.ext.autodoc")
    app.connect("autodoc-process-docstring", add_fields_table, priority=600)
    app.connect("autodoc-process-signature", drop_dataclass_signature)
    app.connect("builder-inited", write_api_pages)
    app.connect("builder-inited", copy_tutorials)
    app.connect("builder-inited", check_notebook_cache)
    app.connect("env-get-outdated", notebooks_outdated)
    app.connect("missing-reference", resolve_reexport)
    app.connect("autodoc-process-docstring", escape_bars, priority=400)
    app.add_css_file("uuv.css")
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
