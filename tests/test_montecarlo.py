"""Monte Carlo runner: reproducible whatever the backend, resumable, summarised correctly."""

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

from drake_uuv.analysis.stats import (
    bootstrap_interval,
    chi2_cdf,
    chi2_ppf,
    nees_band,
    wilson_interval,
)
from drake_uuv.cli import main
from drake_uuv.compare import Variant, compare
from drake_uuv.montecarlo import (
    MonteCarloError,
    Study,
    completed_seeds,
    run_study,
    summarize,
)
from drake_uuv.scenario import load_scenario

SHORT = ["steps=80", "steady_state_start=40"]
RUNS = 6


def _study(folder: Path, runs: int = RUNS, overrides=SHORT) -> Study:
    return Study("test", load_scenario("paper", overrides), runs, folder)


def _outputs(folder: Path) -> tuple[str, str]:
    return (folder / "summary.json").read_text(), (folder / "runs.csv").read_text()


# ----------------------------------------------------------------------- reproducibility


def test_summary_is_identical_for_one_and_two_workers_and_on_dask(tmp_path):
    distributed = pytest.importorskip("dask.distributed")
    serial = run_study(_study(tmp_path / "serial"), workers=1, progress=False, figures=False)
    pooled = run_study(
        _study(tmp_path / "pool"), workers=2, chunk_size=1, progress=False, figures=False
    )
    with distributed.LocalCluster(
        processes=False, n_workers=1, threads_per_worker=2, dashboard_address=None
    ) as cluster:
        on_dask = run_study(
            _study(tmp_path / "dask"),
            scheduler=cluster.scheduler_address,
            chunk_size=2,
            progress=False,
            figures=False,
        )
    assert serial.computed == pooled.computed == on_dask.computed == RUNS
    reference = _outputs(tmp_path / "serial")
    assert _outputs(tmp_path / "pool") == reference
    assert _outputs(tmp_path / "dask") == reference
    np.testing.assert_array_equal(serial.norms, pooled.norms)
    np.testing.assert_array_equal(serial.seeds, np.arange(RUNS))


def test_run_i_uses_seed_random_seed_plus_i(tmp_path):
    base = run_study(_study(tmp_path / "a", runs=4), workers=1, progress=False, figures=False)
    shifted_scenario = load_scenario("paper", SHORT, seed=2)
    shifted = run_study(
        Study("b", shifted_scenario, 2, tmp_path / "b"), workers=1, progress=False, figures=False
    )
    np.testing.assert_array_equal(shifted.seeds, [2, 3])
    np.testing.assert_array_equal(shifted.metrics, base.metrics[2:])


# ---------------------------------------------------------------------------- resuming


def test_resume_computes_only_the_missing_runs_and_gives_the_same_result(tmp_path):
    fresh = run_study(_study(tmp_path / "fresh"), workers=1, progress=False, figures=False)
    folder = tmp_path / "resumed"
    first = run_study(_study(folder, runs=2), workers=1, progress=False, figures=False)
    assert first.computed == 2
    resumed = run_study(_study(folder), workers=2, resume=True, progress=False, figures=False)
    assert resumed.computed == RUNS - 2
    assert _outputs(folder) == _outputs(tmp_path / "fresh")
    again = run_study(_study(folder), workers=1, resume=True, progress=False, figures=False)
    assert again.computed == 0
    assert again.summary == fresh.summary


def test_without_resume_old_runs_are_discarded(tmp_path):
    run_study(_study(tmp_path, runs=3), workers=1, progress=False, figures=False)
    result = run_study(_study(tmp_path, runs=3), workers=1, progress=False, figures=False)
    assert result.computed == 3


def test_resume_refuses_a_folder_of_another_scenario(tmp_path):
    run_study(_study(tmp_path, runs=2), workers=1, progress=False, figures=False)
    other = _study(tmp_path, runs=2, overrides=[*SHORT, "attitude.mode=random"])
    with pytest.raises(MonteCarloError, match=r"another scenario: attitude\.mode"):
        run_study(other, workers=1, resume=True, progress=False, figures=False)


def _start_cli(folder: Path, runs: int, workers: int) -> subprocess.Popen:
    command = [sys.executable, "-m", "drake_uuv.cli", "montecarlo", "--runs", str(runs)]
    command += ["--workers", str(workers), "--chunk-size", "2", "--no-progress", "--out"]
    command += [str(folder), "--set", "steps=150", "--set", "steady_state_start=50"]
    return subprocess.Popen(
        command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True
    )


def _wait_for_parts(folder: Path, process: subprocess.Popen, count: int) -> None:
    deadline = time.monotonic() + 60.0
    while len(list((folder / "runs").glob("part-*.npz"))) < count:
        assert process.poll() is None, process.communicate()
        assert time.monotonic() < deadline, "no runs finished within 60 s"
        time.sleep(0.02)


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
        assert "rerun with --resume" in stdout
    kept = completed_seeds(folder)
    assert 0 < len(kept) < runs
    overrides = ["steps=150", "steady_state_start=50"]
    resumed = run_study(
        _study(folder, runs, overrides), workers=1, resume=True, progress=False, figures=False
    )
    assert resumed.computed == runs - len(kept)
    fresh = run_study(
        _study(tmp_path / "fresh", runs, overrides), workers=2, progress=False, figures=False
    )
    assert resumed.summary == fresh.summary


# ------------------------------------------------------------------------------- summary


