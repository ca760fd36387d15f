"""Results-page section "Attitude that seeks observability": the information-seeking planner
against Algorithm 2 at equal motion, with the paper's KF and the raw-range EKF, and on the
hovering UUV.

Runs the comparison groups ``attitude`` (``runs`` per variant) and ``attitude_vehicle``
(``runs`` per kinematic row, a fifth of them per vehicle row) through
:func:`drake_uuv.studies.compare_groups` into ``work/attitude`` and ``work/attitude_vehicle``
(resume-able), pairs the variants seed by seed with ``studies/paired.py``, draws
``docs/figures/attitude_rmse_rotation.png`` and returns the Markdown. Every number in it
comes from these runs.
"""

import math
import shlex
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.ticker import FormatStrFormatter, LogLocator  # noqa: E402

from drake_uuv.analysis.figures import save_figure  # noqa: E402
from drake_uuv.models.vehicle_limits import utilisation_budget  # noqa: E402
from drake_uuv.studies import compare_groups  # noqa: E402

from ..attitude import ATTITUDE_BUDGETS, ATTITUDE_GROUP, ATTITUDE_VEHICLE_GROUP  # noqa: E402
from ..paired import compare_folders, failed_runs, read_runs  # noqa: E402
from ..shares import VEHICLE_SHARE  # noqa: E402
from ..vehicle import VEHICLE_ANGULAR_RATE, VEHICLE_LOOP, VEHICLE_SPEED_BUDGET  # noqa: E402

# The acceptance: at Algorithm 2's mean rotation per step the planner's position RMSE is at
# least this much lower (and the paired difference's interval excludes zero).
REQUIRED_REDUCTION = 0.2
FIGURE = "attitude_rmse_rotation"
ESTIMATORS = {"kf": "the paper's KF (`!PaperKf`)", "ekf": "the raw-range EKF (`!Ekf`)"}


def _g(value: float | None, fmt: str = ".3g") -> str:
    return "—" if value is None or not math.isfinite(value) else format(value, fmt)


def _with_interval(summary: dict[str, Any], key: str, fmt: str = "#.3g") -> str:
    interval = summary.get(f"{key}_ci95") or (None, None)
    return f"{_g(summary.get(key), fmt)} [{_g(interval[0], fmt)}, {_g(interval[1], fmt)}]"


class _Row:
    """A variant's study: its summary, its runs.csv columns, its folder."""

    def __init__(self, variant, result) -> None:
        self.variant = variant
        self.summary = result.summary
        self.folder = Path(result.study.out_dir)
        self.scenario = result.study.scenario
        self.runs = read_runs(self.folder)

    def reduce(self, column: str, how: str) -> float:
        values = self.runs.get(column)
        if values is None or not np.any(np.isfinite(values)):
            return math.nan
        return float({"mean": np.nanmean, "max": np.nanmax, "min": np.nanmin}[how](values))

    @property
    def failed(self) -> int:
        return failed_runs(self.runs)


def _table(rows: list[_Row], vehicle: bool = False) -> str:
    headers = [
        "variant",
        "budget [rad/step]",
        "runs",
        "position RMSE [m]",
        "RMSE / per-run PCRLB",
        "tracking RMSE [m]",
        "mean rotation [rad/step]",
        "peak rotation [rad/step]",
        "min λ(Λ₂₄) [m²]",
        "stopped by monitor",
        "diverged",
    ]
    if vehicle:
        headers += ["thrust saturated", "attitude error [rad]"]
    out = ["| " + " | ".join(headers) + " |", "|---|" + "---:|" * (len(headers) - 1)]
    for row in rows:
        s = row.summary
        cells = [
            f"`{row.variant.name}`",
            row.variant.note.split(" rad/step")[0] or "unlimited",
            str(s["runs"]),
            _with_interval(s, "position_rmse"),
            _with_interval(s, "position_rmse_over_per_run_pcrlb"),
            _with_interval(s, "tracking_rmse"),
            _g(row.reduce("rotation_mean", "mean"), ".3f"),
            _g(row.reduce("rotation_peak", "max"), ".3f"),
            _g(row.reduce("excitation_min", "min"), "#.3g"),
            str(row.failed),
            _g(s.get("diverged_fraction"), ".0%"),
        ]
        if vehicle:
            cells += [
                _g(row.reduce("thrust_saturated_fraction", "mean"), ".2%"),
                _g(row.reduce("attitude_error_mean", "mean"), ".2g"),
            ]
        out.append("| " + " | ".join(cells) + " |")
    return "\n".join(out) + "\n"


