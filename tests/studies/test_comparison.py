"""Comparison tables: the Markdown and CSV tables, the ratio tables, the written files."""

import csv
import json

import numpy as np
import pytest

from drake_uuv.studies import (
    BaseScenario,
    StudyResult,
    Variant,
    compare,
    csv_table,
    markdown_table,
    ratio_tables,
)
from drake_uuv.studies import comparison as comparison_module
from tests.studies.study_helpers import SHORT


def _summary(runs: int = 4, **values) -> dict:
    summary = {"runs": runs, "position_rmse": 0.5, "position_rmse_ci95": [0.4, 0.6]}
    summary["diverged_fraction"] = 0.25
    summary["diverged_fraction_ci95"] = [0.05, 0.7]
    return {**summary, **values}


def test_markdown_table_one_table_per_group_with_notes_only_where_given():
    rows = [
        (Variant("a", "first", ("x=1",)), _summary()),
        (Variant("b", "second", ("x=2",), note="proven"), _summary(runs=3, position_rmse=None)),
    ]
    text = markdown_table(rows)
    assert text.count("### ") == 2
    first, second = text.split("### second")
    assert "| variant | runs | position RMSE [m] |" in first
    # Absent numbers are dashes; fractions are percentages, without intervals.
    assert "| a | 4 | 0.5 [0.4, 0.6] | — | — | — | 25% | — |" in first
    assert "| variant | note | runs |" in second
    assert "| b | proven | 3 | — [0.4, 0.6] |" in second


def test_csv_table_has_intervals_and_bounds_and_blank_for_missing():
    rows = [(Variant("a", "g", ("x=1", "y=2"), note="n"), _summary(pcrlb_position_rmse=0.1))]
    header, row = csv.DictReader(csv_table(rows).splitlines()), None
    row = next(header)
    assert row["group"] == "g" and row["overrides"] == "x=1 y=2" and row["note"] == "n"
    assert row["position_rmse"] == "0.5" and row["position_rmse_ci95_high"] == "0.6"
    assert row["diverged_fraction_ci95_low"] == "0.05"
    assert row["velocity_rmse"] == "" and row["pcrlb_position_rmse"] == "0.1"


def test_ratio_tables_place_each_marked_estimator_and_mode():
    def row(name, estimator, attitude, marked=True):
        overrides = (f"estimator=!{estimator}", f"attitude=!{attitude}")
        return Variant(name, "grid", overrides, ratio_table=marked)

    rows = [
        (
            row("kf-fixed", "PaperKf", "FixedAttitude"),
            _summary(position_rmse_over_pcrlb=2.0, velocity_rmse_over_pcrlb=1.5),
        ),
        (
            row("ekf-random", "Ekf", "RandomAttitude"),
            _summary(position_rmse_over_per_run_pcrlb=1.02),
        ),
        # Not marked: in no ratio table, although it chooses an estimator and an attitude.
        (
            row("ukf-fixed", "Ukf", "FixedAttitude", marked=False),
            _summary(position_rmse_over_pcrlb=9.0),
        ),
    ]
    text = ratio_tables(rows)
    assert "| estimator | fixed | random |" in text
    assert "| kf | 2 / 1.5 | — / — |" in text
    assert "| ekf | — / — | 1.02 / — |" in text
    assert "ukf" not in text and "| 9 " not in text
    assert ratio_tables([(Variant("a", "other", ()), _summary())]) == ""


def test_ratio_tables_refuse_a_marked_variant_without_estimator_and_attitude():
    rows = [(Variant("odd", "grid", ("estimator=!Ekf",), ratio_table=True), _summary())]
    with pytest.raises(
        ValueError,
        match=r"^ratio_table: variant 'odd' must set both estimator=!Tag and attitude=!Tag, "
        r"got 'estimator=!Ekf'$",
    ):
        ratio_tables(rows)


def _fake_run_studies(calls):
    def run(studies, **options):
        calls.append(options)
        return [
            StudyResult(s, np.arange(s.runs), [], np.empty((s.runs, 0)), None, _summary(), s.runs)
            for s in studies
        ]

    return run


TWO = [
    Variant("first", "pair", ("attitude=!FixedAttitude",)),
    Variant("second", "pair", ("tracking=!LqrTracking", "tracking.max_acceleration=7")),
]


def test_compare_writes_both_files_and_states_its_command(tmp_path, monkeypatch):
    calls = []
    monkeypatch.setattr(comparison_module, "run_studies", _fake_run_studies(calls))
    base = BaseScenario(overrides=SHORT, seed=7)
    result = compare(TWO, tmp_path, runs=4, base=base, groups=["a", "b"], workers=2)
    assert calls == [{"workers": 2, "figures": False}]
    assert [variant for variant, _ in result] == TWO
    study = result[1][1].study
    assert study.out_dir == tmp_path / "studies" / "second"
    assert study.scenario.steps == 80 and study.scenario.random_seed == 7
    assert study.scenario.tracking.max_acceleration == 7
    markdown = (tmp_path / "compare.md").read_text()
    assert markdown.startswith("# Comparison (paper scenario, 4 runs per variant)\n\n")
    command = "drake-uuv compare --runs 4 --seed 7 --set steps=80 --set steady_state_start=40"
    assert f"Made by `{command} --group a --group b`." in markdown
    assert "Cramér–Rao" not in markdown  # no variant marked ratio_table: no ratio tables
    assert (tmp_path / "compare.csv").read_text().count("\n") == 1 + len(TWO)


def test_compare_without_groups_names_itself_and_adds_ratio_tables_of_marked_rows(
    tmp_path, monkeypatch
):
    monkeypatch.setattr(comparison_module, "run_studies", _fake_run_studies([]))
    marked = Variant(
        "ekf-fixed", "grid", ("estimator=!Ekf", "attitude=!FixedAttitude"), ratio_table=True
    )
    compare([*TWO, marked], tmp_path, runs=2, base=BaseScenario("paper", SHORT))
    markdown = (tmp_path / "compare.md").read_text()
    assert "Made by `drake_uuv.studies.compare` (3 variants)." in markdown
    assert "## Estimators against the posterior Cramér–Rao bound" in markdown
    assert "| ekf | — / — |" in markdown


@pytest.mark.slow
def test_compare_runs_each_variant_and_tabulates_its_summary(tmp_path):
    variants = [
        Variant("fixed", "attitude", ("attitude=!FixedAttitude",)),
        Variant("trajectory", "attitude", ("attitude=!TrajectoryAttitude",), note="paper"),
    ]
    compare(variants, tmp_path, 2, BaseScenario(overrides=SHORT), workers=1, progress=False)
    markdown = (tmp_path / "compare.md").read_text()
    assert "| fixed |" in markdown and "| trajectory | paper |" in markdown
    rows = list(csv.DictReader((tmp_path / "compare.csv").read_text().splitlines()))
    assert [row["variant"] for row in rows] == ["fixed", "trajectory"]
    for row, variant in zip(rows, variants, strict=True):
        folder = tmp_path / "studies" / variant.name
        summary = json.loads((folder / "summary.json").read_text())
        assert row["group"] == "attitude" and int(row["runs"]) == summary["runs"] == 2
        assert float(row["position_rmse"]) == summary["position_rmse"]
        assert float(row["nees_mean_ci95_low"]) == summary["nees_mean_ci95"][0]
        assert not (folder / "figures").exists()  # compare draws no band figures
    fixed = json.loads((tmp_path / "studies" / "fixed" / "study.json").read_text())
    assert fixed["scenario"]["attitude"] == {"variant": "FixedAttitude"}
