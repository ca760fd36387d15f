"""Comparison tables: Monte Carlo studies of named scenario variants, side by side.

A :class:`Variant` is a name and a list of ``--set`` overrides applied on top of the base
scenario; variants come in named groups (:data:`VARIANT_GROUPS`), each a function returning
its variants. ``drake-uuv compare`` runs every variant of the chosen groups as one Monte Carlo
batch (one process pool or Dask cluster for all) and writes ``DIR/compare.md`` (one table per
group) and ``DIR/compare.csv`` (one row per variant), with each variant's study in
``DIR/studies/<variant>/``. The ``estimator`` group (every estimator variant × attitude
variant) adds the ratio tables RMSE / PCRLB (:func:`ratio_tables`) to ``compare.md``, and every
row of ``compare.csv`` carries the bounds and ratios of its summary.

Groups that span a slot's variants (the estimators, the attitude generators) take them from
the scenario's variant types, so a new variant joins them without an edit here. To add rows
of another kind, add a group::

    VARIANT_GROUPS["standoff"] = lambda: [
        Variant("far", "standoff", ("tracking.desired_relative_position=[-20, -20, 0]",)),
        ...
    ]

or pass any list of variants to :func:`compare`. (The module is ``comparison``, not
``compare``, so that the :func:`compare` re-exported by :mod:`drake_uuv.studies` does not
shadow it: ``import drake_uuv.studies.compare as m`` would otherwise yield the function.)
"""

import csv
import io
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from drake_uuv.io import write_text_atomic
from drake_uuv.models.vehicle_envelope import (
    FeasibleLimits,
    feasible_limits,
    followable_target_scale,
    plan_max_tilt,
)
from drake_uuv.scenario import (
    ALPHA_PROVEN_INTERVAL,
    NOISE_MODELS,
    Scenario,
    load_scenario,
    variants,
)
from drake_uuv.studies.execution import run_studies
from drake_uuv.studies.study import MonteCarloError, Study, StudyResult


@dataclass(frozen=True)
class Variant:
    """A named row of a comparison: ``--set`` overrides on top of the base scenario."""

    name: str
    group: str
    overrides: tuple[str, ...]
    # Shown in the Markdown table's "note" column (e.g. whether α is in the proven interval).
    note: str = ""


# Short names of variants in row names ("kf-trajectory"); others use their tag in snake case.
SHORT_NAMES = {
    "PaperKf": "kf", "Ekf": "ekf", "Iekf": "iekf",
    "TrajectoryAttitude": "trajectory", "RandomAttitude": "random", "FixedAttitude": "fixed",
    "PaperTracking": "paper", "LqrTracking": "lqr",
}  # fmt: skip


def short_name(tag: str) -> str:
    """A variant's name in row names: :data:`SHORT_NAMES`, or its tag in snake case."""
    return SHORT_NAMES.get(tag) or re.sub(r"(?<=[a-z0-9])(?=[A-Z])", "_", tag).lower()


def slot_variants(slot: str) -> dict[str, str]:
    """A slot's variants as ``{short name: --set override}``, in the scenario's order."""
    return {short_name(tag): f"{slot}=!{tag}" for tag in variants(Scenario, slot)}


# The paper's attitude generators, in the order its claims discuss them.
PAPER_ATTITUDES = {"fixed": "attitude=!FixedAttitude", "random": "attitude=!RandomAttitude",
                   "trajectory": "attitude=!TrajectoryAttitude"}  # fmt: skip


def attitude_noise_variants() -> list[Variant]:
    """The paper's attitude generators × noise model (its claims on excitation and on Γ)."""
    return [
        Variant(
            f"{mode}-{noise}",
            "attitude × noise model",
            (attitude, f"estimator.noise_model={noise}"),
        )
        for mode, attitude in PAPER_ATTITUDES.items()
        for noise in NOISE_MODELS
    ]


# Across and beyond the proven interval (1 − 1/√2, 1 + 1/√2) ≈ (0.293, 1.707); with a perfect
# estimate the tracking error obeys e(k+1) = (1 − α) e(k) + …, bounded for 0 < α < 2.
ALPHAS = (0.05, 0.2, 0.29, 0.5, 1.0, 1.2, 1.5, 1.71, 1.9, 1.98, 2.02, 2.2)