def _paired(baseline: _Row, candidate: _Row, **checks: Any) -> dict[str, Any]:
    return compare_folders(baseline.folder, candidate.folder, **checks)


def _pair_line(label: str, result: dict[str, Any]) -> str:
    lo, hi = result["ratio_ci95"]
    dlo, dhi = result["mean_difference_ci95"]
    return (
        f"| {label} | {result['baseline']:.3f} → {result['candidate']:.3f} | "
        f"{result['ratio']:.3f} [{lo:.3f}, {hi:.3f}] | {result['mean_difference']:+.3f} "
        f"[{dlo:+.3f}, {dhi:+.3f}] | {result['candidate_lower_fraction']:.0%} | "
        f"{result['runs']} ({result['baseline_failed']} / {result['candidate_failed']}) |"
    )


PAIR_HEADER = (
    "| candidate vs baseline | pooled position RMSE [m] | ratio [95 %] | "
    "mean per-seed difference [m] [95 %] | candidate lower | paired seeds (stopped: "
    "baseline / candidate) |\n|---|---:|---:|---:|---:|---:|\n"
)


def _verdict(passed: bool) -> str:
    return "**pass**" if passed else "**FAIL**"


def _figure(rows: dict[str, _Row], docs: Path) -> Path:
    """Pooled position RMSE against the mean rotation per step actually achieved."""
    figure, axes = plt.subplots(1, 2, figsize=(10, 4), sharex=True)
    for axis, estimator in zip(axes, ESTIMATORS, strict=True):
        for kind, label, style in (
            ("alg2", "Algorithm 2, rate-limited", dict(color="tab:blue", marker="o")),
            ("info", "information-seeking planner", dict(color="tab:red", marker="s")),
        ):
            members = [rows[f"{estimator}-{kind}-{b:g}"] for b in ATTITUDE_BUDGETS]
            x = [m.reduce("rotation_mean", "mean") for m in members]
            y = np.array([m.summary["position_rmse"] for m in members])
            ci = np.array([m.summary["position_rmse_ci95"] for m in members]).T
            axis.errorbar(x, y, yerr=np.abs(ci - y), capsize=3, label=label, **style)
            for xi, yi, b in zip(x, y, ATTITUDE_BUDGETS, strict=True):
                axis.annotate(f"{b:g}", (xi, yi), textcoords="offset points", xytext=(4, 4))
        unlimited = rows[f"{estimator}-alg2"]
        axis.errorbar(
            [unlimited.reduce("rotation_mean", "mean")],
            [unlimited.summary["position_rmse"]],
            yerr=np.abs(
                np.array(unlimited.summary["position_rmse_ci95"])[:, None]
                - unlimited.summary["position_rmse"]
            ),
            color="black",
            marker="*",
            markersize=12,
            capsize=3,
            linestyle="none",
            label="Algorithm 2, unlimited",
        )
        axis.set_yscale("log")
        # Plain numbers at 1, 2, 5 × 10ⁿ and at the minor ticks between (the range is narrow).
        axis.yaxis.set_major_locator(LogLocator(base=10.0, subs=(1.0, 2.0, 5.0)))
        axis.yaxis.set_major_formatter(FormatStrFormatter("%g"))
        axis.yaxis.set_minor_formatter(FormatStrFormatter("%g"))
        axis.set_title(ESTIMATORS[estimator].replace("`", ""))
        axis.set_xlabel("mean rotation per step [rad] (labels: budget)")
        axis.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("position RMSE, k ≥ 200 [m] (95 % interval)")
    axes[0].legend(fontsize=8)
    figure.tight_layout()
    path = docs / "figures" / f"{FIGURE}.png"
    save_figure(figure, path.with_suffix(""), formats=("png",))
    return path


