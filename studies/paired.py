"""Paired per-seed comparison of two Monte Carlo study folders (their runs.csv).

    drake-uuv compare --group attitude --runs 100 --workers 2 --out out/attitude
    python studies/paired.py out/attitude/studies/kf-alg2 \\
        out/attitude/studies/kf-info-0.39 --require-reduction 0.2 --excitation-floor 1.0

(or any two ``drake-uuv montecarlo --out`` folders, e.g. one with
``--set 'attitude=!InformationSeeking {max_angle_per_step: 0.39}'``).

Runs are paired by seed (run i of a study uses seed random_seed + i, so two studies with the
same first seed and run count share every target trajectory and every noise draw that both
variants consume alike). For the metric (default ``position_rmse``) it prints each study's
pooled RMSE (√ of the mean over runs of the per-run mean square, as ``summary.json``), their
ratio with a paired percentile-bootstrap 95 % interval (seeds resampled jointly), the mean
per-seed difference (candidate − baseline) with its bootstrap 95 % interval, and the share
of seeds where the candidate is lower; then, where runs.csv has them, the attitude's mean
and peak rotation per step, the smallest excitation eigenvalue over every window of every
run and the peak reference acceleration.

A seed is left out of the pairing when either run was stopped by the estimator-health
monitor (``failed``); how many runs each side lost that way is printed and returned, since
leaving them out flatters the side that lost them.

Checks, each optional; the exit status is 1 if one fails:

* ``--require-reduction R``: the pooled metric is at least ``R`` (a fraction) lower and the
  difference's interval lies below zero;
* ``--require-no-worse``: the candidate's pooled metric is not above the baseline's;
* ``--excitation-floor F``: the candidate's smallest excitation eigenvalue is at least F.

The functions are importable (the results page's attitude section uses
:func:`compare_folders` and :func:`format_result`).
"""

import argparse
import csv
import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

RESAMPLES = 2000
BOOTSTRAP_SEED = 0
ATTITUDE_COLUMNS = (
    ("rotation_mean", "mean", "mean rotation per step [rad]"),
    ("rotation_peak", "max", "peak rotation per step [rad]"),
    ("excitation_min", "min", "smallest excitation eigenvalue, any window [m²]"),
    ("reference_acceleration_peak", "max", "peak reference acceleration [m/s²]"),
)


def read_runs(folder: Path) -> dict[str, np.ndarray]:
    """The columns of ``folder/runs.csv`` as float arrays, keyed by name."""
    path = folder / "runs.csv"
    if not path.is_file():
        raise SystemExit(f"{path}: no runs.csv (run drake-uuv montecarlo --out {folder})")
    with path.open(newline="") as handle:
        rows = list(csv.DictReader(handle))
    if not rows:
        raise SystemExit(f"{path}: no runs")
    return {
        name: np.array(
            [float(row[name]) if row[name] not in ("", None) else math.nan for row in rows]
        )
        for name in rows[0]
    }


