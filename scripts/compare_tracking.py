"""Paper vs LQR tracking law, Monte Carlo: writes docs/tracking_comparison.md.

Runs every variant of :data:`TRACKING_VARIANTS` (``--set`` overrides on the paper scenario)
with seeds 0..runs−1 — the same seeds for every variant, so the target's motion and the sonar
noise are identical between laws and the ratios are paired — and writes one Markdown page:
the table per attitude mode, the acceptance checks (paired ratios with 95 % bootstrap
intervals), the closed-loop eigenvalues and what the attitude plan itself demands.

    python scripts/compare_tracking.py [--runs 50] [--workers 2] [--out docs/tracking_comparison.md]

Exits with status 1 when an acceptance check fails.
"""

import argparse
import math
import os
import sys
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from drake_uuv.io import write_text_atomic
from drake_uuv.models.attitude_plans import trajectory_attitude
from drake_uuv.models.tracking_laws import closed_loop_eigenvalues, lqr_gain, paper_gain_matrix
from drake_uuv.scenario import Scenario, load_scenario

ACCELERATION_LIMIT = 7.0  # m/s²: a ~31 kg hovering vehicle with 77.6 N thrusters
_LIMIT = f"tracking.max_acceleration={ACCELERATION_LIMIT:g}"
_LIMITED = f"limit {ACCELERATION_LIMIT:g} m/s²"

# Variant name → overrides on the paper scenario. `drake-uuv compare` can take the same list.
TRACKING_VARIANTS: dict[str, tuple[str, ...]] = {
    "trajectory / paper": ("attitude=!TrajectoryAttitude", "tracking=!PaperTracking"),
    f"trajectory / paper, {_LIMITED}": (
        "attitude=!TrajectoryAttitude",
        "tracking=!PaperTracking",
        _LIMIT,
    ),
    "trajectory / lqr": ("attitude=!TrajectoryAttitude", "tracking=!LqrTracking"),
    f"trajectory / lqr, {_LIMITED}": (
        "attitude=!TrajectoryAttitude",
        "tracking=!LqrTracking",
        _LIMIT,
    ),
    "trajectory / lqr, no feed-forward": (
        "attitude=!TrajectoryAttitude",
        "tracking=!LqrTracking",
        "tracking.feedforward=false",
    ),
    "random / paper": ("attitude=!RandomAttitude", "tracking=!PaperTracking"),
    f"random / paper, {_LIMITED}": ("attitude=!RandomAttitude", "tracking=!PaperTracking", _LIMIT),
    "random / lqr": ("attitude=!RandomAttitude", "tracking=!LqrTracking"),
    f"random / lqr, {_LIMITED}": ("attitude=!RandomAttitude", "tracking=!LqrTracking", _LIMIT),
}

# Per-run numbers kept: run_metrics keys plus the fraction of steady-state steps at the limit.
_KEYS = (
    "tracking_rmse",
    "position_rmse",
    "velocity_rmse",
    "nees_mean",
    "relative_speed_mean",
    "relative_speed_peak",
    "acceleration_mean",
    "acceleration_peak",
    "saturated_fraction",
    "range_mean",
)


def run_variant(overrides: tuple[str, ...], seeds: Sequence[int]) -> np.ndarray:
    """Runs × :data:`_KEYS` for one variant (one diagram, one context per seed)."""
    from drake_uuv.simulation import ClosedLoopSimulation

    scenario = load_scenario("paper", overrides)
    simulation = ClosedLoopSimulation(scenario)
    limit = scenario.tracking.max_acceleration
    rows = []
    for seed in seeds:
        result = simulation.run(seed)
        applied = np.linalg.norm(result.log["u1_W"][scenario.steady_state_start :], axis=1)
        saturated = 0.0 if limit is None else float(np.mean(applied >= limit * (1 - 1e-12)))
        q = result.log["p_WU"] - result.log["p_WT"]
        range_mean = float(np.mean(np.linalg.norm(q[scenario.steady_state_start :], axis=1)))
        metrics = {**result.metrics, "saturated_fraction": saturated, "range_mean": range_mean}
        rows.append([metrics[key] for key in _KEYS])
    return np.asarray(rows)


def summarize(rows: np.ndarray) -> dict[str, float]:
    """RMSEs: √(mean of per-run MSE); means: mean over runs; peaks: largest over runs."""
    column = {key: rows[:, i] for i, key in enumerate(_KEYS)}
    out = {key: float(np.mean(value)) for key, value in column.items()}
    for key in ("tracking_rmse", "position_rmse", "velocity_rmse"):
        out[key] = math.sqrt(float(np.mean(column[key] ** 2)))
    for key in ("relative_speed_peak", "acceleration_peak"):
        out[key] = float(np.max(column[key]))
    return out


