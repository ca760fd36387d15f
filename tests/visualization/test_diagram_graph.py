"""The committed diagrams/ are the current export of every variant."""

import shutil
from pathlib import Path

import pytest

from drake_uuv.cli import main
from drake_uuv.scenario import load_scenario
from drake_uuv.visualization.diagram_graph import diagram_dot, diagram_variants

DIAGRAMS = Path(__file__).resolve().parents[2] / "diagrams"


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(diagram_variants()))
def test_committed_export_is_current(name: str) -> None:
    committed = DIAGRAMS / f"{name}.dot"
    assert committed.exists(), f"{committed} missing: run python scripts/export_diagrams.py"
    current = diagram_dot(load_scenario("paper", diagram_variants()[name]))
    assert committed.read_text() == current, (
        f"{committed} is stale: run python scripts/export_diagrams.py"
    )
    assert (DIAGRAMS / f"{name}.svg").exists() and (DIAGRAMS / f"{name}.png").exists()


def test_no_stray_exports() -> None:
    assert {p.stem for p in DIAGRAMS.glob("*.dot")} == set(diagram_variants())


def test_export_is_reproducible_within_a_process() -> None:
    scenario = load_scenario("paper")
    assert diagram_dot(scenario) == diagram_dot(scenario)


def test_cli_writes_dot_and_renders_when_graphviz_is_present(tmp_path, capsys) -> None:
    assert main(["diagram", "--out", str(tmp_path)]) == 0
    assert (tmp_path / "paper.dot").read_text() == (DIAGRAMS / "paper.dot").read_text()
    if shutil.which("dot"):
        assert (tmp_path / "paper.svg").read_text().lstrip().startswith("<?xml")
        assert (tmp_path / "paper.png").read_bytes()[:4] == b"\x89PNG"


def test_cli_without_graphviz_writes_dot_and_says_so(tmp_path, capsys, monkeypatch) -> None:
    monkeypatch.setattr(shutil, "which", lambda name: None)
    assert main(["diagram", "--out", str(tmp_path)]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["paper.dot"]
    out = capsys.readouterr().out.splitlines()
    assert out[-1].startswith("Graphviz's dot is not installed")


def test_bad_depth_exits_2(capsys) -> None:
    assert main(["diagram", "--max-depth", "0"]) == 2
    assert "--max-depth: must be ≥ 1, got 0" in capsys.readouterr().err