def alpha_sweep_variants(alphas: Sequence[float] = ALPHAS) -> list[Variant]:
    """The tracking gain α across and beyond the interval where the paper proves boundedness."""
    return [
        Variant(
            f"alpha-{alpha:g}",
            "tracking gain α",
            (f"tracking.alpha={alpha!r}", "tracking.allow_unproven_alpha=true"),
            "proven" if ALPHA_PROVEN_INTERVAL[0] < alpha < ALPHA_PROVEN_INTERVAL[1] else "unproven",
        )
        for alpha in alphas
    ]


ESTIMATOR_GROUP = "estimator × attitude mode"


def estimator_attitude_variants() -> list[Variant]:
    """Every estimator × the paper's attitude generators, for the RMSE / PCRLB table
    (:func:`ratio_tables`)."""
    return [
        Variant(f"{estimator}-{mode}", ESTIMATOR_GROUP, (override, attitude))
        for estimator, override in slot_variants("estimator").items()
        for mode, attitude in PAPER_ATTITUDES.items()
    ]


def tracking_law_variants() -> list[Variant]:
    """The paper's law and the LQR law, with and without a 7 m/s² acceleration limit (what a
    ~31 kg hovering vehicle with 77.6 N thrusters manages), under Algorithms 2 and 1."""
    return [
        Variant(
            f"{mode}-{law}{tag}",
            "tracking law × attitude mode",
            (PAPER_ATTITUDES[mode], f"tracking=!{tracking}", *extra),
        )
        for mode in ("trajectory", "random")
        for law, tracking in (("paper", "PaperTracking"), ("lqr", "LqrTracking"))
        for tag, extra in (("", ()), ("-limit7", ("tracking.max_acceleration=7",)))
    ]


# [rad/s] The hovering UUV's angular rate that never saturates its thrusters with the loop
# below: drake_uuv.models.vehicle_limits.utilisation_budget of 0.3 rad/s (and steps of it),
# 0.6 m/s², any tilt and speeds up to 0.38 m/s uses at most 0.84 of the worst thruster's
# thrust (1.0 rad/s works in practice, with a few ticks saturated, but is not guaranteed).
VEHICLE_ANGULAR_RATE = 0.3
# [m/s] The speed the loop plans for: half the vehicle's 0.76 m/s top speed.
VEHICLE_SPEED_BUDGET = 0.38
# A loop the vehicle can fly (top speed 0.76 m/s, 3.33 m/s² in its worst direction): the LQR
# law limited to 0.6 m/s², Bryson weights for 0.38 m/s of speed error (1/0.38² ≈ 6.918) and
# 0.6 m/s² (1/0.6² ≈ 2.778), and q* fixed in the world. A q* in the body or the heading turns
# with the attitude and asks |q*| ω of speed, 0.85 m/s at 0.3 rad/s for the paper's
# |q*| = 2.83 m, beyond the top speed before the target's own drift is added.
VEHICLE_LOOP = (
    "tracking=!LqrTracking",
    "tracking.reference_frame=world",
    "tracking.max_acceleration=0.6",
    "tracking.velocity_weight=6.918",
    "tracking.input_weight=2.778",
)


