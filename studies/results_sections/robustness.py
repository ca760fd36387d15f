"""Results-page section "Does any run get lost?": the ``robustness`` comparison group.

Runs the group's studies (``robustness_variants`` of ``studies/robustness.py``) under
``work/robustness`` through :func:`drake_uuv.studies.compare_groups` (resume-able) and returns
the section's Markdown: for each row its runs, the lost runs with their seeds (stopped by the
estimator-health monitor, or ending more than 10 m off), the worst final error, the mean NEES
with its 95 % band and its bootstrap interval, and the position RMSE over the per-run bound.
"""

import math
from pathlib import Path
from typing import Any

import numpy as np

from drake_uuv.models.statistics import nees_band
from drake_uuv.scenario import load_scenario
from drake_uuv.studies import compare_groups
from drake_uuv.studies.study import StudyResult

from ..robustness import LOST_ERROR, REGIMES, ROBUSTNESS_GROUP, SHIPPED
from ..shares import LARGE_CLOUD, LARGE_CLOUD_SHARE, VEHICLE_SHARE

# Seeds listed in a row at most; more are counted.
LISTED_SEEDS = 12


def lost_seeds(result: StudyResult) -> list[int]:
    """The seeds of the runs lost: stopped by the monitor, or ending beyond :data:`LOST_ERROR`."""
    failed = result.column("failed") > 0
    final = (
        result.column("final_position_error") if not failed.all() else np.full(len(failed), np.nan)
    )
    lost = failed | ~(final <= LOST_ERROR)
    return [int(seed) for seed in result.seeds[lost]]


def _g(value: float, fmt: str = ".3g") -> str:
    return "—" if value is None or not math.isfinite(value) else format(value, fmt)


def row(name: str, note: str, result: StudyResult) -> tuple[str, bool, bool]:
    """The row's Markdown, whether it lost no run and whether its mean NEES is in the band."""
    runs = len(result.seeds)
    summary = result.summary
    lost = lost_seeds(result)
    listed = ", ".join(map(str, lost[:LISTED_SEEDS])) + (" …" if len(lost) > LISTED_SEEDS else "")
    finite = result.column("final_position_error")
    finite = finite[np.isfinite(finite)]
    worst = float(finite.max()) if finite.size else math.nan
    low, high = nees_band(6, max(runs - len(lost), 1))
    nees = summary.get("nees_mean", math.nan)
    low_ci, high_ci = summary.get("nees_mean_ci95", (math.nan, math.nan))
    consistent = low <= nees <= high
    ratio = summary.get("position_rmse_over_per_run_pcrlb", math.nan)
    cells = [
        f"`{name}`", note, str(runs), f"{len(lost)}" + (f" ({listed})" if lost else ""),
        _g(worst), f"{_g(nees)} [{_g(low_ci)}, {_g(high_ci)}]", f"[{low:.2f}, {high:.2f}]",
        "yes" if consistent else "**no**", _g(ratio),
    ]  # fmt: skip
    return "| " + " | ".join(cells) + " |", not lost, consistent