def pair(
    baseline: dict[str, np.ndarray], candidate: dict[str, np.ndarray], metric: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """``(seeds, baseline values, candidate values, runs excluded)`` over the shared seeds.

    A seed is excluded when either run failed (``failed`` = 1) or its metric is not finite.
    """
    for name, runs in (("baseline", baseline), ("candidate", candidate)):
        if metric not in runs:
            raise SystemExit(f"{name}: runs.csv has no column {metric!r}")
    shared, b_index, c_index = np.intersect1d(
        baseline["seed"], candidate["seed"], return_indices=True
    )
    if len(shared) == 0:
        raise SystemExit("the two studies share no seed")
    b = baseline[metric][b_index]
    c = candidate[metric][c_index]
    failed = np.zeros(len(shared), dtype=bool)
    for runs, index in ((baseline, b_index), (candidate, c_index)):
        if "failed" in runs:
            failed |= runs["failed"][index] != 0.0
    keep = ~failed & np.isfinite(b) & np.isfinite(c)
    return shared[keep], b[keep], c[keep], int(np.sum(~keep))


def paired_comparison(b: np.ndarray, c: np.ndarray) -> dict[str, float]:
    """Pooled RMSEs, their ratio and the per-seed difference, with bootstrap 95 % intervals."""
    rng = np.random.default_rng(BOOTSTRAP_SEED)
    index = rng.integers(0, len(b), size=(RESAMPLES, len(b)))
    pooled_b = math.sqrt(float(np.mean(b**2)))
    pooled_c = math.sqrt(float(np.mean(c**2)))
    ratios = np.sqrt(np.mean(c[index] ** 2, axis=1) / np.mean(b[index] ** 2, axis=1))
    difference = c - b
    means = np.mean(difference[index], axis=1)
    return {
        "runs": len(b),
        "baseline": pooled_b,
        "candidate": pooled_c,
        "ratio": pooled_c / pooled_b,
        "ratio_ci95": [float(np.quantile(ratios, 0.025)), float(np.quantile(ratios, 0.975))],
        "reduction": 1.0 - pooled_c / pooled_b,
        "mean_difference": float(np.mean(difference)),
        "mean_difference_ci95": [
            float(np.quantile(means, 0.025)),
            float(np.quantile(means, 0.975)),
        ],
        "candidate_lower_fraction": float(np.mean(difference < 0.0)),
    }


def attitude_summary(runs: dict[str, np.ndarray]) -> dict[str, float]:
    """The attitude columns of a study reduced over its runs (mean, max or min as listed)."""
    reducers = {"mean": np.nanmean, "max": np.nanmax, "min": np.nanmin}
    return {
        name: float(reducers[how](runs[name]))
        for name, how, _ in ATTITUDE_COLUMNS
        if name in runs and np.any(np.isfinite(runs[name]))
    }


def compare_folders(
    baseline_folder: Path,
    candidate_folder: Path,
    metric: str = "position_rmse",
    require_reduction: float | None = None,
    require_no_worse: bool = False,
    excitation_floor: float | None = None,
) -> dict[str, Any]:
    """The paired comparison of two study folders and the checks asked for (see the module
    notes); ``result["checks"]`` maps each check's label to whether it passed."""
    baseline, candidate = read_runs(baseline_folder), read_runs(candidate_folder)
    seeds, b, c, excluded = pair(baseline, candidate, metric)
    result: dict[str, Any] = {
        "metric": metric,
        "baseline_study": str(baseline_folder),
        "candidate_study": str(candidate_folder),
        "excluded_seeds": excluded,
        "baseline_failed": failed_runs(baseline),
        "candidate_failed": failed_runs(candidate),
        "first_seed": int(seeds[0]),
        **paired_comparison(b, c),
        "baseline_attitude": attitude_summary(baseline),
        "candidate_attitude": attitude_summary(candidate),
    }
    checks: dict[str, bool] = {}
    if require_reduction is not None:
        checks[f"reduction ≥ {require_reduction:g}, interval below 0"] = (
            result["reduction"] >= require_reduction and result["mean_difference_ci95"][1] < 0.0
        )
    if require_no_worse:
        checks["candidate not worse"] = result["candidate"] <= result["baseline"]
    if excitation_floor is not None:
        low = result["candidate_attitude"].get("excitation_min", math.nan)
        checks[f"excitation ≥ {excitation_floor:g} m²"] = bool(low >= excitation_floor)
    result["checks"] = checks
    return result


def failed_runs(runs: dict[str, np.ndarray]) -> int:
    """How many runs of a study the estimator-health monitor stopped."""
    return int(np.sum(runs["failed"] != 0.0)) if "failed" in runs else 0


def format_result(result: dict[str, Any]) -> str:
    """The printed lines of a :func:`compare_folders` result."""
    lo, hi = result["ratio_ci95"]
    dlo, dhi = result["mean_difference_ci95"]
    lines = [
        f"{result['metric']}: {result['runs']} paired seeds from {result['first_seed']} "
        f"({result['excluded_seeds']} excluded; runs stopped by the monitor: baseline "
        f"{result['baseline_failed']}, candidate {result['candidate_failed']})",
        f"  baseline  {result['baseline']:.4f}   {result['baseline_study']}",
        f"  candidate {result['candidate']:.4f}   {result['candidate_study']}",
        f"  ratio {result['ratio']:.3f} [{lo:.3f}, {hi:.3f}]  "
        f"(reduction {result['reduction']:.1%})",
        f"  per-seed difference {result['mean_difference']:+.4f} [{dlo:+.4f}, {dhi:+.4f}], "
        f"candidate lower in {result['candidate_lower_fraction']:.0%}",
    ]
    for name, _, label in ATTITUDE_COLUMNS:
        values = [result[f"{side}_attitude"].get(name) for side in ("baseline", "candidate")]
        if any(v is not None for v in values):
            text = "  ".join("—" if v is None else f"{v:.3f}" for v in values)
            lines.append(f"  {label}: {text}")
    for label, passed in result["checks"].items():
        lines.append(f"  check {label}: {'pass' if passed else 'FAIL'}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__.splitlines()[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("baseline", type=Path, help="study folder of the reference variant")
    parser.add_argument("candidate", type=Path, help="study folder of the variant compared")
    parser.add_argument("--metric", default="position_rmse", help="a per-run column (RMSE-like)")
    parser.add_argument("--require-reduction", type=float, metavar="R")
    parser.add_argument("--require-no-worse", action="store_true")
    parser.add_argument("--excitation-floor", type=float, metavar="F")
    parser.add_argument("--json", type=Path, help="also write the result here")
    args = parser.parse_args(argv)

    result = compare_folders(
        args.baseline,
        args.candidate,
        args.metric,
        require_reduction=args.require_reduction,
        require_no_worse=args.require_no_worse,
        excitation_floor=args.excitation_floor,
    )
    print(format_result(result))
    if args.json is not None:
        args.json.write_text(json.dumps(result, indent=2) + "\n")
    return 0 if all(result["checks"].values()) else 1


if __name__ == "__main__":
    sys.exit(main())
