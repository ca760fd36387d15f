"""Results-page section "Does it survive a real vehicle?": the ``vehicle`` comparison group.

Runs the group's studies (``vehicle_variants`` of ``studies/vehicle.py``) under ``work/vehicle``
through :func:`drake_uuv.studies.compare_groups` (resume-able), one seeded run of
each configuration on the vehicle (filter with the vehicle's navigation) for the
attitude-tracking and thrust figures (``docs/figures/vehicle_*.png``), a figure of the
feasible configuration's error and NEES per step under each way the filter accounts for the
vehicle's motion (``docs/figures/vehicle_motion_errors.png``, from the studies' runs), and
returns the section's Markdown with every number taken from those runs and from
:func:`drake_uuv.models.vehicle_envelope.feasible_limits`.
"""

import math
import shlex
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from drake_uuv.analysis.figures import save_figure  # noqa: E402
from drake_uuv.analysis.stats import nees_band  # noqa: E402
from drake_uuv.analysis.vehicle_figures import (  # noqa: E402
    attitude_tracking_figure,
    thrust_figure,
)
from drake_uuv.models.attitude_plans import trajectory_attitude  # noqa: E402
from drake_uuv.models.so3 import log_so3  # noqa: E402
from drake_uuv.models.vehicle_envelope import (  # noqa: E402
    followable_target_scale,
    target_speed_exceedance,
    target_speed_rms,
)
from drake_uuv.scenario import load_scenario  # noqa: E402
from drake_uuv.simulation import ClosedLoopSimulation  # noqa: E402
from drake_uuv.studies import compare_groups  # noqa: E402
from drake_uuv.studies.runner import NORMS  # noqa: E402
from drake_uuv.studies.study import StudyResult  # noqa: E402

from ..vehicle import (  # noqa: E402
    VEHICLE_GROUP,
    scenario_feasible_limits,
    scenario_plan_max_tilt,
    vehicle_variants,
)

# The configurations shown side by side, and the seed of their figures.
CONFIGURATIONS = ("paper", "feasible", "hull")
FIGURE_SEED = 0
# The acceptance: the vehicle's estimation RMSE within this factor of the kinematic plant's.
RMSE_RATIO_LIMIT = 1.5
# [m] A run's tracking RMSE above this: the vehicle fell behind the target (lost the standoff).
LOST_TRACKING = 10.0
BOOTSTRAP_RESAMPLES = 2000
# The vehicle rows of each configuration, after its kinematic row.
_VEHICLE_ROWS = ("vehicle", "vehicle-inflated", "vehicle-navigation")


def _g(value: float | None, fmt: str = ".3g") -> str:
    return "—" if value is None or not math.isfinite(value) else format(value, fmt)


def _mean(values: np.ndarray) -> float:
    """Mean of the finite values; NaN (quietly) when there are none, as for a kinematic row's
    vehicle-only columns."""
    finite = values[np.isfinite(values)]
    return float(np.mean(finite)) if finite.size else math.nan


def _rms(values: np.ndarray) -> float:
    return math.sqrt(_mean(values**2))


def _column(result: StudyResult, name: str) -> np.ndarray:
    if name not in result.metric_names:
        return np.full(len(result.seeds), math.nan)
    return result.column(name)


def _numbers(result: StudyResult) -> dict[str, Any]:
    """The section's figures of one study (runs in seed order)."""
    s = result.summary
    start = s["steady_state_start"]
    nees = np.asarray(result.norms[:, NORMS.index("nees"), start:], dtype=float)
    completed = np.all(np.isfinite(nees), axis=1)
    runs = int(np.sum(completed))
    low, high = nees_band(6, max(runs, 1))
    per_step = nees[completed].mean(axis=0) if runs else np.full(nees.shape[1], math.nan)
    peaks = _column(result, "attitude_error_peak")
    return {
        "summary": s,
        "seeds": np.asarray(result.seeds),
        "runs": len(result.seeds),
        "completed": runs,
        "band": (low, high),
        "nees_in_band": bool(low <= (s["nees_mean"] or math.inf) <= high),
        "steps_in_band": float(np.mean((per_step >= low) & (per_step <= high))),
        "attitude_error_mean": _mean(_column(result, "attitude_error_mean")),
        "attitude_error_peak": float(np.nanmax(peaks)) if np.any(np.isfinite(peaks)) else math.nan,
        "saturated": _mean(_column(result, "thrust_saturated_fraction")),
        "model_acceleration_rmse": _rms(_column(result, "model_acceleration_rmse")),
        "acceleration_mean": s["acceleration_mean"],
        "position_mse": _column(result, "position_rmse") ** 2,
        "velocity_mse": _column(result, "velocity_rmse") ** 2,
        "bound_mse": _column(result, "pcrlb_position_rmse") ** 2,
        "tracking_runs": _column(result, "tracking_rmse"),
        "nees_runs": _column(result, "nees_mean"),
        "saturated_runs": _column(result, "thrust_saturated_fraction"),
        "norms": np.asarray(result.norms, dtype=float),
    }


