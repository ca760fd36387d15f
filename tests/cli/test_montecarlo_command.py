"""`drake-uuv montecarlo`: outputs, printed summary, status 2 on bad input, 130 on Ctrl-C."""

import csv
import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from drake_uuv.cli import main
from drake_uuv.scenario import load_scenario
from drake_uuv.studies import Study, completed_seeds, run_study

SHORT = ["--set", "steps=60", "--set", "steady_state_start=20"]


@pytest.mark.slow
def test_montecarlo_command_writes_runs_summary_and_bands(tmp_path, capsys):
    status = main(
        ["montecarlo", "--runs", "3", "--workers", "1", "--no-progress", "--out", str(tmp_path)]
        + SHORT
    )
    assert status == 0
    rows = list(csv.DictReader((tmp_path / "runs.csv").read_text().splitlines()))
    assert [int(row["seed"]) for row in rows] == [0, 1, 2]
    assert list(rows[0])[:2] == ["seed", "position_rmse"]
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["runs"] == 3 and summary["steps"] == 60
    # The summary is the runs': the RMSE over runs is the root of the mean square.
    rmse = [float(row["position_rmse"]) for row in rows]
    assert summary["position_rmse"] == pytest.approx(math.sqrt(np.mean(np.square(rmse))))
    low, high = summary["position_rmse_ci95"]
    assert low <= summary["position_rmse"] <= high
    assert summary["nees_mean"] == pytest.approx(np.mean([float(r["nees_mean"]) for r in rows]))
    assert len(summary["diverged_fraction_ci95"]) == 2
    assert (tmp_path / "figures" / "error_bands.png").read_bytes()[:4] == b"\x89PNG"
    assert (tmp_path / "figures" / "error_bands.png").stat().st_size > 10_000
    assert "<svg" in (tmp_path / "figures" / "error_bands.svg").read_text()
    out = capsys.readouterr().out.splitlines()
    assert out[0] == f"computed 3 runs -> {tmp_path}/"
    assert out[1] == "3 runs, seeds 0..2, k ≥ 20:"
    assert out[2].startswith(f"  position RMSE {summary['position_rmse']:.4g} m [")


@pytest.mark.parametrize(
    ("option", "message"),
    [
        (["--runs", "0"], "--runs: must be ≥ 1, got 0"),
        (["--workers", "0"], "--workers: must be ≥ 1, got 0"),
        (["--chunk-size", "0"], "--chunk-size: must be ≥ 1, got 0"),
        (["--runs", "x"], "argument --runs: invalid int value: 'x'"),
        (["--set", "steps=0"], "steps: must be"),
    ],
)
def test_bad_options_exit_with_status_2_and_one_line(tmp_path, capsys, option, message):
    status = main(["montecarlo", "--out", str(tmp_path), "--no-progress", *option])
    assert status == 2
    err = capsys.readouterr().err
    assert err.startswith("drake-uuv: error: ") and err.count("\n") == 1 and message in err


@pytest.mark.slow
def test_resume_of_another_scenario_exits_2_and_keeps_the_runs(tmp_path, capsys):
    base = ["montecarlo", "--runs", "2", "--workers", "1", "--no-progress", "--out", str(tmp_path)]
    assert main(base + SHORT) == 0
    status = main(base + SHORT + ["--resume", "--set", "attitude=!RandomAttitude"])
    assert status == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert (
        "holds runs of another scenario: attitude.variant ('TrajectoryAttitude' on disk, "
        "'RandomAttitude' now)" in err
    )
    assert completed_seeds(tmp_path) == {0, 1}
    assert main(base + SHORT + ["--resume"]) == 0
    assert capsys.readouterr().out.startswith(f"computed 0 runs, kept 2 -> {tmp_path}/")


def _start_cli(folder: Path, runs: int, workers: int) -> subprocess.Popen:
    command = [sys.executable, "-m", "drake_uuv.cli", "montecarlo", "--runs", str(runs)]
    command += ["--workers", str(workers), "--chunk-size", "2", "--no-progress", "--out"]
    command += [str(folder), "--set", "steps=150", "--set", "steady_state_start=50"]
    # SIGINT back to its default in the child: a shell's background job (nohup … &) starts with
    # it ignored, and Python then installs no KeyboardInterrupt handler, so Ctrl-C would be lost.
    return subprocess.Popen(
        command,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )


def _wait_for_parts(folder: Path, process: subprocess.Popen, count: int) -> None:
    deadline = time.monotonic() + 60.0
    while len(list((folder / "runs").glob("part-*.npz"))) < count:
        assert process.poll() is None, process.communicate()
        assert time.monotonic() < deadline, "no runs finished within 60 s"
        time.sleep(0.02)


@pytest.mark.slow
@pytest.mark.parametrize(("how", "workers"), [("kill", 2), ("interrupt", 1)])
def test_an_interrupted_study_keeps_finished_runs_and_resume_completes_it(tmp_path, how, workers):
    runs = 40
    folder = tmp_path / "interrupted"
    process = _start_cli(folder, runs, workers)
    try:
        _wait_for_parts(folder, process, 2)
        if how == "kill":  # no chance to clean up: every part on disk must still be whole;
            os.kill(process.pid, signal.SIGKILL)  # the pool's workers must die with it
        else:
            process.send_signal(signal.SIGINT)
        stdout, _ = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.communicate()
    if how == "interrupt":
        assert process.returncode == 130
        kept = len(completed_seeds(folder))
        assert f"interrupted: {kept} finished runs kept in {folder}/runs; rerun with --resume" in (
            stdout
        )
    else:
        assert process.returncode == -signal.SIGKILL
        _wait_for_no_process_in_group(process.pid)
    kept = completed_seeds(folder)
    assert 0 < len(kept) < runs
    scenario = load_scenario("paper", ["steps=150", "steady_state_start=50"])
    options = dict(progress=False, figures=False)
    resumed = run_study(Study("r", scenario, runs, folder), workers=1, resume=True, **options)
    assert resumed.computed == runs - len(kept)
    fresh = run_study(Study("f", scenario, runs, tmp_path / "fresh"), workers=2, **options)
    assert resumed.summary == fresh.summary


def _wait_for_no_process_in_group(group: int) -> None:
    """The killed parent's pool workers die with it (PR_SET_PDEATHSIG), within 10 s."""
    deadline = time.monotonic() + 10.0
    while True:
        try:
            os.killpg(group, 0)
        except ProcessLookupError:
            return
        assert time.monotonic() < deadline, "pool workers outlived their killed parent"
        time.sleep(0.05)