def section(work: Path, docs: Path, runs: int, execution: dict[str, Any]) -> str:
    """Runs (or resumes) both groups, draws the figure and returns the section's Markdown."""
    main = compare_groups([ATTITUDE_GROUP], work / "attitude", runs, **execution)
    vehicle = compare_groups([ATTITUDE_VEHICLE_GROUP], work / "attitude_vehicle", runs, **execution)
    vehicle_runs = round(VEHICLE_SHARE * runs)
    rows = {variant.name: _Row(variant, result) for variant, result in main}
    vrows = {variant.name: _Row(variant, result) for variant, result in vehicle}
    (docs / "figures").mkdir(parents=True, exist_ok=True)
    figure = _figure(rows, docs)

    top = max(ATTITUDE_BUDGETS)
    half = sorted(ATTITUDE_BUDGETS)[-2]
    any_info = next(row for name, row in rows.items() if "-info-" in name)
    floor = any_info.scenario.attitude.excitation_floor
    window = any_info.scenario.analysis.pe_window
    t = any_info.scenario.time_step

    tables, pairs, verdicts = [], [], []
    for estimator, title in ESTIMATORS.items():
        members = [rows[f"{estimator}-alg2"]]
        for b in ATTITUDE_BUDGETS:
            members += [rows[f"{estimator}-alg2-{b:g}"], rows[f"{estimator}-info-{b:g}"]]
        tables.append(f"**{title}**\n\n{_table(members)}")
        unlimited = rows[f"{estimator}-alg2"]
        alg2_rotation = unlimited.reduce("rotation_mean", "mean")
        lines = []
        for b in ATTITUDE_BUDGETS:
            info = rows[f"{estimator}-info-{b:g}"]
            lines.append(
                _pair_line(
                    f"`{info.variant.name}` vs `{estimator}-alg2-{b:g}`",
                    _paired(rows[f"{estimator}-alg2-{b:g}"], info),
                )
            )
            lines.append(
                _pair_line(f"`{info.variant.name}` vs `{unlimited.variant.name}`",
                           _paired(unlimited, info))
            )  # fmt: skip
        pairs.append(f"**{title}**\n\n{PAIR_HEADER}" + "\n".join(lines) + "\n")

        equal = _paired(unlimited, rows[f"{estimator}-info-{top:g}"],
                        require_reduction=REQUIRED_REDUCTION)  # fmt: skip
        at_half = _paired(unlimited, rows[f"{estimator}-info-{half:g}"], require_no_worse=True)
        lows = {b: rows[f"{estimator}-info-{b:g}"].reduce("excitation_min", "min")
                for b in ATTITUDE_BUDGETS}  # fmt: skip
        excited = all(low >= floor for low in lows.values())
        lo, hi = equal["ratio_ci95"]
        dlo, dhi = equal["mean_difference_ci95"]
        hlo, hhi = at_half["ratio_ci95"]
        significance = (
            "the interval lies below 1"
            if hhi < 1.0
            else "the interval lies above 1"
            if hlo > 1.0
            else "the interval contains 1: no difference to be seen"
        )
        stopped = sum(rows[f"{estimator}-info-{b:g}"].failed for b in ATTITUDE_BUDGETS)
        unseen = (
            f" ({stopped} runs stopped by the monitor have no excitation figure)" if stopped else ""
        )
        verdicts.append(
            f"*{title}*; Algorithm 2 (unlimited) turns {alg2_rotation:.3f} rad per step on "
            f"average, so {top:g} rad is about equal ({top / alg2_rotation - 1:+.1%}).\n\n"
            f"- At {top:g} rad per step the planner's position RMSE is {equal['candidate']:.3f} m "
            f"against {equal['baseline']:.3f} m: {equal['reduction']:.1%} lower (ratio "
            f"{equal['ratio']:.3f} [{lo:.3f}, {hi:.3f}]; per-seed difference "
            f"{equal['mean_difference']:+.3f} m [{dlo:+.3f}, {dhi:+.3f}]). "
            f"≥ {REQUIRED_REDUCTION:.0%} lower with the interval below zero: "
            f"{_verdict(all(equal['checks'].values()))}.\n"
            f"- At {half:g} rad per step: {at_half['candidate']:.3f} m against Algorithm 2's "
            f"{at_half['baseline']:.3f} m at full motion (ratio {at_half['ratio']:.3f} "
            f"[{hlo:.3f}, {hhi:.3f}], {significance}). At least as accurate: "
            f"{_verdict(all(at_half['checks'].values()))}.\n"
            f"- Smallest eigenvalue of Λ over every {window}-step window of every run, budgets "
            + ", ".join(f"{b:g}: {low:.3f} m²" for b, low in lows.items())
            + f"{unseen}. Above the {floor:g} m² floor: {_verdict(excited)}.\n"
        )

    limited = rows[f"kf-alg2-{top:g}"].reduce("rotation_mean", "mean")
    planner = rows[f"kf-info-{top:g}"].reduce("rotation_mean", "mean")
    motion_note = (
        f"The planner spends its whole budget every step (mean rotation {planner:.3f} rad at "
        f"{top:g}); Algorithm 2 limited to a budget spends less on average ({limited:.3f} rad at "
        f"{top:g}), since the limit only clips its larger steps. So the rate-limited rows "
        "compare equal peak motion, and Algorithm 2 unlimited against the planner at "
        f"{top:g} rad compares equal mean motion.\n"
    )
    low = min(ATTITUDE_BUDGETS)
    same = np.array_equal(
        rows[f"kf-alg2-{low:g}"].runs["position_rmse"],
        rows[f"ekf-alg2-{low:g}"].runs["position_rmse"],
        equal_nan=True,
    )
    same_note = (
        f"With Algorithm 2 limited to {low:g} rad per step the EKF's rows equal the KF's run for "
        "run: the raw-range filters start as the paper's KF on the sample means and hand over "
        "when trace P_qq falls below their threshold (`linear_start_position_variance`), which "
        "that little excitation never brings about.\n"
        if same
        else ""
    )

    vnames = list(vrows)
    vpairs, vresults = [], {}
    for plant in ("kinematic", "auv"):
        alg2, info = (vrows[n] for n in vnames if n.startswith(f"{plant}-"))
        vresults[plant] = _paired(alg2, info)
        vpairs.append(_pair_line(f"`{info.variant.name}` vs `{alg2.variant.name}`",
                                 vresults[plant]))  # fmt: skip
    auv_result = vresults["auv"]
    alo, ahi = auv_result["ratio_ci95"]
    vbudget = VEHICLE_ANGULAR_RATE * t
    auv = next(row.scenario for name, row in vrows.items() if name.startswith("auv-"))
    tracking = auv.tracking
    speed_budget = 1.0 / math.sqrt(tracking.velocity_weight)  # Bryson: weight = 1/acceptable²
    vehicle_model = auv.plant
    thrust = utilisation_budget(
        vehicle_model.vehicle_model(),
        vehicle_model.allocator(),
        acceleration=tracking.max_acceleration,
        speed=speed_budget,
        angular_rate=VEHICLE_ANGULAR_RATE,
        rate_step=VEHICLE_ANGULAR_RATE,
        tilt=math.pi / 2,
        attitude_bandwidth=vehicle_model.attitude_bandwidth,
        attitude_damping_ratio=vehicle_model.attitude_damping_ratio,
    )["total"]
    sweep = float(np.linalg.norm(rows["kf-alg2"].scenario.tracking.desired_relative_position))
    paper = rows["kf-alg2"].scenario
    scale = auv.target.acceleration_covariance[0][0] / paper.target.acceleration_covariance[0][0]
    v0 = np.asarray(paper.target.initial_velocity)
    paper_speed = math.sqrt(
        v0 @ v0
        + (paper.steps - 1) * paper.time_step**2 * np.trace(paper.target.acceleration_covariance)
    )
    loop = " ".join(f"`--set {shlex.quote(o)}`" for o in VEHICLE_LOOP)
    main_command = f"drake-uuv compare --group attitude --runs {runs}"
    vehicle_command = f"drake-uuv compare --group attitude_vehicle --runs {runs}"

    return f"""
## Attitude that seeks observability

The paper closes by promising an attitude that "adaptively adjusts to maximize
observability"; its Algorithms 1 and 2 turn the sonar baseline blindly. The
information-seeking planner (`attitude: !InformationSeeking {{max_angle_per_step: B}}`) does
what the promise says: each step it scores candidate attitudes within a rotation budget of B
rad (the angle of R(k+1) R(k)ᵀ) by the posterior covariance the next measurement would
leave the filter, and turns to the best. The score is A-optimal on position (−trace P_qq after
the update, the squared position RMSE a consistent filter predicts), one step ahead. For the
paper's KF it scores the range difference Y (information q_s q_sᵀ / Γ, so only the baseline
direction matters); for the EKF the two raw ranges, and since the tracking law holds the target
at R q*, whole attitudes (the line of sight turns with the body).

**Persistent excitation.** The KF is observable only while the excitation Gramian
Λ(k) = Σ q_s q_sᵀ over the last {window} steps (paper eq. 10) stays positive definite. A greedy
planner does not keep it so: it measures where the filter is most uncertain, and a direction it
has just measured drops in priority until its variance has grown back, which can take longer
than a window; with a small budget the baseline cannot come back in time. So the planner keeps a
floor of {floor:g} m² on the smallest eigenvalue of Λ over every window: a candidate is
admissible only if the trailing window ending with it meets the floor a few steps early, and
when none is, it turns toward the least excited direction.

**A fair comparison.** Algorithm 2 moves a lot (its mean rotation per step is in the tables),
so a planner that turns less but better has to be compared at equal motion: Algorithm 2 is
rate-limited to the same budget (`attitude.max_angular_rate = B / t`, t = {t:g} s, so no step
turns more than B) and the planner gets `max_angle_per_step = B`, for B in
{", ".join(f"{b:g}" for b in ATTITUDE_BUDGETS)} rad. Every variant runs the same {runs} seeds
(`{main_command}`); runs are paired by seed and compared by a paired bootstrap of the pooled
RMSE (`studies/paired.py`; a seed is left out of a pair when the
estimator-health monitor stopped either run). Brackets are 95 % intervals; RMSEs over k ≥ 200;
"min λ(Λ₂₄)" is the smallest over every window of every run; "diverged": final position error
above 10 m.

{tables[0]}
{tables[1]}
{motion_note}
{same_note}
Position RMSE against the rotation per step each variant actually used (the budget labels the
points; the star is Algorithm 2 unlimited):

![attitude: RMSE against rotation](figures/{figure.name})

Paired comparisons (the ratio is candidate / baseline of the pooled position RMSE):

{pairs[0]}
{pairs[1]}
### Acceptance

{verdicts[0]}
{verdicts[1]}
### On the hovering UUV

The same comparison on the 8-thruster vehicle (`--set plant=HoveringAuv`) at one budget, taken
from the rate the vehicle follows without saturating: {VEHICLE_ANGULAR_RATE:g} rad/s, i.e.
{vbudget:g} rad per step (Algorithm 2 with `attitude.max_angular_rate={VEHICLE_ANGULAR_RATE:g}`
against the planner with `max_angle_per_step: {vbudget:g}`), paper's KF, {vehicle_runs} runs
each, and for reference the same loop on the kinematic plant ({runs} runs;
`{vehicle_command}`). The loop is one the vehicle can fly: {loop}. The LQR law's limit of
{tracking.max_acceleration:g} m/s² and Bryson weights for {speed_budget:.2f} m/s of speed error
(half the vehicle's 0.76 m/s top speed) and {tracking.max_acceleration:g} m/s² keep the
commands within its thrust: with {VEHICLE_ANGULAR_RATE:g} rad/s, rate steps of as much, any
tilt and speeds up to {speed_budget:.2f} m/s, the worst-direction thrust budget
(`drake_uuv.models.vehicle_limits.utilisation_budget`) is {thrust:.0%} used. q* is fixed in
the world because a q* in the body (or the heading) turns with the attitude and asks
|q*| ω = {sweep * VEHICLE_ANGULAR_RATE:.2f} m/s of speed at {VEHICLE_ANGULAR_RATE:g} rad/s,
beyond the top speed before the target's drift is added; in the world frame the attitude turns
without moving the vehicle. The target is slowed to one the vehicle can follow: the paper's
target's velocity is a random walk whose RMS reaches {paper_speed:.2f} m/s at the last step,
more than the vehicle's top speed, and a vehicle that falls behind leaves a filter that trusts
its commanded acceleration behind too; here its W is scaled by {scale:.3g} (in the target and
in the filter), so that the RMS speed at the last step is {VEHICLE_SPEED_BUDGET:g} m/s.
"thrust saturated": the share of the 50 Hz ticks whose wrench the allocation scaled down;
"attitude error": |Log(R_cmd R_WBᵀ)| at the outer ticks (both means over runs of the
steady-state window).

{_table([vrows[n] for n in vnames], vehicle=True)}
{PAIR_HEADER}{chr(10).join(vpairs)}

On the vehicle the planner's position RMSE is {auv_result["candidate"]:.3f} m against
Algorithm 2's {auv_result["baseline"]:.3f} m at the same {vbudget:g} rad per step (ratio
{auv_result["ratio"]:.3f} [{alo:.3f}, {ahi:.3f}], {auv_result["runs"]} paired seeds).
"""
