"""Diagram exports: the committed diagrams/ are the current export of what the docs embed, and
every registered variant builds its diagram (no committed file needed for a new variant)."""

import re
import shutil
from pathlib import Path

import pytest

from drake_uuv.cli import main
from drake_uuv.diagram import SLOT_REGISTRY, SYSTEM_NAMES
from drake_uuv.scenario import load_scenario
from drake_uuv.visualization.diagram_graph import (
    DOCUMENTED_DIAGRAMS,
    diagram_dot,
    diagram_variants,
)

ROOT = Path(__file__).resolve().parents[2]
DIAGRAMS = ROOT / "diagrams"


def _registered_variants() -> list[tuple[str, type]]:
    return [(slot.section, variant) for slot in SLOT_REGISTRY for variant in slot.table]


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(DOCUMENTED_DIAGRAMS))
def test_committed_export_is_current(name: str) -> None:
    committed = DIAGRAMS / f"{name}.dot"
    assert committed.exists(), f"{committed} missing: run python scripts/export_diagrams.py"
    current = diagram_dot(load_scenario("paper", DOCUMENTED_DIAGRAMS[name]))
    assert committed.read_text() == current, (
        f"{committed} is stale: run python scripts/export_diagrams.py"
    )
    assert (DIAGRAMS / f"{name}.svg").exists() and (DIAGRAMS / f"{name}.png").exists()


def test_diagrams_holds_exactly_the_documented_exports() -> None:
    assert {p.name for p in DIAGRAMS.iterdir()} == {
        f"{name}.{suffix}" for name in DOCUMENTED_DIAGRAMS for suffix in ("dot", "svg", "png")
    }


def test_every_documented_export_is_embedded_in_a_doc() -> None:
    docs = [ROOT / "README.md", ROOT / "ARCHITECTURE.md", *(ROOT / "docs").glob("*.md")]
    text = "\n".join(path.read_text() for path in docs)
    embedded = set(re.findall(r"diagrams/(\w+)\.svg", text))
    assert embedded == set(DOCUMENTED_DIAGRAMS)


def test_variants_come_from_the_registry() -> None:
    """One export per registered variant that differs from the paper scenario's default,
    besides the paper's own and the sonar faults'."""
    paper = load_scenario("paper")
    expected = {
        (f"{section}=!{variant.__name__}",)
        for section, variant in _registered_variants()
        if not isinstance(getattr(paper, section), variant)
    }
    exports = diagram_variants()
    assert exports.pop("paper") == [] and "sonar.beam_half_angle_deg=10" in exports.pop(
        "sonar_faults"
    )
    assert {tuple(overrides) for overrides in exports.values()} == expected
    assert len(exports) == len(expected)


@pytest.mark.parametrize(
    "section, variant", _registered_variants(), ids=lambda v: getattr(v, "__name__", v)
)
def test_every_registered_variant_builds_its_diagram(section: str, variant: type) -> None:
    dot = diagram_dot(load_scenario("paper", [f"{section}=!{variant.__name__}"]))
    for name in SYSTEM_NAMES:
        assert f"name={name}\n" in dot
    slot = next(slot for slot in SLOT_REGISTRY if slot.section == section)
    system = slot.table[variant]
    if isinstance(system, type):  # a class built by the factory: its box names it
        assert f"<B>{system.__module__}.{system.__qualname__}</B><BR/>\nname={slot.system}\n" in dot


def test_export_is_reproducible_within_a_process() -> None:
    scenario = load_scenario("paper")
    assert diagram_dot(scenario) == diagram_dot(scenario)


def test_cli_writes_dot_and_renders_when_graphviz_is_present(tmp_path, capsys) -> None:
    assert main(["diagram", "--out", str(tmp_path)]) == 0
    assert (tmp_path / "paper.dot").read_text() == (DIAGRAMS / "paper.dot").read_text()
    if shutil.which("dot"):
        assert (tmp_path / "paper.svg").read_text().lstrip().startswith("<?xml")
        assert (tmp_path / "paper.png").read_bytes()[:4] == b"\x89PNG"


def test_cli_all_variants_writes_every_variant(tmp_path, capsys, monkeypatch) -> None:
    monkeypatch.setattr(shutil, "which", lambda name: None)  # the .dot only: fast
    assert main(["diagram", "--all-variants", "--out", str(tmp_path)]) == 0
    assert {p.name for p in tmp_path.iterdir()} == {f"{n}.dot" for n in diagram_variants()}


def test_cli_without_graphviz_writes_dot_and_says_so(tmp_path, capsys, monkeypatch) -> None:
    monkeypatch.setattr(shutil, "which", lambda name: None)
    assert main(["diagram", "--out", str(tmp_path)]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["paper.dot"]
    out = capsys.readouterr().out.splitlines()
    assert out[-1].startswith("Graphviz's dot is not installed")


def test_bad_depth_exits_2(capsys) -> None:
    assert main(["diagram", "--max-depth", "0"]) == 2
    assert "--max-depth: must be ≥ 1, got 0" in capsys.readouterr().err