def vehicle_variants() -> list[Variant]:
    """The paper's closed loop and a configuration the vehicle can fly, each on the paper's
    kinematic plant and on the 8-thruster hovering UUV (``!HoveringAuv``), with the filter's
    two ways of accounting for the vehicle's own motion.

    - ``paper-*``: Algorithm 2 and the paper's tracking law, q* fixed in the body.
    - ``feasible-*``: the LQR law with q* fixed in the world, the rate limit, acceleration
      limit and Bryson weights that :func:`drake_uuv.models.vehicle_envelope.feasible_limits`
      derives for the default vehicle and Algorithm 2 (the tests check that they agree).
    - ``hull-*``: the feasible configuration with a sonar baseline that fits the hull,
      |b| = 0.49 m instead of the paper's 1.41 m (sonars as if on booms).
    - ``slow-*``: the feasible configuration and a target the vehicle can follow: the paper's
      W scaled by 0.166 (:func:`~drake_uuv.models.vehicle_envelope.followable_target_scale`,
      three digits), so that the target's RMS speed at the last step is the envelope's speed
      budget (0.38 m/s) instead of 0.88 m/s. It separates the target's speed from the filter:
      with a target the vehicle keeps up with, the vehicle follows its commands and even the
      commanded prediction holds.
    - ``*-vehicle``: the filter predicts with the commanded acceleration ``R u1``
      (``estimator.vehicle_motion=commanded``, the paper's), which the vehicle follows only
      as far as its thrusters allow.
    - ``*-inflated``: the same, with the filter's process noise inflated by what the vehicle
      does not follow of its commanded acceleration, ``estimator.added_acceleration_variance
      = model_acceleration_rmse² / 3`` with the RMS over the 30 runs (seeds 0–29) of the same
      configuration on the vehicle without inflation. The paper's configuration gets none:
      its commands are a hundred times what the thrusters deliver.
    - ``*-navigation``: the filter predicts the target and takes the vehicle's state from its
      navigation (``estimator.vehicle_motion=navigation``; the paper assumes the vehicle's
      state known), exact whatever the vehicle did of its commands. On the kinematic plant it
      gives the same estimates as the commanded prediction, so the ``*-kinematic`` rows serve
      as the reference of both.
    """
    group = "vehicle: paper and feasible configuration, kinematic plant and hovering UUV"
    paper = ("tracking=!PaperTracking", "attitude=!TrajectoryAttitude")
    feasible = (
        *VEHICLE_LOOP,
        "attitude=!TrajectoryAttitude",
        f"attitude.max_angular_rate={VEHICLE_ANGULAR_RATE}",
    )
    hull = (*feasible, "sonar.baseline=[-0.35, 0.35, 0]")
    scale, slowed = followable_target(load_scenario("paper"))
    slow = (*feasible, slowed)
    vehicle = "plant=!HoveringAuv"
    navigation = "estimator.vehicle_motion=navigation"
    # model_acceleration_rmse² / 3 [m²/s⁴] (see above): RMS 0.2530 m/s² over feasible-vehicle's
    # runs, 0.2780 m/s² over hull-vehicle's (drake-uuv compare --group vehicle --runs 30).
    inflation = {"feasible": 0.02133, "hull": 0.02577}
    rows = [
        Variant("paper-kinematic", group, paper, "paper"),
        Variant("paper-vehicle", group, (*paper, vehicle), "paper"),
        Variant("paper-vehicle-navigation", group, (*paper, vehicle, navigation), "paper, nav."),
    ]
    for name, overrides in (("feasible", feasible), ("hull", hull)):
        rows += [
            Variant(f"{name}-kinematic", group, overrides, name),
            Variant(f"{name}-vehicle", group, (*overrides, vehicle), name),
            Variant(
                f"{name}-vehicle-inflated",
                group,
                (
                    *overrides,
                    vehicle,
                    f"estimator.added_acceleration_variance={inflation[name]:.4g}",
                ),
                f"{name}, σ² = {inflation[name]:.3g} m²/s⁴",
            ),
            Variant(
                f"{name}-vehicle-navigation",
                group,
                (*overrides, vehicle, navigation),
                f"{name}, nav.",
            ),
        ]
    rows += [
        Variant("slow-kinematic", group, slow, f"feasible, W × {scale:g}"),
        Variant("slow-vehicle", group, (*slow, vehicle), f"feasible, W × {scale:g}"),
        Variant(
            "slow-vehicle-navigation",
            group,
            (*slow, vehicle, navigation),
            f"feasible, W × {scale:g}, nav.",
        ),
    ]
    return rows