def paired_ratio(
    numerator: np.ndarray, denominator: np.ndarray, rms: bool, resamples: int = 4000
) -> tuple[float, float, float]:
    """Ratio of two variants' statistic over the same seeds, with a 95 % paired bootstrap."""

    def statistic(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        if rms:
            return np.sqrt(np.mean(a**2, axis=-1) / np.mean(b**2, axis=-1))
        return np.mean(a, axis=-1) / np.mean(b, axis=-1)

    rng = np.random.default_rng(0)
    index = rng.integers(0, len(numerator), size=(resamples, len(numerator)))
    low, high = np.percentile(statistic(numerator[index], denominator[index]), [2.5, 97.5])
    return float(statistic(numerator, denominator)), float(low), float(high)


def plan_demand(scenario: Scenario) -> dict[str, float]:
    """Speed and acceleration of the Algorithm 2 reference r(k) = R̄(k−1) q* itself.

    By first and second differences over the run's steps; also the largest attitude step.
    """
    s, a = scenario, scenario.attitude
    b = np.asarray(s.sonar.baseline)
    q_star = np.asarray(s.tracking.desired_relative_position)
    R = [trajectory_attitude(k, b, a.rho, a.h_amplitude, a.h_frequency) for k in range(s.steps)]
    r = np.array([Ri @ q_star for Ri in R])
    t = s.time_step
    speed = np.linalg.norm(np.diff(r, axis=0), axis=1) / t
    acceleration = np.linalg.norm(np.diff(r, 2, axis=0), axis=1) / t**2
    angle = [
        np.arccos(np.clip((np.trace(R[k + 1] @ R[k].T) - 1) / 2, -1, 1)) for k in range(s.steps - 1)
    ]
    return {
        "speed_mean": float(np.mean(speed)),
        "speed_peak": float(np.max(speed)),
        "acceleration_mean": float(np.mean(acceleration)),
        "acceleration_peak": float(np.max(acceleration)),
        "step_angle_peak": float(np.max(angle)),
    }


def speed_growth(mode: str, steps: int = 2000, block: int = 250) -> list[float]:
    """Mean relative speed of the paper's law per ``block`` steps of one long run (seed 0)."""
    from drake_uuv.simulation import ClosedLoopSimulation

    tags = {"trajectory": "TrajectoryAttitude", "random": "RandomAttitude"}
    scenario = load_scenario("paper", [f"attitude=!{tags[mode]}", f"steps={steps}"])
    log = ClosedLoopSimulation(scenario).run(0).log
    speed = np.linalg.norm(log["v_WU"] - log["v_WT"], axis=1)
    return [float(np.mean(speed[k : k + block])) for k in range(0, steps, block)]


def _eigenvalue_text(values: np.ndarray) -> str:
    distinct: list[complex] = []
    for value in values:
        if not any(abs(value - d) < 1e-9 for d in distinct):
            distinct.append(complex(value))
    parts = []
    for value in distinct:
        count = sum(abs(v - value) < 1e-9 for v in values)
        text = (
            f"{value.real:.4g}"
            if abs(value.imag) < 1e-12
            else f"{value.real:.4g} {'+' if value.imag > 0 else '−'} {abs(value.imag):.4g}j"
        )
        parts.append(f"{text} (×{count})")
    return ", ".join(parts)


def markdown(
    summaries: dict[str, dict[str, float]],
    rows: dict[str, np.ndarray],
    runs: int,
) -> tuple[str, bool]:
    """The page and whether every acceptance check passed."""
    paper = load_scenario("paper")
    lqr = load_scenario("paper", ["tracking=!LqrTracking"])
    t = lqr.tracking
    out = [
        "# Tracking laws compared: the paper's §III-B law and the LQR law",
        "",
        f"Made by `python scripts/compare_tracking.py --runs {runs}` ({runs} runs per variant, "
        f"seeds 0–{runs - 1}, the same seeds for every variant). Paper "
        f"scenario (t = {paper.time_step} s, {paper.steps} steps); every number is over the "
        f"steady-state window k ≥ {paper.steady_state_start}. LQR weights (the defaults): "
        f"position {t.position_weight:g}, velocity {t.velocity_weight:g}, input "
        f"{t.input_weight:g}; *{_LIMITED}* sets `tracking.max_acceleration: "
        f"{ACCELERATION_LIMIT:g}` (what a "
        "~31 kg hovering vehicle with 77.6 N thrusters manages).",
        "",
        "*tracking RMSE*: RMS of |q − R q*|; *estimation RMSE*: RMS of the filter's relative "
        "position (and velocity) error; both √(mean over runs of the per-run mean square). "
        "*speed*: true relative speed |v − v̄|; *acceleration*: the applied world acceleration "
        "|R u1|; *mean* is over steps and runs, *peak* the largest over all runs; *at limit*: "
        "share of steps with the acceleration at the limit; *mean range*: mean |q|, the "
        "UUV–target distance (|q*| = 2.83 m).",
        "",
    ]
    headers = [
        "law",
        "tracking RMSE [m]",
        "estimation RMSE [m]",
        "velocity est. RMSE [m/s]",
        "mean NEES",
        "speed mean / peak [m/s]",
        "acceleration mean / peak [m/s²]",
        "at limit",
        "mean range [m]",
    ]
    for mode, title in (("trajectory", "Algorithm 2 (trajectory)"), ("random", "Algorithm 1")):
        out += [f"## Attitude: {title}", ""]
        out.append("| " + " | ".join(headers) + " |")
        out.append("|---|" + "---:|" * (len(headers) - 1))
        for name, s in summaries.items():
            if not name.startswith(mode):
                continue
            at_limit = "—" if _LIMITED not in name else f"{s['saturated_fraction']:.0%}"
            out.append(
                f"| {name.split(' / ', 1)[1]} | {s['tracking_rmse']:.3f} | "
                f"{s['position_rmse']:.3f} | {s['velocity_rmse']:.3f} | {s['nees_mean']:.2f} | "
                f"{s['relative_speed_mean']:.3g} / {s['relative_speed_peak']:.3g} | "
                f"{s['acceleration_mean']:.3g} / {s['acceleration_peak']:.3g} | {at_limit} | "
                f"{s['range_mean']:.2f} |"
            )
        out.append("")

    out += [
        "## Acceptance (paper scenario = Algorithm 2)",
        "",
        "Ratios lqr / paper over the same seeds, with 95 % paired-bootstrap intervals.",
        "",
        "| lqr variant | tracking RMSE ≤ 1.1× | mean acceleration < 5 % | estimation RMSE ≤ 1.1× "
        "| pass |",
        "|---|---:|---:|---:|---|",
    ]
    index = {key: i for i, key in enumerate(_KEYS)}
    reference = rows["trajectory / paper"]
    passed_all = True
    for name in ("trajectory / lqr", f"trajectory / lqr, {_LIMITED}"):
        mine = rows[name]
        tracking = paired_ratio(
            mine[:, index["tracking_rmse"]], reference[:, index["tracking_rmse"]], True
        )
        acceleration = paired_ratio(
            mine[:, index["acceleration_mean"]], reference[:, index["acceleration_mean"]], False
        )
        estimation = paired_ratio(
            mine[:, index["position_rmse"]], reference[:, index["position_rmse"]], True
        )
        passed = tracking[0] <= 1.1 and acceleration[0] < 0.05 and estimation[0] <= 1.1
        passed_all &= passed
        cells = [
            f"{r[0]:.3f} [{r[1]:.3f}, {r[2]:.3f}]" for r in (tracking, acceleration, estimation)
        ]
        out.append(
            f"| {name.split(' / ', 1)[1]} | "
            + " | ".join(cells)
            + f" | {'yes' if passed else '**no**'} |"
        )
    out.append("")

    demand = plan_demand(paper)
    t_lqr = lqr.tracking
    K_lqr = lqr_gain(
        lqr.time_step, t_lqr.position_weight, t_lqr.velocity_weight, t_lqr.input_weight
    )
    damping = _damping(eig_lqr := closed_loop_eigenvalues(lqr.time_step, K_lqr[0]), paper.time_step)
    frequency = _natural_frequency(eig_lqr, paper.time_step)
    growth = {mode: speed_growth(mode) for mode in ("trajectory", "random")}
    eig_paper = closed_loop_eigenvalues(
        paper.time_step, paper_gain_matrix(paper.time_step, paper.tracking.alpha)
    )
    out += [
        "## Closed-loop eigenvalues",
        "",
        "Of A − BK on the relative double integrator (`closed_loop_eigenvalues(t, K)`; "
        "`tracking_spectral_radius` in metrics.json):",
        "",
        f"- paper law, α = {paper.tracking.alpha:g}: {_eigenvalue_text(eig_paper)} — spectral "
        f"radius {np.max(np.abs(eig_paper)):.4g}: the velocity mode −1 is never damped.",
        f"- lqr law: {_eigenvalue_text(eig_lqr)} — spectral radius "
        f"{np.max(np.abs(eig_lqr)):.4g}, i.e. per axis a damping ratio of {damping:.2f} at "
        f"{frequency:.2f} rad/s.",
        "",
        "## What the plan itself asks",
        "",
        f"Algorithm 2's reference r(k) = R̄(k−1) q* (finite differences over {paper.steps} "
        f"steps): speed mean {demand['speed_mean']:.2f} / peak {demand['speed_peak']:.2f} m/s, "
        f"acceleration mean {demand['acceleration_mean']:.2f} / peak "
        f"{demand['acceleration_peak']:.1f} m/s²; the minimal rotation whips through up to "
        f"{demand['step_angle_peak']:.2f} rad in one step where ζ passes close to −b. Near the "
        f"peak no {ACCELERATION_LIMIT:g} m/s² vehicle can stay on the reference, which is "
        "what the limited rows pay for.",
        "",
        "The paper's law asks two orders of magnitude more than the plan. Its velocity mode at "
        "−1 is driven resonantly by the plan's content at the Nyquist frequency (Algorithm 2) "
        "or by the random jumps (Algorithm 1), so its relative speed keeps growing and its "
        "steady-state numbers above depend on the run length. Mean relative speed [m/s] per "
        "250 steps of one 2000-step run (seed 0):",
        "",
        "| attitude | " + " | ".join(f"k {k}–{k + 249}" for k in range(0, 2000, 250)) + " |",
        "|---|" + "---:|" * 8,
        *(
            f"| {mode} | " + " | ".join(f"{v:.0f}" for v in values) + " |"
            for mode, values in growth.items()
        ),
        "",
        "## Notes",
        "",
        "- **Feed-forward.** The LQR law follows r(k) = R(k) q* with the reference state "
        "[r(k); ν(k)] and acceleration a_ff(k) of the constant-acceleration arc through r(k), "
        "r(k+1), r(k+2) from the attitude generator's plan: ν = (−3 r0 + 4 r1 − r2)/(2t), "
        "a_ff = (r0 − 2 r1 + r2)/t², a = a_ff − K (Υ̂ − [r; ν]). It lands exactly on r(k+1); "
        "the only residual is the velocity mismatch Δ³r(k)/(2t), zero for references quadratic "
        "in k. Algorithm 1 knows only R(k+1), so its plan holds R(k+2) = R(k+1). Without the "
        "feed-forward the law lags the turning reference (row *no feed-forward*).",
        "- **Limit without wind-up.** The law is static (no integrator, no filter state; the "
        "feed-forward is recomputed from the plan every step), so saturating |a| cannot wind "
        "anything up; the saturated acceleration is what the vehicle and the Kalman filter use.",
        "- **Estimation RMSE and the law.** The filter's accuracy depends on the vehicle's "
        "motion through the geometry and through the range: the noise variance of "
        "Y = ½(d1² − d2²) grows with d1² + d2². Under Algorithm 2 both laws keep the "
        "target near R q*, so the estimation RMSEs agree. Under Algorithm 1 the reference "
        "jumps to a random point of the 2.83 m sphere every step; a smooth vehicle cannot "
        "follow and hovers near the sphere's centre, the target (mean range above), so its "
        "estimate is better and its tracking RMSE is bounded by about |q*|.",
        "",
        "To add these rows to `drake-uuv compare`, each variant is the list of `--set` "
        "overrides in `TRACKING_VARIANTS` of `scripts/compare_tracking.py`.",
        "",
    ]
    return "\n".join(out), passed_all


def _continuous(eigenvalues: np.ndarray, time_step: float) -> complex:
    value = complex(eigenvalues[np.argmax(np.abs(eigenvalues.imag))])
    return complex(np.log(value)) / time_step


def _damping(eigenvalues: np.ndarray, time_step: float) -> float:
    s = _continuous(eigenvalues, time_step)
    return -s.real / abs(s)


def _natural_frequency(eigenvalues: np.ndarray, time_step: float) -> float:
    return abs(_continuous(eigenvalues, time_step))


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=50, help="runs per variant (default 50)")
    parser.add_argument(
        "--workers", type=int, default=min(2, os.cpu_count() or 1), help="processes"
    )
    parser.add_argument("--out", default="docs/tracking_comparison.md", help="Markdown output")
    args = parser.parse_args(argv)
    if args.runs < 2:
        parser.error(f"--runs: must be ≥ 2, got {args.runs}")
    seeds = list(range(args.runs))
    start = time.perf_counter()
    with ProcessPoolExecutor(max_workers=max(1, args.workers)) as pool:
        futures = {
            name: pool.submit(run_variant, overrides, seeds)
            for name, overrides in TRACKING_VARIANTS.items()
        }
        rows = {name: future.result() for name, future in futures.items()}
    summaries = {name: summarize(value) for name, value in rows.items()}
    page, passed = markdown(summaries, rows, args.runs)
    write_text_atomic(Path(args.out), page)
    print(page)
    print(f"-> {args.out} ({time.perf_counter() - start:.0f} s)")
    return 0 if passed else 1


if __name__ == "__main__":
    sys.exit(main())