def test_runs_stopped_by_the_monitor_count_as_failed_and_diverged(tmp_path, monkeypatch):
    from drake_uuv.monitor import SimulationFailure
    from drake_uuv.simulation import ClosedLoopSimulation

    original = ClosedLoopSimulation.run

    def run(self, seed=None, **options):
        if seed in (1, 2):
            raise SimulationFailure(f"seed {seed}: run stopped: a test failure")
        return original(self, seed, **options)

    monkeypatch.setattr(ClosedLoopSimulation, "run", run)
    options = dict(workers=1, progress=False, figures=False)
    one_per_part = run_study(_study(tmp_path / "a", runs=4), chunk_size=1, **options)
    one_part = run_study(_study(tmp_path / "b", runs=4), chunk_size=4, **options)
    assert _outputs(tmp_path / "a") == _outputs(tmp_path / "b")  # parts of failed runs only
    summary = one_per_part.summary
    assert summary["completed_runs"] == 2 and summary["failed_fraction"] == 0.5
    assert summary["diverged_fraction"] >= 0.5
    np.testing.assert_array_equal(one_part.column("failed"), [0, 1, 1, 0])
    assert np.isnan(one_part.column("position_rmse")[1])
    completed = one_part.column("position_rmse")[[0, 3]]
    assert summary["position_rmse"] == pytest.approx(math.sqrt(np.mean(completed**2)))


def test_summary_combines_mean_square_errors_not_rmses():
    names = [
        "position_rmse",
        "velocity_rmse",
        "tracking_rmse",
        "nees_mean",
        "final_position_error",
        "relative_speed_mean",
        "relative_speed_peak",
        "acceleration_mean",
        "acceleration_peak",
        "max_tracking_error",
        "final_tracking_error",
    ]
    metrics = np.ones((2, len(names)))
    metrics[:, 0] = [1.0, 3.0]
    metrics[:, 4] = [0.5, math.nan]  # a non-finite final error counts as diverged
    metrics[:, 9] = [2.0, 20.0]
    summary = summarize(names, metrics, load_scenario("paper"), np.array([0, 1]))
    assert summary["position_rmse"] == pytest.approx(math.sqrt(5.0))
    assert summary["diverged_fraction"] == 0.5
    assert summary["tracking_bounded_fraction"] == 0.5
    for key in ("position_rmse", "velocity_rmse", "tracking_rmse", "nees_mean"):
        low, high = summary[f"{key}_ci95"]
        assert low <= summary[key] <= high


def test_montecarlo_command_writes_runs_summary_and_bands(tmp_path):
    status = main(
        ["montecarlo", "--runs", "3", "--workers", "1", "--no-progress", "--out", str(tmp_path)]
        + ["--set", "steps=60", "--set", "steady_state_start=20"]
    )
    assert status == 0
    rows = (tmp_path / "runs.csv").read_text().splitlines()
    assert rows[0].startswith("seed,position_rmse,") and len(rows) == 4
    summary = json.loads((tmp_path / "summary.json").read_text())
    for key in (
        "runs",
        "position_rmse",
        "velocity_rmse",
        "tracking_rmse",
        "nees_mean",
        "diverged_fraction",
        "position_rmse_ci95",
        "nees_mean_ci95",
        "diverged_fraction_ci95",
    ):
        assert key in summary
    assert summary["runs"] == 3
    assert (tmp_path / "figures" / "bands.png").stat().st_size > 10_000
    assert (tmp_path / "figures" / "bands.svg").exists()


@pytest.mark.parametrize(
    ("option", "message"),
    [(["--runs", "0"], "--runs: must be ≥ 1"), (["--workers", "0"], "--workers: must be ≥ 1")],
)
def test_bad_options_exit_with_status_2(tmp_path, capsys, option, message):
    status = main(["montecarlo", "--out", str(tmp_path), "--no-progress", *option])
    assert status == 2
    assert message in capsys.readouterr().err


def test_compare_writes_a_table_row_per_variant(tmp_path):
    variants = [
        Variant("fixed", "attitude", ("attitude.mode=fixed",)),
        Variant("trajectory", "attitude", ("attitude.mode=trajectory",), note="paper"),
    ]
    compare(variants, tmp_path, runs=2, base_overrides=SHORT, workers=1, progress=False)
    markdown = (tmp_path / "compare.md").read_text()
    assert "| fixed |" in markdown and "| trajectory | paper |" in markdown
    rows = (tmp_path / "compare.csv").read_text().splitlines()
    assert len(rows) == 3 and rows[1].startswith("attitude,fixed,")


# ------------------------------------------------------------------------------ statistics


@pytest.mark.parametrize(
    ("probability", "dof", "expected"),
    [
        (0.975, 6, 14.4494),
        (0.025, 6, 1.2373),
        (0.95, 1, 3.8415),
        (0.975, 100, 129.5612),
        (0.025, 100, 74.2219),
    ],
)
def test_chi2_quantiles_match_tables(probability, dof, expected):
    assert chi2_ppf(probability, dof) == pytest.approx(expected, abs=5e-4)
    assert chi2_cdf(chi2_ppf(probability, dof), dof) == pytest.approx(probability, abs=1e-12)


def test_nees_band_narrows_around_the_dimension_with_more_runs():
    low1, high1 = nees_band(6, 1)
    low100, high100 = nees_band(6, 100)
    assert low1 < low100 < 6 < high100 < high1


def test_intervals_are_deterministic_and_sensible():
    values = np.random.default_rng(1).normal(5.0, 1.0, size=200)
    first = bootstrap_interval(values, lambda x: x.mean(axis=-1))
    assert first == bootstrap_interval(values, lambda x: x.mean(axis=-1))
    assert first[0] < values.mean() < first[1]
    assert first[1] - first[0] == pytest.approx(2 * 1.96 / math.sqrt(200), rel=0.25)
    assert wilson_interval(0, 40) == (0.0, pytest.approx(0.0876, abs=1e-3))
    assert wilson_interval(40, 40)[1] == 1.0