def section(work: Path, docs: Path, runs: int, execution: dict[str, Any]) -> str:
    """Runs the ``robustness`` group and returns the section's Markdown."""
    compared = compare_groups([ROBUSTNESS_GROUP], work / "robustness", runs, **execution)
    table = [
        "| row | what | runs | lost (seeds) | worst final error [m] | mean NEES [95 % interval] "
        "| band (consistent filter) | consistent | position RMSE / per-run bound |",
        "|---|---|---:|---|---:|---:|---:|---|---:|",
    ]
    kept = consistent = 0
    as_shipped = {f"robust-{name}" for name in SHIPPED}
    shipped_out, nees_of = [], {}
    for variant, result in compared:
        line, none_lost, in_band = row(variant.name, variant.note, result)
        table.append(line)
        kept += none_lost
        consistent += in_band
        if variant.name in as_shipped and not in_band:
            shipped_out.append(f"`{variant.name}`")
        if variant.name.endswith(("-ekf", "-ekf2", "-ukf", "-ukf2", "-pf", "-pf2")):
            nees_of[variant.name] = (result.summary.get("nees_mean", math.nan), in_band)
    ekf_nees, ekf_option = _pairs(nees_of, "ekf")
    ukf_nees, ukf_option = _pairs(nees_of, "ukf")
    pf_nees, pf_option = _pairs(nees_of, "pf")
    vehicle_runs = round(VEHICLE_SHARE * runs)
    cloud_runs = round(LARGE_CLOUD_SHARE * runs)
    cloud = f"{LARGE_CLOUD:,}".replace(",", " ")
    far = load_scenario(REGIMES["far"][0]).estimator
    far_count = f"{far.particle_count:,}".replace(",", " ")
    far_kernel = far.particle_kernel.replace("_", "–")
    return f"""
## Does any run get lost?

A lost run is a vehicle lost at sea: the loops are run over many seeds, batched (one diagram
steps a whole batch of runs), {runs} per row on the kinematic plant, {vehicle_runs}
on the hovering UUV and {cloud_runs} with a particle filter of {cloud} particles (the
table's *runs*). Every shipped scenario runs as it ships (`robust-<scenario>`), and the EKF, the
UKF and the particle filter run in the paper's regime, under a damped LQR law with q\\* fixed in
the world (≤ 3 m/s², `lqr`), at the far standoff (14 m), with noisy sonars (σ = 1 m) and in
the realistic scenario on both plants. The EKF runs twice: as the textbook filter (`ekf`) and
with the ranges' second-order terms (`ekf2`: Gelb's truncated second-order filter, its term's
variance counted over 7 updates, `--set estimator.second_order=full --set
estimator.linearisation_correlation=7`); so does the UKF, as the textbook filter (`ukf`) and
with its linearisation error's variance counted over 4 updates (`ukf2`); and, where the
scenario's own filter does not have it, the particle filter with its regularisation kernel
in range–bearing coordinates (`pf2`). A run is lost when the
estimator-health monitor stopped it or its final position error exceeds {LOST_ERROR:g} m. A
regime's filters take its scenario's particle options (at the far standoff, as
`far_standoff.yaml`: {far_count} particles, the regularisation kernel in {far_kernel}
coordinates) and otherwise their defaults: each filter with its recovery (a run whose
innovations say it diverged goes back to its linear start) and, in the realistic scenario, the
tracking law's hold (at rest while the filter is in its linear start). The
band is the 95 % band of a consistent filter's NEES averaged over the row's runs at one step,
χ²(6n)/n: a time average varies less, so a mean outside it is inconsistent.

{chr(10).join(table)}

{kept} of {len(compared)} rows lose no run; {consistent} of {len(compared)} have their mean NEES
inside the band (`drake-uuv compare --group robustness --runs {runs}`). Of the
{len(as_shipped)} shipped scenarios, as they ship, {len(as_shipped) - len(shipped_out)} are
consistent{"" if not shipped_out else " (out of band: " + ", ".join(shipped_out) + ")"}.

The EKF's mean NEES, textbook → second-order: {ekf_nees}. The second-order terms are what the
textbook EKF misses where the range shell bends (their mean moves the estimate inside the
shell, their variance widens the ranges' noise): with them {ekf_option}. The UKF's, its
linearisation error counted as independent from update to update → over 4 updates (`--set
estimator.linearisation_correlation=4`; its sigma points carry the second-order term already):
{ukf_nees}; so counted {ukf_option}. The particle filter's, its regularisation kernel in
Cartesian → range–bearing coordinates (`pf2`, `--set estimator.particle_kernel=range_bearing`:
the kernel moves particles along their range shells; `far_standoff` ships it):
{pf_nees}; so moved {pf_option}.
"""


def _pairs(nees_of: dict[str, tuple[float, bool]], name: str) -> tuple[str, str]:
    """For the rows ``robust-<regime>-<name>`` and their consistent ``…-<name>2``: each regime's
    mean NEES, default → consistent option, and where the option is out of band, in words."""
    pairs, out = [], []
    for row, (nees, _) in nees_of.items():
        if row.endswith(f"-{name}") and row + "2" in nees_of:
            nees2, in_band2 = nees_of[row + "2"]
            regime = row[len("robust-") : -len(name) - 1]
            pairs.append(f"{regime} {_g(nees)} → {_g(nees2)}")
            if not in_band2:  # out of band: below it, cautious; above it, overconfident
                out.append(f"`{regime}` ({'below' if nees2 < 6.0 else 'above'})")
    listed = " and ".join([", ".join(out[:-1]), out[-1]] if len(out) > 1 else out)
    return "; ".join(pairs), (
        f"it stays out of band in {listed}" if out else "it is in band in every regime"
    )