def _ratio(
    vehicle: dict[str, Any], kinematic: dict[str, Any], part: str = "position"
) -> tuple[float, float, float]:
    """Vehicle / kinematic RMSE of ``part`` (position or velocity) and its 95 % interval,
    bootstrapping the seeds both studies ran in pairs."""
    a, b = _paired(vehicle, kinematic, f"{part}_mse")
    keep = np.isfinite(a) & np.isfinite(b)
    a, b = a[keep], b[keep]
    if not len(a):
        return math.nan, math.nan, math.nan
    rng = np.random.default_rng(0)
    index = rng.integers(0, len(a), size=(BOOTSTRAP_RESAMPLES, len(a)))
    with np.errstate(all="ignore"):
        ratios = np.sqrt(a[index].mean(axis=1) / b[index].mean(axis=1))
    low, high = np.percentile(ratios, [2.5, 97.5])
    return math.sqrt(a.mean() / b.mean()), float(low), float(high)


def _paired(
    first: dict[str, Any], second: dict[str, Any], key: str
) -> tuple[np.ndarray, np.ndarray]:
    """``key``'s per-run values of two studies on the seeds both ran, in seed order (a vehicle
    row runs a fifth of a kinematic row's seeds: its share)."""
    _, i, j = np.intersect1d(first["seeds"], second["seeds"], return_indices=True)
    return first[key][i], second[key][j]


def _figures(docs: Path) -> None:
    """One seeded run of each configuration on the vehicle, the filter with the vehicle's
    navigation: its attitude-tracking and thrust figures."""
    overrides = {v.name: v.overrides for v in vehicle_variants()}
    for name in CONFIGURATIONS:
        scenario = load_scenario("paper", list(overrides[f"{name}-vehicle-navigation"]))
        result = ClosedLoopSimulation(scenario).run(FIGURE_SEED)
        save_figure(
            attitude_tracking_figure(result.log, scenario),
            docs / "figures" / f"vehicle_{name}_attitude",
            formats=("png",),
        )
        save_figure(
            thrust_figure(result.log, scenario),
            docs / "figures" / f"vehicle_{name}_thrusts",
            formats=("png",),
        )


def _motion_figure(n: dict[str, dict[str, Any]], docs: Path, start: int) -> None:
    """The feasible configuration per step: RMS position error over runs, and mean NEES over
    runs against its band, on the kinematic plant and on the vehicle with each way the filter
    accounts for the vehicle's motion."""
    rows = [
        ("feasible-kinematic", "kinematic plant", "black"),
        ("feasible-vehicle", "vehicle, commanded", "tab:red"),
        ("feasible-vehicle-inflated", "vehicle, commanded + inflated W", "tab:orange"),
        ("feasible-vehicle-navigation", "vehicle, navigation", "tab:blue"),
    ]
    figure, (top, bottom) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    for name, label, color in rows:
        norms = n[name]["norms"]
        k = np.arange(norms.shape[2])
        with np.errstate(all="ignore"):
            position = np.sqrt(np.nanmean(norms[:, NORMS.index("position")] ** 2, axis=0))
            nees = np.nanmean(norms[:, NORMS.index("nees")], axis=0)
        top.semilogy(k, position, color=color, lw=0.9, label=label)
        bottom.semilogy(k, nees, color=color, lw=0.9, label=label)
    runs = n["feasible-kinematic"]["runs"]
    low, high = nees_band(6, runs)
    bottom.axhspan(low, high, color="tab:green", alpha=0.15, label=f"nees_band(6, {runs})")
    for axis in (top, bottom):
        axis.axvline(start, color="0.6", lw=0.8, ls="--")
        axis.grid(True, which="both", alpha=0.3)
    top.set_ylabel("RMS position error [m]")
    bottom.set_ylabel(f"mean NEES over {runs} runs")
    bottom.set_xlabel("step k")
    top.legend(fontsize=8, loc="upper left")
    bottom.legend(fontsize=8, loc="upper left")
    top.set_title("Feasible configuration, paper's target: the filter's vehicle motion", fontsize=9)
    figure.tight_layout()
    save_figure(figure, docs / "figures" / "vehicle_motion_errors", formats=("png",))


