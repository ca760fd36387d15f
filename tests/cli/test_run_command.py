"""`drake-uuv run`: its outputs, and status 2 with one line on bad input."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from drake_uuv.cli import main


@pytest.mark.slow
def test_run_writes_log_metrics_and_figure(tmp_path) -> None:
    out = tmp_path / "paper"
    status = main(
        ["run", "--out", str(out), "--set", "steps=120", "--set", "steady_state_start=60"]
    )
    assert status == 0
    log = np.load(out / "log.npz")
    assert log["x_TU_hat"].shape == (120, 6) and log["P_TU"].shape == (120, 6, 6)
    metrics = json.loads((out / "metrics.json").read_text())
    for key in ("position_rmse", "velocity_rmse", "tracking_rmse", "nees_mean", "steps", "seed",
                "wall_time_s"):  # fmt: skip
        assert key in metrics
    assert metrics["steps"] == 120 and metrics["seed"] == 0
    # The metric is the logged run's: q = p_WU − p_WT against q̂, over k ≥ 60.
    error = (log["p_WU"] - log["p_WT"] - log["x_TU_hat"][:, :3])[60:]
    rmse = np.sqrt(np.mean(np.sum(error**2, axis=1)))
    assert metrics["position_rmse"] == pytest.approx(rmse, rel=1e-12)
    assert (out / "error_summary.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (out / "error_summary.png").stat().st_size > 10_000


@pytest.mark.slow
def test_seed_option(tmp_path, capsys) -> None:
    status = main(["run", "--out", str(tmp_path / "a"), "--seed", "5", "--set", "steps=20",
                   "--set", "steady_state_start=0"])  # fmt: skip
    assert status == 0
    assert json.loads((tmp_path / "a" / "metrics.json").read_text())["seed"] == 5
    assert np.load(tmp_path / "a" / "log.npz")["x_TU_hat"].shape == (20, 6)
    assert capsys.readouterr().out.startswith("20 steps in ")


@pytest.mark.parametrize(
    "args, message",
    [
        (["run", "--set", "bogus.key=1"], "bogus.key: unknown field 'bogus'"),
        (["run", "--set", "sonar.baseline=[1, 2]"], "sonar.baseline: must be a list of 3 numbers"),
        (
            ["run", "--set", "sonar.noise_variances=[-1, 0.01]"],
            "sonar.noise_variances: must be > 0",
        ),
        (["run", "--set", "tracking.alpha=2"], "tracking.alpha: must be in"),
        (["run", "--scenario", "missing.yaml"], "scenario: no such file"),
        (["run", "--seed", "x"], "argument --seed: invalid int value: 'x'"),
        (["run", "--bogus"], "unrecognized arguments: --bogus"),
        (["run", "--realtime-rate", "-1"], "--realtime-rate: must be ≥ 0, got -1.0"),
        (["launch"], "invalid choice: 'launch'"),
    ],
)
def test_bad_input_exits_2_with_one_line(capsys, args: list[str], message: str) -> None:
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err and "Traceback" not in err


@pytest.mark.slow
def test_python_m_runs_the_command_line_with_its_exit_status(tmp_path) -> None:
    result = subprocess.run(
        [sys.executable, "-m", "drake_uuv.cli", "run", "--set", "attitude=!Bad"],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        env={**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])},
    )
    assert result.returncode == 2
    assert result.stderr.strip() == (
        "drake-uuv: error: attitude: unknown variant !Bad (known: TrajectoryAttitude, "
        "RandomAttitude, FixedAttitude, InformationSeeking)"
    )