REGIMES_GROUP = "regimes: range noise and standoff × estimator"
# The regimes of the estimators' study: name → (note, --set overrides). σ at the paper's
# standoff (q* = [−2, −2, 0] in the body frame, |q*| ≈ 2.8 m); standoff at σ = 0.1 m with q*
# fixed in the world frame (in the body frame it spins with Algorithm 2's turning).
REGIMES: dict[str, tuple[str, tuple[str, ...]]] = {
    "paper": ("σ = 0.1 m, paper (2.8 m body)", ("sonar.noise_variances=[0.01, 0.01]",)),
    "sigma0.5": ("σ = 0.5 m, paper standoff", ("sonar.noise_variances=[0.25, 0.25]",)),
    "sigma1": ("σ = 1 m, paper standoff", ("sonar.noise_variances=[1.0, 1.0]",)),
    **{
        f"world{name}": (
            f"σ = 0.1 m, {name} m world",
            (
                "sonar.noise_variances=[0.01, 0.01]",
                "tracking.reference_frame=world",
                f"tracking.desired_relative_position=[{side}, {side}, 0.0]",
            ),
        )
        for name, side in (("2.8", -2.0), ("14", -10.0), ("28", -20.0))
    },
}
# The estimators of the regime study: the paper's KF, the raw-range EKF, UKF and particle
# filter (each handing over from the KF by the default rule), and the particle filter with
# four times its default count as the large-count reference (the empirical optimum).
REGIME_ESTIMATORS = {
    "kf": "estimator=!PaperKf",
    "ekf": "estimator=!Ekf",
    "ukf": "estimator=!Ukf",
    "pf": "estimator=!ParticleFilter",
    "pf20000": "estimator=!ParticleFilter {particle_count: 20000}",
}


def regime_variants() -> list[Variant]:
    """Every regime of :data:`REGIMES` × :data:`REGIME_ESTIMATORS`, named
    ``<regime>-<estimator>`` (``sigma0.5-pf``, ``world28-pf20000``)."""
    return [
        Variant(f"{regime}-{estimator}", REGIMES_GROUP, (*overrides, override), note)
        for regime, (note, overrides) in REGIMES.items()
        for estimator, override in REGIME_ESTIMATORS.items()
    ]


# Rotation budgets [rad per step] of the attitude group: a quarter and a half of Algorithm 2's
# mean rotation per step in the paper scenario (0.381 rad), and about all of it.
ATTITUDE_BUDGETS = (0.1, 0.2, 0.39)
ATTITUDE_GROUP = "attitude: Algorithm 2 against the information-seeking planner, equal rotation"


def attitude_budget_variants(budgets: Sequence[float] = ATTITUDE_BUDGETS) -> list[Variant]:
    """Algorithm 2 unlimited, then for each budget B [rad per step] Algorithm 2 rate-limited to
    B (``attitude.max_angular_rate = B / t``, so no step turns more than B) and the
    information-seeking planner with ``max_angle_per_step = B``: under the paper's KF and the
    raw-range EKF. Same seeds for all, so the rows pair run by run.

    ``t`` is the paper scenario's ``time_step`` (0.5 s); a base override of the time step
    would change the rate-limited rows' budget, not the planner's.
    """
    t = load_scenario("paper").time_step
    rows = []
    for estimator in ("PaperKf", "Ekf"):
        name, chosen = short_name(estimator), f"estimator=!{estimator}"
        rows.append(
            Variant(
                f"{name}-alg2",
                ATTITUDE_GROUP,
                (chosen, "attitude=!TrajectoryAttitude"),
                "unlimited",
            )
        )
        for budget in budgets:
            note = f"{budget:g} rad/step"
            rows += [
                Variant(
                    f"{name}-alg2-{budget:g}",
                    ATTITUDE_GROUP,
                    (
                        chosen,
                        "attitude=!TrajectoryAttitude",
                        f"attitude.max_angular_rate={budget / t!r}",
                    ),
                    note,
                ),
                Variant(
                    f"{name}-info-{budget:g}",
                    ATTITUDE_GROUP,
                    (chosen, f"attitude=!InformationSeeking {{max_angle_per_step: {budget!r}}}"),
                    note,
                ),
            ]
    return rows


ATTITUDE_VEHICLE_GROUP = "attitude on the hovering UUV: equal rotation within its rate limit"


def followable_target(paper: Scenario) -> tuple[float, str]:
    """The factor on the paper's W that a vehicle can follow, and its ``--set`` override.

    :func:`~drake_uuv.models.vehicle_envelope.followable_target_scale` for an RMS speed of
    :data:`VEHICLE_SPEED_BUDGET` at the last step, rounded to three digits (0.166 for the
    paper scenario), and ``target.acceleration_covariance`` scaled by it (six digits).
    """
    v0, W0 = paper.target.initial_velocity, np.asarray(paper.target.acceleration_covariance)
    scale = followable_target_scale(v0, W0, paper.time_step, paper.steps, VEHICLE_SPEED_BUDGET)
    scale = float(f"{scale:.3g}")
    W = [[float(f"{w:.6g}") for w in row] for row in (scale * W0).tolist()]
    return scale, f"target.acceleration_covariance={W}"