def _table(header: tuple[str, ...], rows: list[tuple[Any, ...]]) -> str:
    """A Markdown table: text cells left-aligned, utilisations (floats) right-aligned."""
    lines = ["| " + " | ".join(header) + " |", "|---|---|---:|---:|"]
    for row in rows:
        cells = [f"{c:.3f}" if isinstance(c, float) else str(c) for c in row]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _row(label: str, n: dict[str, Any]) -> str:
    s = n["summary"]
    cells = [
        label,
        f"{n['completed']}/{n['runs']}",
        _g(s["position_rmse"]),
        _g(s["velocity_rmse"]),
        _g(s["tracking_rmse"]),
        _g(s["nees_mean"]),
        f"{n['steps_in_band']:.0%}",
        _g(s["acceleration_mean"]),
        _g(n["model_acceleration_rmse"]),
        _g(n["attitude_error_mean"]),
        _g(n["attitude_error_peak"]),
        "—" if not math.isfinite(n["saturated"]) else f"{n['saturated']:.1%}",
        f"{s['diverged_fraction']:.0%}",
    ]
    return "| " + " | ".join(cells) + " |"


_HEADER = (
    "| configuration, plant, filter's vehicle motion | runs | position RMSE [m] "
    "| velocity RMSE [m/s] | tracking RMSE [m] | mean NEES | steps in band "
    "| mean \\|a\\| asked [m/s²] | model_acceleration_rmse [m/s²] "
    "| attitude error mean [rad] | attitude error peak [rad] | thrust saturated | diverged |\n"
    "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
)


def _label(name: str) -> str:
    """``feasible-vehicle-navigation`` → ``feasible, vehicle, navigation``."""
    config, plant, *rest = name.split("-")
    if plant == "kinematic":
        return f"{config}, kinematic plant"
    motion = {"": "commanded", "inflated": "commanded, inflated", "navigation": "navigation"}
    return f"{config}, vehicle, {motion[rest[0] if rest else '']}"


def _acceptance_row(name: str, n: dict[str, dict[str, Any]]) -> str:
    kinematic = n[name.split("-")[0] + "-kinematic"]
    vehicle = n[name]
    ratio, low, high = _ratio(vehicle, kinematic)
    velocity, vlow, vhigh = _ratio(vehicle, kinematic, "velocity")
    s, band = vehicle["summary"], vehicle["band"]
    ci = s.get("nees_mean_ci95") or [None, None]
    return (
        f"| {_label(name)} | {_g(ratio)} [{_g(low)}, {_g(high)}] | "
        f"{'yes' if ratio <= RMSE_RATIO_LIMIT else '**no**'} | "
        f"{_g(velocity)} [{_g(vlow)}, {_g(vhigh)}] | "
        f"{_g(s['nees_mean'])} [{_g(ci[0])}, {_g(ci[1])}] | [{band[0]:.2f}, {band[1]:.2f}] | "
        f"{'yes' if vehicle['nees_in_band'] else '**no**'} |"
    )


