"""Graphviz export of the closed-loop diagram, straight from the diagram that runs."""

import re
import shutil
import subprocess
from pathlib import Path

from drake_uuv.diagram import SLOT_REGISTRY, make_uuv_diagram
from drake_uuv.io import write_atomic, write_text_atomic
from drake_uuv.scenario import Scenario, load_scenario

_ID = re.compile(r"(?<=\bs)\d+\b|(?<=cluster)\d+|(?<=digraph _)\d+")
_EDGE = re.compile(r"^s(\d+):y(\d+):e -> s(\d+):u(\d+):w$")


def _sorted_edges(lines: list[str]) -> list[str]:
    """Sorts each run of edge lines (Drake emits them in pointer-hash order)."""
    out: list[str] = []
    run: list[str] = []
    for line in [*lines, ""]:
        match = _EDGE.match(line)
        if match:
            run.append(line)
            continue
        out += sorted(run, key=lambda e: tuple(int(g) for g in _EDGE.match(e).groups()))
        run = []
        out.append(line)
    return out[:-1]


def diagram_dot(scenario: Scenario, max_depth: int = 1, loggers: bool = False) -> str:
    """``GetGraphvizString`` of the scenario's diagram with stable node ids.

    Without ``loggers`` (the default) the picture shows the loop itself: the one logger per
    signal that a run adds would crowd it out. Drake numbers nodes by a per-process system id,
    so the raw string changes with whatever was built before; renumbering ids in order of
    first appearance makes the export reproducible (and a committed export checkable). Edges
    are sorted for the same reason.
    """
    diagram = make_uuv_diagram(scenario, log=loggers).diagram
    raw = diagram.GetGraphvizString(max_depth=max_depth)
    ids: dict[str, str] = {}
    renumbered = _ID.sub(lambda m: ids.setdefault(m.group(0), str(len(ids))), raw)
    return "\n".join(_sorted_edges(renumbered.split("\n")))


def diagram_variants() -> dict[str, list[str]]:
    """Every distinct diagram the package builds, by the overrides of the paper scenario.

    One per variant of each slot (from :data:`~drake_uuv.diagram.SLOT_REGISTRY`, so a new
    variant gets its export without anyone editing this function), named
    ``<section>_<variant in snake case>``, one with every sonar fault switched on (it adds
    ports), and none that would repeat the paper's own diagram.
    """
    paper = load_scenario("paper")
    candidates: dict[str, list[str]] = {}
    for slot in SLOT_REGISTRY:
        for variant in slot.table:
            tag = variant.__name__
            candidates[f"{slot.section}_{_snake(tag)}"] = [f"{slot.section}=!{tag}"]
    candidates["sonar_faults"] = [
        "sonar.beam_half_angle_deg=10",
        "sonar.dropout_probability=[0.1, 0.1]",
        "sonar.outlier_probability=0.05",
        "estimator.gate_probability=0.99",
    ]
    exports: dict[str, list[str]] = {"paper": []}
    for name, overrides in candidates.items():
        if load_scenario("paper", overrides) != paper:
            exports[name] = overrides
    return exports


def render(dot_path: Path, formats: tuple[str, ...] = ("svg", "png")) -> list[Path] | None:
    """Renders a ``.dot`` with Graphviz's ``dot``; None when ``dot`` is not installed."""
    dot = shutil.which("dot")
    if dot is None:
        return None
    written = []
    for fmt in formats:
        image = subprocess.run(
            [dot, f"-T{fmt}", str(dot_path)], check=True, capture_output=True
        ).stdout
        written.append(write_atomic(dot_path.with_suffix(f".{fmt}"), lambda f, d=image: f.write(d)))
    return written


def _snake(name: str) -> str:
    return re.sub(r"(?<=[a-z0-9])(?=[A-Z])", "_", name).lower()


def export_diagram(
    scenario: Scenario, out_dir: Path, name: str, max_depth: int = 1, loggers: bool = False
) -> list[Path]:
    """Writes ``name.dot`` (always) and ``.svg``/``.png`` (when Graphviz is present)."""
    dot = diagram_dot(scenario, max_depth, loggers)
    dot_path = write_text_atomic(Path(out_dir) / f"{name}.dot", dot)
    return [dot_path, *(render(dot_path) or [])]


#: The exports the docs embed (README.md shows ``diagrams/paper.svg``): what ``diagrams/``
#: holds, by name → overrides of the paper scenario.
DOCUMENTED_DIAGRAMS: dict[str, list[str]] = {"paper": []}


def export_all_variants(
    out_dir: Path,
    max_depth: int = 1,
    loggers: bool = False,
    exports: dict[str, list[str]] | None = None,
) -> list[Path]:
    """Exports ``exports`` (default: :func:`diagram_variants`) into ``out_dir``."""
    written = []
    for name, overrides in (diagram_variants() if exports is None else exports).items():
        scenario = load_scenario("paper", overrides)
        written += export_diagram(scenario, out_dir, name, max_depth, loggers)
    return written