def scenario_plan_max_tilt(scenario: Scenario) -> float:
    """The worst tilt [rad] of Algorithm 2's plan over a scenario's run
    (:func:`~drake_uuv.models.vehicle_envelope.plan_max_tilt`)."""
    attitude = scenario.attitude
    return plan_max_tilt(
        np.asarray(scenario.sonar.baseline),
        attitude.rho,
        attitude.h_amplitude,
        attitude.h_frequency,
        scenario.steps,
    )


def scenario_feasible_limits(scenario: Scenario) -> FeasibleLimits:
    """:func:`~drake_uuv.models.vehicle_envelope.feasible_limits` for a ``!HoveringAuv``
    scenario with Algorithm 2: its vehicle, its attitude loop and
    :func:`scenario_plan_max_tilt`."""
    vehicle = scenario.plant
    return feasible_limits(
        vehicle.vehicle_model(),
        vehicle.allocator(),
        attitude_bandwidth=vehicle.attitude_bandwidth,
        attitude_damping_ratio=vehicle.attitude_damping_ratio,
        time_step=scenario.time_step,
        rho=scenario.attitude.rho,
        max_tilt=scenario_plan_max_tilt(scenario),
    )


def attitude_vehicle_variants() -> list[Variant]:
    """Algorithm 2 rate-limited to :data:`VEHICLE_ANGULAR_RATE` against the planner with the
    same rotation per step (``rate · t``), under the paper's KF and :data:`VEHICLE_LOOP`, on
    the 8-thruster hovering UUV (``!HoveringAuv``) and, for reference, the paper's kinematic
    plant, with the paper's target slowed to one the vehicle can follow: W scaled by
    :func:`~drake_uuv.models.vehicle_envelope.followable_target_scale` for an RMS speed of
    :data:`VEHICLE_SPEED_BUDGET` at the last step (three digits), both in the target and in
    the filter.
    ``t`` and W are the paper scenario's (0.5 s)."""
    paper = load_scenario("paper")
    t = paper.time_step
    budget = VEHICLE_ANGULAR_RATE * t
    note = f"{budget:g} rad/step"
    scale, target = followable_target(paper)
    attitudes = {
        "alg2": ("attitude=!TrajectoryAttitude", f"attitude.max_angular_rate={budget / t!r}"),
        "info": (f"attitude=!InformationSeeking {{max_angle_per_step: {budget!r}}}",),
    }
    return [
        Variant(
            f"{plant}-{kind}-{budget:g}",
            ATTITUDE_VEHICLE_GROUP,
            ("estimator=!PaperKf", *VEHICLE_LOOP, target, *chosen, *extra),
            f"{note}, W × {scale:g}",
        )
        for plant, extra in (("kinematic", ()), ("auv", ("plant=!HoveringAuv",)))
        for kind, chosen in attitudes.items()
    ]


# Group name → its variants. Other features add groups here.
VARIANT_GROUPS: dict[str, Callable[[], list[Variant]]] = {
    "attitude_noise": attitude_noise_variants,
    "alpha": alpha_sweep_variants,
    "estimator": estimator_attitude_variants,
    "tracking": tracking_law_variants,
    "vehicle": vehicle_variants,
    "regimes": regime_variants,
    "attitude": attitude_budget_variants,
    "attitude_vehicle": attitude_vehicle_variants,
}

# Columns of the tables: (CSV name, Markdown header, summary key, format).
_COLUMNS: list[tuple[str, str, str, str]] = [
    ("position_rmse", "position RMSE [m]", "position_rmse", ".3g"),
    ("velocity_rmse", "velocity RMSE [m/s]", "velocity_rmse", ".3g"),
    ("tracking_rmse", "tracking RMSE [m]", "tracking_rmse", ".3g"),
    ("nees_mean", "mean NEES (6)", "nees_mean", ".3g"),
    ("diverged_fraction", "diverged", "diverged_fraction", ".0%"),
    ("tracking_bounded_fraction", "tracking bounded", "tracking_bounded_fraction", ".0%"),
    ("relative_speed_mean", "mean relative speed [m/s]", "relative_speed_mean", ".3g"),
    ("relative_speed_peak", "peak relative speed [m/s]", "relative_speed_peak", ".3g"),
    ("acceleration_mean", "mean acceleration [m/s²]", "acceleration_mean", ".3g"),
    ("acceleration_peak", "peak acceleration [m/s²]", "acceleration_peak", ".3g"),
]