def section(work: Path, docs: Path, runs: int, execution: dict[str, Any]) -> str:
    """Runs the ``vehicle`` group and returns the section's Markdown (see the module notes)."""
    (docs / "figures").mkdir(parents=True, exist_ok=True)
    base = load_scenario("paper", ["plant=!HoveringAuv"])
    attitude, target = base.attitude, base.target
    q_star = float(np.linalg.norm(base.tracking.desired_relative_position))
    # The plan's worst tilt, shown beside the envelope's (which caps it at 90°).
    tilt = scenario_plan_max_tilt(base)
    f = scenario_feasible_limits(base)
    start, steps, t = base.steady_state_start, base.steps, base.time_step
    baseline = np.asarray(base.sonar.baseline)
    plan = [
        trajectory_attitude(k, baseline, attitude.rho, attitude.h_amplitude, attitude.h_frequency)
        for k in range(steps)
    ]
    W = np.asarray(target.acceleration_covariance)
    speed_start = target_speed_rms(target.initial_velocity, W, t, start)
    speed_end = target_speed_rms(target.initial_velocity, W, t, steps - 1)
    outrun_steps, outrun_runs = target_speed_exceedance(
        target.initial_velocity, W, t, steps, start, f.limits.speed
    )
    budget_steps, _ = target_speed_exceedance(
        target.initial_velocity, W, t, steps, start, f.speed_budget
    )
    slow_scale = followable_target_scale(target.initial_velocity, W, t, steps, f.speed_budget)

    variants = vehicle_variants()
    compared = compare_groups([VEHICLE_GROUP], work / "vehicle", runs, **execution)
    n = {variant.name: _numbers(result) for variant, result in compared}
    _figures(docs)
    _motion_figure(n, docs, start)
    note = {v.name: v.note for v in variants}

    rows = "\n".join(_row(_label(v.name), n[v.name]) for v in variants)
    acceptance_table = "\n".join(
        _acceptance_row(v.name, n) for v in variants if "-vehicle" in v.name
    )
    pk, pv, pn = n["paper-kinematic"], n["paper-vehicle"], n["paper-vehicle-navigation"]
    fk, fv, fi, fn = (n[f"feasible-{s}"] for s in ("kinematic", *_VEHICLE_ROWS))
    hk, hv, hi, hn = (n[f"hull-{s}"] for s in ("kinematic", *_VEHICLE_ROWS))
    sk, sv, sn = n["slow-kinematic"], n["slow-vehicle"], n["slow-vehicle-navigation"]
    budget = f.budget
    body_speed = q_star * f.angular_rate
    limits = f.limits

    derivation = _table(
        ("step", "demand", "value", "thrust utilisation"),
        [
            ("speed budget v_s", f"half the top speed {limits.speed:.3f} m/s (drag ∝ v²)",
             f"{f.speed_budget:.3f} m/s", budget["speed"]),
            ("rate limit ω",
             f"Algorithm 2's azimuth sweep ρπ/t = {f.sweep_rate:.3f} rad/s, rounded up",
             f"**{f.angular_rate:g} rad/s**", budget["angular_rate"]),
            ("rate steps", "a rate-limited plan reverses its rate: 2ω",
             f"{2 * f.angular_rate:g} rad/s", budget["rate_step"]),
            ("tilt", f"the plan tilts the body up to {math.degrees(tilt):.0f}°: worst "
             "restoring moment", f"{math.degrees(f.tilt):.0f}°", budget["tilt"]),
            ("turning while moving", "Coriolis coupling of v_s and ω", "", budget["coupling"]),
            ("acceleration limit a",
             f"the rest: largest a with total ≤ 1 is {f.acceleration_exact:.3f}, rounded down",
             f"**{f.acceleration:g} m/s²**", budget["acceleration"]),
            ("total", "", "", budget["total"]),
        ],
    )  # fmt: skip

    def s(x: dict[str, Any], key: str, fmt: str = ".3g") -> str:
        return _g(x["summary"][key], fmt)

    def pr(x: dict[str, Any]) -> str:
        return s(x, "position_rmse")

    def div(x: dict[str, Any]) -> str:
        return f"{x['summary']['diverged_fraction']:.0%}"

    paper_turn = max(
        float(np.linalg.norm(log_so3(plan[k + 1] @ plan[k].T))) for k in range(len(plan) - 1)
    )
    accept, accept_low, accept_high = _ratio(fn, fk)
    accept_velocity = _ratio(fn, fk, "velocity")
    holds_rmse = accept <= RMSE_RATIO_LIMIT
    holds = holds_rmse and fn["nees_in_band"]
    verdict = "holds" if holds else "does **not** hold"
    interval_inside = accept_high <= RMSE_RATIO_LIMIT
    fn_ci = fn["summary"]["nees_mean_ci95"]
    # Why the paper's target fails the ratio: runs in which the vehicle fell behind.
    lost = fn["tracking_runs"] > LOST_TRACKING
    fn_mse, fk_mse = _paired(fn, fk, "position_mse")
    kept = ~(_paired(fn, fk, "tracking_runs")[0] > LOST_TRACKING)
    kept &= np.isfinite(fn_mse) & np.isfinite(fk_mse)
    kept_ratio = math.sqrt(np.mean(fn_mse[kept]) / np.mean(fk_mse[kept]))
    fn_bound, fk_bound = _paired(fn, fk, "bound_mse")
    bound_ratio = math.sqrt(np.nanmean(fn_bound) / np.nanmean(fk_bound))
    slow_accept, slow_low, slow_high = _ratio(sn, sk)
    slow_holds = slow_accept <= RMSE_RATIO_LIMIT and sn["nees_in_band"]
    slow_ratio = _ratio(sv, sk)[0]
    slow_nav_ratio = _ratio(sn, sk)[0]
    worst_slow = int(np.nanargmax(sv["nees_runs"]))
    # A bias integrates: an acceleration error a held for τ puts the position a τ²/2 off.
    drift_time = 10.0
    drift = 0.5 * fv["model_acceleration_rmse"] * drift_time**2
    return f"""
## Does it survive a real vehicle?

The paper's vehicle is a double integrator that takes any acceleration and any attitude in one
step. `plant: !HoveringAuv` replaces it with a 31 kg hovering UUV (HoloOcean's HoveringAUV
layout, eight 77.6 N thrusters; BlueROV2 Heavy hydrodynamics scaled to its mass; Fossen's
equations) whose 50 Hz low-level controller makes the vehicle follow the outer loop's
acceleration `R u1` and attitude step `Exp(u2 t) R` with its thrusters. Its worst-direction
limits (`drake_uuv/models/vehicle_limits.py`): {limits.acceleration:.2f} m/s² acceleration,
{limits.angular_acceleration:.1f} rad/s² angular acceleration, {limits.speed:.2f} m/s top speed,
{limits.angular_rate:.2f} rad/s turning rate.

The filter's process model stays the paper's double integrator with the target's W. What
changes is how it accounts for the vehicle's own motion between two steps
(`estimator.vehicle_motion`):

- **commanded** (the paper's): `Υ̂(k+1|k) = A Υ̂(k|k) + B R u1(k)`, the commanded world
  acceleration taken as what the vehicle did. Exact for the kinematic plant.
- **navigation**: the vehicle's state `X = [p_WU, v_WU]` is known (the paper assumes it
  known; a real vehicle has its navigation), so the filter predicts the target,
  `X̄(k+1|k) = A (X(k) − Υ̂(k|k))`, and `Υ̂(k+1|k) = X(k+1) − X̄(k+1|k)`, with the same
  `P(k+1|k)`. Exact whatever the vehicle did of its commands. On the kinematic plant it
  gives the same estimates as *commanded* (`tests/estimators/test_kalman_filter.py`), so each
  kinematic row below stands for both.

{runs} seeded runs per kinematic row (seeds {base.random_seed}–{base.random_seed + runs - 1})
and the first fifth of them per vehicle row (a vehicle run costs several times a kinematic
one; the table's *runs*), so rows compare in pairs on common seeds, steady state k ≥ {start},
by `drake-uuv compare --group vehicle --runs {runs}`.

**In short.**

- *The paper's commands are not flyable.* Its law asks for a mean |a| of
  {s(pk, "acceleration_mean")} m/s² against the vehicle's {limits.acceleration:.2f}; thrusts
  are saturated {pv["saturated"]:.0%} of the time. With the commanded prediction the estimate
  is lost (position RMSE {pr(pv)} m, {div(pv)} of runs diverge). With navigation the
estimate survives ({pr(pn)} m against
  {pr(pk)} m on the kinematic plant) but the vehicle does not fly the paper's loop (tracking
  RMSE {s(pn, "tracking_rmse")} m against {s(pk, "tracking_rmse")} m, thrusts saturated
  {pn["saturated"]:.0%} of the time).
- *A configuration derived from the vehicle's limits* (rate {f.angular_rate:g} rad/s,
  acceleration {f.acceleration:g} m/s², q\\* fixed in the world) is flyable, but with the
  paper's target and the commanded prediction the estimate diverges in {div(fv)} of runs
  (position RMSE {pr(fv)} m against {pr(fk)} m): the vehicle does not make the commanded
  accelerations ({_g(fv["model_acceleration_rmse"])} m/s² RMS off) and the filter integrates
  the difference as motion, a bias. Inflating W by the measured mismatch brings the mean
  NEES from {s(fv, "nees_mean")} to {s(fi, "nees_mean")} but the RMSE only to {pr(fi)} m
  ({div(fi)} diverge).
- *With navigation the acceptance {verdict}* with the paper's own target: position
  RMSE {_g(accept, ".2f")}× the kinematic plant's, 95 % interval [{_g(accept_low, ".2f")},
  {_g(accept_high, ".2f")}] (limit {RMSE_RATIO_LIMIT:g}), mean NEES {s(fn, "nees_mean")}
  against the band [{fn["band"][0]:.2f}, {fn["band"][1]:.2f}]; {div(fn)} of runs diverge.
  The filter is consistent; the target outruns the vehicle in {int(np.sum(lost))} of
  {fn["runs"]} runs and the ranging geometry degrades with the distance (below). With a
  target the vehicle can follow, the ratio is {_g(slow_accept, ".2f")}× and the NEES
  {s(sn, "nees_mean")}.
- *A hull-mounted baseline* (|b| = 0.49 m instead of 1.41 m) costs a factor
  {_g(_ratio(hn, fn)[0], ".2f")} in position RMSE on the vehicle with navigation ({pr(hn)} m
  against {pr(fn)} m).
- *Assumed*: navigation and attitude known exactly (as the paper assumes the vehicle's state
  known), no current, ideal thrusters; see the last subsection.

### The paper's commands on the vehicle

The paper's law asks for a mean |a| of {s(pk, "acceleration_mean")} m/s² even on the
kinematic plant, and Algorithm 2 for turns of up to {paper_turn:.1f} rad in one 0.5 s step.
On the vehicle the thrusters are saturated {pv["saturated"]:.0%} of the time, the attitude
misses its target by {_g(pv["attitude_error_mean"])} rad on average (peak
{_g(pv["attitude_error_peak"])} rad), and the vehicle's acceleration differs from the
commanded one by {_g(pv["model_acceleration_rmse"])} m/s² RMS. The commanded prediction
takes all of it as motion and the estimate is lost: position RMSE {pr(pv)} m against
{pr(pk)} m on the kinematic plant, mean NEES {s(pv, "nees_mean", ".3g")}, {div(pv)} of runs
end more than 10 m off.

**What remains with navigation.** The filter no longer needs the vehicle to obey: position
RMSE {pr(pn)} m, velocity RMSE {s(pn, "velocity_rmse")} m/s, mean NEES
{s(pn, "nees_mean")}, {div(pn)} diverged. The sonars still measure from the attitude the
vehicle reaches, and the filter uses that attitude's baseline `b_W`, so the estimate does not
care that it is not Algorithm 2's. The loop is what is lost: thrusts saturated
{pn["saturated"]:.0%} of the time, the attitude {_g(pn["attitude_error_mean"])} rad from its
target on average, the acceleration {_g(pn["model_acceleration_rmse"])} m/s² RMS from the
commanded one, tracking RMSE {s(pn, "tracking_rmse")} m against {s(pk, "tracking_rmse")} m.
Seed {FIGURE_SEED}, navigation:

![attitude, paper configuration](figures/vehicle_paper_attitude.png)
![thrusts, paper configuration](figures/vehicle_paper_thrusts.png)

### A configuration the vehicle can fly, derived from the vehicle

`feasible_limits` (`drake_uuv/models/vehicle_envelope.py`) derives the limits from the
vehicle's thrust budget (`utilisation_budget`: per thruster, the worst case over directions of
each demand, summed; an envelope whose total is at most 1 never saturates):

{derivation}

The LQR weights follow Bryson's rule with the same figures (acceptable relative speed v_s,
acceptable acceleration a): `velocity_weight` = 1/v_s² = {f.velocity_weight:.3g},
`input_weight` = 1/a² = {f.input_weight:.3g}; its defaults (2 m/s, 3.2 m/s²) ask for relative
speeds beyond the vehicle's top speed while the estimate is still converging.

**The frame of q\\*.** Fixed in the body (the paper's), q\\* turns with the body: following it
at ω = {f.angular_rate:g} rad/s needs |q\\*| ω = {q_star:.2f} × {f.angular_rate:g} =
{body_speed:.2f} m/s on top of the target's speed, more than the vehicle's
{limits.speed:.2f} m/s before the target moves at all. Fixed in the heading it costs as much
for yaw, most of Algorithm 2's turning. A lower rate is no way out: within v_s the body frame
allows ω ≤ v_s/|q\\*| = {f.speed_budget / q_star:.3f} rad/s,
{f.speed_budget / q_star / f.sweep_rate:.0%} of the sweep the excitation needs. The excitation
comes from the baseline b_W turning, not from q\\*, so the feasible configuration fixes q\\* in
the **world** (`tracking.reference_frame=world`), where turning costs no speed:
`{" ".join(f"--set {shlex.quote(o)}" for o in f.overrides())}`.

**What no configuration covers: the paper's target.** Its velocity is a random walk, RMS speed
√(|v̄(0)|² + k t² tr W) = {speed_start:.2f} m/s at k = {start} and {speed_end:.2f} m/s at
k = {steps - 1}. It is faster than the vehicle's top speed {limits.speed:.2f} m/s in
{outrun_steps:.0%} of the steady-state steps ({outrun_runs:.0%} of runs at some step) and faster
than v_s in {budget_steps:.0%} (4000 seeded draws of the target alone). There the vehicle
falls behind and saturates whatever the filter: thrusts saturated {fn["saturated"]:.1%} of the
time with navigation, {fv["saturated"]:.1%} with the commanded prediction (whose wrong
estimate also sends the vehicle after the wrong point). The `slow-*` rows give the same
configuration a target it can follow: W × {slow_scale:.3g}, whose RMS speed at the last step
is v_s (`followable_target_scale`).

### Side by side

*runs*: completed of started (the estimator-health monitor stops a run whose innovations blow
up; its metrics are not in the row); *steps in band*: share of the steady-state steps whose
mean NEES over the runs lies in the 95 % band of that mean, `nees_band(6, runs)` =
χ²(6·runs)/runs; *model_acceleration_rmse*: RMS of |(v(k+1) − v(k))/t − R u1(k)|, what the
vehicle did not do of its commands (what the commanded prediction takes as motion); *thrust
saturated*: share of the controller's 50 Hz ticks whose wrench the allocation scaled down;
attitude error: mean over runs of each run's mean, and peak over all runs; *diverged*: final
position error above 10 m.

{_HEADER}
{rows}

Seed {FIGURE_SEED}, navigation, feasible configuration (the paper's target) and the hull
baseline:

![attitude, feasible configuration](figures/vehicle_feasible_attitude.png)
![thrusts, feasible configuration](figures/vehicle_feasible_thrusts.png)
![attitude, hull baseline](figures/vehicle_hull_attitude.png)
![thrusts, hull baseline](figures/vehicle_hull_thrusts.png)

### The commanded prediction fails by a bias; inflation does not remove it

Every step the commanded prediction moves Υ̂ by what the vehicle was told to do; the
difference from what it did enters the estimate like a wrong input, not like noise. While the
vehicle lags behind a fast target the difference keeps its sign, and the filter integrates
it: {_g(fv["model_acceleration_rmse"])} m/s² (the RMS mismatch of the feasible rows) held for
{drift_time:g} s is {drift:.0f} m of position. The error per step (RMS over the {runs} runs)
grows from where the vehicle first falls behind and does not come back; the kinematic
plant's and the navigation filter's stay flat at the same level:

![error and NEES per step by the filter's vehicle motion](figures/vehicle_motion_errors.png)

**Inflation.** Adding the measured mismatch to the process noise,
σ² = model_acceleration_rmse²/3 per axis ({note["feasible-vehicle-inflated"]}; hull
baseline {note["hull-vehicle-inflated"]}), tells the filter it is less sure, so it weighs
the measurements more: the mean NEES falls from {s(fv, "nees_mean")} to
{s(fi, "nees_mean")} (hull: {s(hv, "nees_mean")} →
{s(hi, "nees_mean")}), still far above the band, and the position RMSE from {pr(fv)} m to
{pr(fi)} m (hull: {pr(hv)} → {pr(hi)} m), {div(fi)} of runs diverged (hull {div(hi)}).
A variance describes a zero-mean error; this one is not. Its size is also a property of the
closed loop, not of the vehicle: with the navigation filter the same vehicle and configuration
miss their commands by only {_g(fn["model_acceleration_rmse"])} m/s² RMS, because a correct
estimate does not send them after a wrong point.

**The `slow-*` rows: the target's speed, separated from the filter.** With a target the
vehicle can follow, the vehicle does what it is told (mismatch
{_g(sv["model_acceleration_rmse"])} m/s² RMS, thrusts saturated {sv["saturated"]:.1%} of the
time) and the commanded prediction holds too: position RMSE {_g(slow_ratio, ".2f")}× the
kinematic plant's, mean NEES {s(sv, "nees_mean")} (the worst run, seed
{base.random_seed + worst_slow}, whose target still reached the vehicle's top speed:
{_g(sv["nees_runs"][worst_slow], ".1f")}); with navigation {_g(slow_nav_ratio, ".2f")}× and
{s(sn, "nees_mean")}. So the commanded prediction is not wrong in itself; it fails where the
vehicle cannot do what it is told, which the paper's target provokes. They stay in the group
for that: they show the failure's cause, and that navigation costs nothing where the commanded
prediction works.

### Acceptance: the vehicle against the kinematic plant, same configuration and seeds

Position (and velocity) RMSE ratio with its 95 % interval (seeds resampled in pairs), and the
mean NEES over runs and steady-state steps (95 % bootstrap interval over runs) against
`nees_band(6, {runs})`, the 95 % band of the mean of {runs} runs' NEES at one step. The time
average varies less than one step's mean, so this band is the lenient test, the one
`tests/estimators/test_estimator_acceptance.py` applies. The acceptance is the feasible
configuration on the vehicle; the other rows show what each choice costs.

| vehicle row | position RMSE / kinematic | ≤ {RMSE_RATIO_LIMIT:g}? | velocity RMSE / kinematic \
| mean NEES | band | in band? |
|---|---:|:---:|---:|---:|---:|:---:|
{acceptance_table}

**Verdict.** With navigation, on the paper's target, the feasible configuration
{verdict}: position RMSE {_g(accept, ".3f")}× the kinematic plant's (95 % interval
[{_g(accept_low, ".3f")}, {_g(accept_high, ".3f")}], \
{"entirely" if interval_inside else "not entirely"} below {RMSE_RATIO_LIMIT:g}), velocity RMSE
{_g(accept_velocity[0], ".3f")}× [{_g(accept_velocity[1], ".3f")},
{_g(accept_velocity[2], ".3f")}], mean NEES {s(fn, "nees_mean", ".3f")} (interval
[{_g(fn_ci[0], ".3f")}, {_g(fn_ci[1], ".3f")}]) against [{fn["band"][0]:.3f},
{fn["band"][1]:.3f}]; {fn["steps_in_band"]:.0%} of the steady-state steps have their mean
NEES in that band. With the commanded prediction the ratio is {_g(_ratio(fv, fk)[0], ".2f")}×,
inflated {_g(_ratio(fi, fk)[0], ".2f")}×.

What decides the ratio is the geometry, not the filter. In {int(np.sum(lost))} of
{fn["runs"]} runs the paper's target outran the vehicle, which fell behind (tracking RMSE
above {LOST_TRACKING:g} m), and a range error grows with the range: the per-run posterior
Cramér–Rao bound of the vehicle's runs is {_g(bound_ratio, ".2f")}× the kinematic plant's,
and the filter's RMSE over it is {s(fn, "position_rmse_over_per_run_pcrlb", ".2f")} against
{s(fk, "position_rmse_over_per_run_pcrlb", ".2f")} on the kinematic plant. Over the
{int(np.sum(kept))} runs the vehicle kept up with, the ratio is {_g(kept_ratio, ".2f")}×
(that subset is chosen after the fact, so it explains and does not test). With a target the
vehicle can follow (`slow-vehicle-navigation`), the acceptance
{"holds" if slow_holds else "does **not** hold"}: position RMSE {_g(slow_accept, ".3f")}×
the kinematic plant's [{_g(slow_low, ".3f")}, {_g(slow_high, ".3f")}], mean NEES
{s(sn, "nees_mean", ".3f")} against [{sn["band"][0]:.3f}, {sn["band"][1]:.3f}].

### What a real mounting costs

With both sonars on the hull (b = [−0.35, 0.35, 0] m, |b| = 0.49 m instead of the paper's
1.41 m "as if on booms"), Y = q_sᵀ q has a third of the lever: position RMSE {pr(hk)} m
against {pr(fk)} m on the kinematic plant ({div(hk)} of runs diverged), {pr(hn)} m against
{pr(fn)} m on the vehicle with navigation ({div(hn)} diverged), tracking RMSE
{s(hn, "tracking_rmse")} m against {s(fn, "tracking_rmse")} m. The vehicle with navigation
stays within {_g(_ratio(hn, hk)[0], ".2f")}× the kinematic plant's RMSE with that baseline too.

### What this assumes

- **Perfect navigation.** The navigation filter takes the vehicle's position and velocity
  exactly from the simulation, as the paper assumes the vehicle's state known. A real
  vehicle's navigation (DVL, INS, USBL) has noise and drift, and its error enters the
  relative estimate one to one: the estimate of the target's state is then relative to where
  the vehicle believes it is. Not modelled here.
- **Perfect attitude.** The sonar baseline `b_W = R_WB b` uses the vehicle's true attitude,
  and the low-level controller its true state.
- **The vehicle.** Fossen's equations (rigid body and added mass, Coriolis, linear and
  quadratic drag, restoring forces; BlueROV2 Heavy coefficients scaled to 31 kg) in still
  water: no current, no waves. Thrust is applied as allocated, without lag
  (`thrust_time_constant` 0), limited only by the thrusters' maximum.
- **The target** is the paper's velocity random walk; a target that outruns the vehicle is
  kept (the `slow-*` rows show what a followable one changes).
- **The filter** is the paper's KF with its double-integrator process model and the target's
  W, unchanged between rows except for `vehicle_motion` and, in the inflated rows,
  `added_acceleration_variance`.
"""
