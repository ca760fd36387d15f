"""`drake-uuv compare`: the printed and written tables, and status 2 on a bad group."""

import pytest

from drake_uuv.cli import main


def test_an_unknown_group_exits_2_naming_the_known_ones(tmp_path, capsys):
    status = main(["compare", "--group", "bogus", "--out", str(tmp_path), "--no-progress"])
    assert status == 2
    err = capsys.readouterr().err
    assert err == (
        "drake-uuv: error: --group: unknown group 'bogus' "
        "(known: attitude_noise, alpha, estimator, tracking, vehicle, regimes, attitude, "
        "attitude_vehicle)\n"
    )
    assert not (tmp_path / "compare.md").exists()


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
    assert out == f"{markdown}\n-> {tmp_path}/compare.md, {tmp_path}/compare.csv\n"
    assert (tmp_path / "compare.csv").read_text().count("\n") == 1 + 8
