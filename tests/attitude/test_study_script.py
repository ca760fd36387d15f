"""studies/paired.py: pairing by seed, the comparison and its checks."""

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import study_module

study = study_module("paired")


def write_runs(folder: Path, rows: list[dict[str, float]]) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    with (folder / "runs.csv").open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    return folder


@pytest.fixture
def studies(tmp_path: Path) -> tuple[Path, Path]:
    rng = np.random.default_rng(0)
    base = 0.6 + 0.05 * rng.standard_normal(100)
    baseline = [
        {"seed": s, "position_rmse": base[s], "failed": 0, "rotation_mean": 0.38,
         "rotation_peak": 1.5, "excitation_min": 4.4}
        for s in range(100)
    ]  # fmt: skip
    # The candidate: 30 % lower per seed, rows in another order, one seed more, one failed.
    candidate = [
        {"seed": s, "position_rmse": 0.7 * base[s] if s < 100 else 9.0, "failed": int(s == 7),
         "rotation_mean": 0.39, "rotation_peak": 0.39, "excitation_min": 1.2 + 0.01 * s}
        for s in reversed(range(101))
    ]  # fmt: skip
    return write_runs(tmp_path / "b", baseline), write_runs(tmp_path / "c", candidate)


def test_pairs_by_seed_and_excludes_failed_runs(studies) -> None:
    seeds, b, c, excluded = study.pair(
        study.read_runs(studies[0]), study.read_runs(studies[1]), "position_rmse"
    )
    assert excluded == 1 and len(seeds) == 99 and 7 not in seeds
    np.testing.assert_allclose(c, 0.7 * b)


def test_comparison_numbers_and_checks(studies, tmp_path: Path, capsys) -> None:
    out = tmp_path / "result.json"
    status = study.main([*map(str, studies), "--require-reduction", "0.2",
                         "--excitation-floor", "1.0", "--json", str(out)])  # fmt: skip
    assert status == 0
    result = json.loads(out.read_text())
    assert math.isclose(result["ratio"], 0.7, rel_tol=1e-12)
    assert result["ratio_ci95"][0] == pytest.approx(0.7) == result["ratio_ci95"][1]
    assert result["mean_difference_ci95"][1] < 0.0
    assert result["candidate_lower_fraction"] == 1.0
    assert result["candidate_attitude"] == {
        "rotation_mean": pytest.approx(0.39),
        "rotation_peak": pytest.approx(0.39),
        "excitation_min": pytest.approx(1.2),
    }
    assert "check reduction ≥ 0.2, interval below 0: pass" in capsys.readouterr().out
    # Swapped, the candidate is worse: every check fails, exit status 1.
    assert study.main([*map(str, reversed(studies)), "--require-no-worse"]) == 1
    assert study.main([*map(str, studies), "--excitation-floor", "2.0"]) == 1


def test_missing_folder_names_it(tmp_path: Path) -> None:
    with pytest.raises(SystemExit, match=r"nowhere/runs.csv: no runs.csv"):
        study.read_runs(tmp_path / "nowhere")


def test_compare_folders_counts_the_runs_the_monitor_stopped(studies) -> None:
    result = study.compare_folders(*studies, require_no_worse=True)
    assert result["baseline_failed"] == 0 and result["candidate_failed"] == 1
    assert result["excluded_seeds"] == 1 and result["runs"] == 99
    assert result["checks"] == {"candidate not worse": True}
    text = study.format_result(result)
    assert "(1 excluded; runs stopped by the monitor: baseline 0, candidate 1)" in text
    assert text.endswith("check candidate not worse: pass")
