"""`drake-uuv compare`: finding the groups, listing them, the default groups, the estimate
printed before the runs, the printed and written tables, and status 2 on bad input."""

import numpy as np
import pytest

import drake_uuv.studies as studies_package
from drake_uuv.cli import main
from drake_uuv.studies import StudyResult, format_group_list, load_groups
from drake_uuv.studies import comparison as comparison_module
from drake_uuv.studies import estimate as estimate_module
from tests.conftest import STUDIES

PAPER_GROUPS = ("attitude_noise", "alpha", "tracking")


@pytest.fixture
def no_simulation(monkeypatch):
    """Studies and timed runs that fail the test if anything is simulated."""

    def refuse(*args, **kwargs):
        raise AssertionError("simulated")

    monkeypatch.setattr(comparison_module, "run_studies", refuse)
    monkeypatch.setattr(estimate_module, "time_one_run", refuse)


def test_an_unknown_group_exits_2_naming_the_known_ones(tmp_path, capsys, no_simulation):
    status = main(["compare", "--group", "bogus", "--out", str(tmp_path), "--no-progress"])
    assert status == 2
    assert capsys.readouterr().err == (
        "drake-uuv: error: --group: unknown group 'bogus' "
        "(known: attitude_noise, alpha, estimator, tracking, vehicle, regimes, attitude, "
        "attitude_vehicle, navigation, robustness)\n"
    )
    assert not (tmp_path / "compare.md").exists()


def test_a_folder_without_groups_exits_2_naming_it(tmp_path, capsys, no_simulation):
    assert main(["compare", "--studies", str(tmp_path / "none"), "--out", str(tmp_path)]) == 2
    assert capsys.readouterr().err == (
        f"drake-uuv: error: --studies: no study groups in {tmp_path / 'none'} "
        "(no __init__.py there; pass --studies DIR)\n"
    )


def test_without_a_checkout_the_default_folder_is_named(tmp_path, capsys, monkeypatch):
    # As if drake_uuv were installed without its repository: no studies/ beside it.
    monkeypatch.setattr(studies_package, "default_studies_folder", lambda: tmp_path / "studies")
    assert main(["compare", "--group", "list"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"drake-uuv: error: --studies: no study groups in {tmp_path}/studies ")


def test_group_list_prints_every_group_and_runs_nothing(tmp_path, capsys, no_simulation):
    out = tmp_path / "out"
    assert main(["compare", "--group", "list", "--runs", "7", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert text == format_group_list(load_groups(STUDIES), 7) + "\n"
    lines = text.splitlines()
    assert lines[0].split() == ["group", "variants", "runs", "description"]
    rows = {line.split()[0]: line.split()[1:3] for line in lines[1:-1]}
    assert rows["tracking*"] == ["8", "56"] and rows["regimes"] == ["30", str(24 * 7 + 6)]
    assert [name for name in rows if name.endswith("*")] == [f"{g}*" for g in PAPER_GROUPS]
    assert not out.exists()


def test_runs_below_one_exit_2_before_anything_is_timed(tmp_path, capsys, no_simulation):
    assert main(["compare", "--runs", "0", "--out", str(tmp_path)]) == 2
    captured = capsys.readouterr()
    assert captured.err == "drake-uuv: error: --runs: must be ≥ 1, got 0\n"
    assert captured.out == ""


def test_without_group_the_paper_s_groups_run_after_the_estimate(tmp_path, capsys, monkeypatch):
    studies = []

    def fake_run_studies(batch, **options):
        studies.extend(batch)
        return [
            StudyResult(s, np.arange(s.runs), [], np.empty((s.runs, 0)), None, {"runs": 3}, 3)
            for s in batch
        ]

    monkeypatch.setattr(comparison_module, "run_studies", fake_run_studies)
    monkeypatch.setattr(estimate_module, "time_one_run", lambda scenario: 0.5)
    args = ["compare", "--runs", "3", "--workers", "2", "--no-progress", "--out", str(tmp_path)]
    assert main(args) == 0
    groups = load_groups(STUDIES)
    expected = [v.name for g in PAPER_GROUPS for v in groups[g].variants()]
    assert [study.name for study in studies] == expected and len(expected) == 26
    out = capsys.readouterr().out.splitlines()
    # 26 variants × 3 runs at a fake 0.5 s each, on 2 workers: 19.5 s.
    assert out[0] == "78 runs to compute (26 variants × 3 runs): about 20 s on 2 workers,"
    # The paper's groups differ in attitude only: three configurations timed.
    assert [line.split("  ")[-1] for line in out[2:5]] == [
        f"KinematicUuv, PaperKf, {attitude}Attitude, 500 steps"
        for attitude in ("Trajectory", "Random", "Fixed")
    ]
    assert out[5] == "# Comparison (paper scenario, 3 runs per variant)"
    markdown = (tmp_path / "compare.md").read_text()
    assert "--group attitude_noise --group alpha --group tracking`." in markdown


@pytest.mark.slow
def test_compare_prints_and_writes_the_tables_of_the_chosen_group(tmp_path, capsys):
    args = ["compare", "--runs", "1", "--group", "tracking", "--workers", "1", "--no-progress"]
    args += ["--out", str(tmp_path), "--set", "steps=40", "--set", "steady_state_start=10"]
    assert main(args) == 0
    markdown = (tmp_path / "compare.md").read_text()
    assert markdown.startswith("# Comparison (paper scenario, 1 runs per variant)\n")
    assert (
        "Made by `drake-uuv compare --runs 1 --set steps=40 --set steady_state_start=10 "
        "--group tracking`." in markdown
    )
    assert markdown.count("\n| trajectory-") == 4 and markdown.count("\n| random-") == 4
    out = capsys.readouterr().out
    estimate, tables = out.split("# Comparison", 1)
    lines = estimate.splitlines()
    assert lines[0].startswith("8 runs to compute (8 variants × 1 run): about ")
    assert lines[0].endswith(" s on 1 worker,")
    # Algorithms 2 and 1 under the paper's KF: two configurations, four runs each.
    assert [line.split()[3] for line in lines[2:]] == ["4", "4"]
    assert (
        "# Comparison" + tables == f"{markdown}\n-> {tmp_path}/compare.md, {tmp_path}/compare.csv\n"
    )
    assert (tmp_path / "compare.csv").read_text().count("\n") == 1 + 8