def _slug(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "_", name)


def _number(value: float | None, fmt: str) -> str:
    return "—" if value is None else format(value, fmt)


def _cell(summary: dict[str, Any], key: str, fmt: str) -> str:
    text = _number(summary.get(key), fmt)
    interval = summary.get(f"{key}_ci95")
    if interval is not None and key.endswith(("rmse", "nees_mean")):
        text += f" [{_number(interval[0], fmt)}, {_number(interval[1], fmt)}]"
    return text


def markdown_table(rows: Sequence[tuple[Variant, dict[str, Any]]]) -> str:
    """One Markdown table per group: variant, overrides, runs, then :data:`_COLUMNS`."""
    out: list[str] = []
    groups = list(dict.fromkeys(variant.group for variant, _ in rows))
    for group in groups:
        out.append(f"### {group}\n")
        members = [(variant, summary) for variant, summary in rows if variant.group == group]
        notes = any(variant.note for variant, _ in members)
        headers = ["variant", *(["note"] if notes else []), "runs"]
        headers += [header for _, header, _, _ in _COLUMNS]
        out.append("| " + " | ".join(headers) + " |")
        aligns = ["---"] * (2 if notes else 1) + ["---:"] * (len(headers) - (2 if notes else 1))
        out.append("|" + "|".join(aligns) + "|")
        for variant, summary in members:
            cells = [variant.name, *([variant.note] if notes else []), str(summary["runs"])]
            cells += [_cell(summary, key, fmt) for _, _, key, fmt in _COLUMNS]
            out.append("| " + " | ".join(cells) + " |")
        out.append("")
    return "\n".join(out)


# The bound columns of the CSV (summary keys, see drake_uuv.studies.statistics.summarize).
_BOUND_COLUMNS = [
    "pcrlb_position_rmse",
    "pcrlb_velocity_rmse",
    "pcrlb_per_run_position_rmse",
    "pcrlb_per_run_velocity_rmse",
    "kf_riccati_position_rmse",
    "kf_riccati_velocity_rmse",
    "position_rmse_over_pcrlb",
    "velocity_rmse_over_pcrlb",
    "position_rmse_over_per_run_pcrlb",
    "velocity_rmse_over_per_run_pcrlb",
]


def _settings(variant: Variant) -> dict[str, str]:
    return dict(override.split("=", 1) for override in variant.overrides)


def ratio_tables(rows: Sequence[tuple[Variant, dict[str, Any]]]) -> str:
    """Markdown: estimator × attitude mode → RMSE / PCRLB, position and velocity.

    Two tables from the rows of the ``estimator`` group (empty string if there are none):
    against the Monte Carlo PCRLB (the proven bound) and against the mean of the per-run
    bounds (what a run-by-run efficient estimator attains; see
    :mod:`drake_uuv.models.pcrlb`). Each cell is ``position / velocity``.
    """
    cells: dict[tuple[str, str], dict[str, Any]] = {}
    for variant, summary in rows:
        if variant.group == ESTIMATOR_GROUP:
            settings = _settings(variant)
            estimator = short_name(settings["estimator"].removeprefix("!"))
            cells[estimator, short_name(settings["attitude"].removeprefix("!"))] = summary
    if not cells:
        return ""
    estimators = list(dict.fromkeys(estimator for estimator, _ in cells))
    modes = list(dict.fromkeys(mode for _, mode in cells))
    out = []
    for suffix, title in (
        ("pcrlb", "RMSE / PCRLB (Monte Carlo bound: information averaged over runs)"),
        ("per_run_pcrlb", "RMSE / mean of per-run bounds (each along its own trajectory)"),
    ):
        out.append(f"### {title}, position / velocity\n")
        out.append("| estimator | " + " | ".join(modes) + " |")
        out.append("|---|" + "|".join("---:" for _ in modes) + "|")
        for estimator in estimators:
            row = [estimator]
            for mode in modes:
                summary = cells.get((estimator, mode), {})
                row.append(
                    f"{_number(summary.get(f'position_rmse_over_{suffix}'), '.3g')} / "
                    f"{_number(summary.get(f'velocity_rmse_over_{suffix}'), '.3g')}"
                )
            out.append("| " + " | ".join(row) + " |")
        out.append("")
    return "\n".join(out)


def csv_table(rows: Sequence[tuple[Variant, dict[str, Any]]]) -> str:
    """One CSV row per variant with every number of its summary and the 95 % bounds."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    names = [name for name, _, _, _ in _COLUMNS]
    header = ["group", "variant", "note", "overrides", "runs"]
    for name in names:
        header.append(name)
        if name.endswith(("rmse", "nees_mean", "fraction")):
            header += [f"{name}_ci95_low", f"{name}_ci95_high"]
    header += _BOUND_COLUMNS
    writer.writerow(header)
    for variant, summary in rows:
        row: list[Any] = [variant.group, variant.name, variant.note, " ".join(variant.overrides)]
        row.append(summary["runs"])
        for name in names:
            row.append(summary.get(name))
            if name.endswith(("rmse", "nees_mean", "fraction")):
                row += list(summary.get(f"{name}_ci95", [None, None]))
        row += [summary.get(name) for name in _BOUND_COLUMNS]
        writer.writerow(["" if v is None else v for v in row])
    return buffer.getvalue()


def compare(
    variants: Sequence[Variant],
    out_dir: Path,
    runs: int,
    scenario: str = "paper",
    base_overrides: Sequence[str] = (),
    seed: int | None = None,
    **execution: Any,
) -> list[tuple[Variant, StudyResult]]:
    """Runs every variant's study; writes ``compare.md`` and ``compare.csv`` in ``out_dir``.

    ``execution``: keywords of :func:`drake_uuv.studies.execution.run_studies` (workers, scheduler,
    resume, progress).
    """
    out_dir = Path(out_dir)
    studies = [
        Study(
            variant.name,
            load_scenario(scenario, [*base_overrides, *variant.overrides], seed=seed),
            runs,
            out_dir / "studies" / _slug(variant.name),
        )
        for variant in variants
    ]
    execution.setdefault("figures", False)
    results = run_studies(studies, **execution)
    rows = [(variant, result.summary) for variant, result in zip(variants, results, strict=True)]
    low, high = ALPHA_PROVEN_INTERVAL
    command = f"drake-uuv compare --runs {runs}" + "".join(f" --set {o}" for o in base_overrides)
    groups = [name for name, make in VARIANT_GROUPS.items() if set(make()) <= set(variants)]
    if len(groups) < len(VARIANT_GROUPS):
        command += "".join(f" --group {name}" for name in groups)
    header = (
        f"# Comparison ({scenario} scenario, {runs} runs per variant)\n\n"
        f"Made by `{command}`. Metrics over the steady-state window; brackets are 95 % "
        "intervals (bootstrap over runs). *diverged*: final position error > 10 m; "
        "*tracking bounded*: steady-state tracking error stays < 10 m. The paper proves "
        f"bounded tracking for α in ({low:.4f}, {high:.4f}).\n\n"
    )
    ratios = ratio_tables(rows)
    if ratios:
        ratios = (
            "\n## Estimators against the posterior Cramér–Rao bound\n\n"
            "Steady-state RMSE over the bound's RMS (√ mean trace), position / velocity. "
            "The bound is for the raw two-range measurement with all f samples, evaluated on "
            "each variant's own true trajectories.\n\n" + ratios
        )
    write_text_atomic(out_dir / "compare.md", header + markdown_table(rows) + ratios)
    write_text_atomic(out_dir / "compare.csv", csv_table(rows))
    return list(zip(variants, results, strict=True))


def selected_variants(groups: Sequence[str] | None) -> list[Variant]:
    """The variants of the named groups (all groups if None)."""
    names = list(VARIANT_GROUPS) if not groups else list(groups)
    unknown = [name for name in names if name not in VARIANT_GROUPS]
    if unknown:
        raise MonteCarloError(
            f"--group: unknown group {unknown[0]!r} (known: {', '.join(VARIANT_GROUPS)})"
        )
    return [variant for name in names for variant in VARIANT_GROUPS[name]()]
