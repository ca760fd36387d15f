"""Comparison tables: variants and groups, the Markdown and CSV tables, the written files."""

import csv
import json
import math

import numpy as np
import pytest

from drake_uuv.diagram import make_uuv_diagram
from drake_uuv.models.vehicle_limits import utilisation_budget
from drake_uuv.scenario import (
    ALPHA_PROVEN_INTERVAL,
    Ekf,
    HoveringAuv,
    InformationSeeking,
    KinematicUuv,
    LqrTracking,
    PaperKf,
    Scenario,
    TrajectoryAttitude,
    load_scenario,
    variants,
)
from drake_uuv.simulation import ClosedLoopSimulation
from drake_uuv.studies import (
    ESTIMATOR_GROUP,
    VARIANT_GROUPS,
    MonteCarloError,
    StudyResult,
    Variant,
    alpha_sweep_variants,
    compare,
    csv_table,
    markdown_table,
    ratio_tables,
    selected_variants,
)
from drake_uuv.studies import comparison as comparison_module
from drake_uuv.studies.comparison import (
    VEHICLE_ANGULAR_RATE,
    VEHICLE_SPEED_BUDGET,
    attitude_vehicle_variants,
)
from tests.studies.study_helpers import SHORT


def _summary(runs: int = 4, **values) -> dict:
    summary = {"runs": runs, "position_rmse": 0.5, "position_rmse_ci95": [0.4, 0.6]}
    summary["diverged_fraction"] = 0.25
    summary["diverged_fraction_ci95"] = [0.05, 0.7]
    return {**summary, **values}


def test_selected_variants_are_the_groups_in_order_and_unknown_groups_are_refused():
    everything = selected_variants(None)
    assert everything == [v for make in VARIANT_GROUPS.values() for v in make()]
    assert selected_variants(["tracking", "alpha"]) == (
        VARIANT_GROUPS["tracking"]() + VARIANT_GROUPS["alpha"]()
    )
    with pytest.raises(MonteCarloError, match=r"^--group: unknown group 'bogus' \(known: "):
        selected_variants(["alpha", "bogus"])


def test_variant_names_are_unique_and_alphas_are_labelled_by_the_proven_interval():
    names = [variant.name for variant in selected_variants(None)]
    assert len(names) == len(set(names))
    low, high = ALPHA_PROVEN_INTERVAL
    for variant in alpha_sweep_variants([0.29, 0.3, 1.7, 1.71]):
        alpha = float(variant.name.removeprefix("alpha-"))
        assert variant.note == ("proven" if low < alpha < high else "unproven")
    estimator = VARIANT_GROUPS["estimator"]()
    # Every estimator variant the scenario knows, under each of the paper's three attitudes.
    assert len(estimator) == len(variants(Scenario, "estimator")) * 3
    assert {v.overrides[0] for v in estimator} == {
        f"estimator=!{tag}" for tag in variants(Scenario, "estimator")
    }


def test_markdown_table_one_table_per_group_with_notes_only_where_given():
    rows = [
        (Variant("a", "first", ("x=1",)), _summary()),
        (Variant("b", "second", ("x=2",), note="proven"), _summary(runs=3, position_rmse=None)),
    ]
    text = markdown_table(rows)
    assert text.count("### ") == 2
    first, second = text.split("### second")
    assert "| variant | runs | position RMSE [m] |" in first
    # Absent numbers are dashes; fractions are percentages, without intervals.
    assert "| a | 4 | 0.5 [0.4, 0.6] | — | — | — | 25% | — |" in first
    assert "| variant | note | runs |" in second
    assert "| b | proven | 3 | — [0.4, 0.6] |" in second


def test_csv_table_has_intervals_and_bounds_and_blank_for_missing():
    rows = [(Variant("a", "g", ("x=1", "y=2"), note="n"), _summary(pcrlb_position_rmse=0.1))]
    header, row = csv.DictReader(csv_table(rows).splitlines()), None
    row = next(header)
    assert row["group"] == "g" and row["overrides"] == "x=1 y=2" and row["note"] == "n"
    assert row["position_rmse"] == "0.5" and row["position_rmse_ci95_high"] == "0.6"
    assert row["diverged_fraction_ci95_low"] == "0.05"
    assert row["velocity_rmse"] == "" and row["pcrlb_position_rmse"] == "0.1"


def test_ratio_tables_place_each_estimator_and_mode():
    rows = [
        (
            Variant("kf-fixed", ESTIMATOR_GROUP, ("estimator=!PaperKf", "attitude=!FixedAttitude")),
            _summary(position_rmse_over_pcrlb=2.0, velocity_rmse_over_pcrlb=1.5),
        ),
        (
            Variant("ekf-random", ESTIMATOR_GROUP, ("estimator=!Ekf", "attitude=!RandomAttitude")),
            _summary(position_rmse_over_per_run_pcrlb=1.02),
        ),
    ]
    text = ratio_tables(rows)
    assert "| estimator | fixed | random |" in text
    assert "| kf | 2 / 1.5 | — / — |" in text
    assert "| ekf | — / — | 1.02 / — |" in text
    assert ratio_tables([(Variant("a", "other", ()), _summary())]) == ""


def test_compare_writes_both_files_and_states_its_command(tmp_path, monkeypatch):
    calls = []

    def fake_run_studies(studies, **options):
        calls.append(options)
        return [
            StudyResult(s, np.arange(s.runs), [], np.empty((s.runs, 0)), None, _summary(), s.runs)
            for s in studies
        ]

    monkeypatch.setattr(comparison_module, "run_studies", fake_run_studies)
    variants = VARIANT_GROUPS["tracking"]()
    result = compare(variants, tmp_path, runs=4, base_overrides=SHORT, workers=2)
    assert calls == [{"workers": 2, "figures": False}]
    assert [variant for variant, _ in result] == variants
    assert result[0][1].study.out_dir == tmp_path / "studies" / variants[0].name
    assert result[0][1].study.scenario.steps == 80
    markdown = (tmp_path / "compare.md").read_text()
    assert markdown.startswith("# Comparison (paper scenario, 4 runs per variant)\n\n")
    command = "drake-uuv compare --runs 4 --set steps=80 --set steady_state_start=40"
    assert f"Made by `{command} --group tracking`." in markdown
    assert "Cramér–Rao" not in markdown  # no estimator group: no ratio tables
    assert (tmp_path / "compare.csv").read_text().count("\n") == 1 + len(variants)


@pytest.mark.slow
def test_compare_runs_each_variant_and_tabulates_its_summary(tmp_path):
    variants = [
        Variant("fixed", "attitude", ("attitude=!FixedAttitude",)),
        Variant("trajectory", "attitude", ("attitude=!TrajectoryAttitude",), note="paper"),
    ]
    compare(variants, tmp_path, runs=2, base_overrides=SHORT, workers=1, progress=False)
    markdown = (tmp_path / "compare.md").read_text()
    assert "| fixed |" in markdown and "| trajectory | paper |" in markdown
    rows = list(csv.DictReader((tmp_path / "compare.csv").read_text().splitlines()))
    assert [row["variant"] for row in rows] == ["fixed", "trajectory"]
    for row, variant in zip(rows, variants, strict=True):
        folder = tmp_path / "studies" / variant.name
        summary = json.loads((folder / "summary.json").read_text())
        assert row["group"] == "attitude" and int(row["runs"]) == summary["runs"] == 2
        assert float(row["position_rmse"]) == summary["position_rmse"]
        assert float(row["nees_mean_ci95_low"]) == summary["nees_mean_ci95"][0]
        assert not (folder / "figures").exists()  # compare draws no band figures
    fixed = json.loads((tmp_path / "studies" / "fixed" / "study.json").read_text())
    assert fixed["scenario"]["attitude"] == {"variant": "FixedAttitude"}


BUDGET_ROWS = ("alg2", "alg2-0.1", "info-0.1", "alg2-0.2", "info-0.2", "alg2-0.39", "info-0.39")


def test_attitude_group_pairs_each_budget_with_algorithm_2_limited_to_it_and_builds():
    variants = VARIANT_GROUPS["attitude"]()
    assert [v.name for v in variants] == [
        f"{e}-{row}" for e in ("kf", "ekf") for row in BUDGET_ROWS
    ]
    for variant in variants:
        scenario = load_scenario("paper", list(variant.overrides))
        expected = {"kf": PaperKf, "ekf": Ekf}[variant.name.split("-")[0]]
        assert type(scenario.estimator) is expected, variant.name
        attitude = scenario.attitude
        kind, _, budget = variant.name.partition("-")[2].partition("-")
        if kind == "info":
            assert type(attitude) is InformationSeeking
            assert attitude.max_angle_per_step == float(budget)
            assert variant.note == f"{budget} rad/step"
        elif budget:
            assert type(attitude) is TrajectoryAttitude
            # The rate limit turns by at most the budget in one time step.
            assert attitude.max_angular_rate * scenario.time_step == pytest.approx(
                float(budget), rel=1e-15
            )
            assert variant.note == f"{budget} rad/step"
        else:
            assert type(attitude) is TrajectoryAttitude and attitude.max_angular_rate is None
        make_uuv_diagram(scenario, log=False)  # every system of the variant builds and wires


@pytest.mark.slow
def test_attitude_group_rows_of_a_budget_turn_by_at_most_it_and_the_limit_binds():
    rows = {v.name: v for v in VARIANT_GROUPS["attitude"]()}
    peaks = {}
    for name in ("kf-alg2", "kf-alg2-0.1", "kf-info-0.1", "ekf-info-0.2"):
        scenario = load_scenario("paper", [*SHORT, *rows[name].overrides])
        peaks[name] = ClosedLoopSimulation(scenario).run(seed=3).metrics["rotation_peak"]
    # Unlimited, Algorithm 2 turns far more than 0.1 rad in some step (h(k) swings the
    # baseline's elevation by ±0.5 |b| every 6 steps), so the limit of 0.1 rad binds ...
    assert peaks["kf-alg2"] > 0.3
    assert peaks["kf-alg2-0.1"] == pytest.approx(0.1, abs=1e-9)
    # ... and the planner stays within its budget.
    assert peaks["kf-info-0.1"] <= 0.1 + 1e-9
    assert peaks["ekf-info-0.2"] <= 0.2 + 1e-9


def test_attitude_vehicle_group_compares_at_the_vehicle_rate_on_both_plants():
    variants = VARIANT_GROUPS["attitude_vehicle"]()
    names = ["kinematic-alg2-0.15", "kinematic-info-0.15", "auv-alg2-0.15", "auv-info-0.15"]
    assert [v.name for v in variants] == names
    for variant in variants:
        scenario = load_scenario("paper", list(variant.overrides))
        plant = HoveringAuv if variant.name.startswith("auv") else KinematicUuv
        assert type(scenario.plant) is plant and type(scenario.estimator) is PaperKf
        assert type(scenario.tracking) is LqrTracking
        assert scenario.tracking.reference_frame == "world"
        assert scenario.tracking.max_acceleration == 0.6
        # The target, and the filter's model of it, slowed to one the vehicle can follow.
        np.testing.assert_allclose(
            scenario.target.acceleration_covariance,
            0.166 * np.asarray(load_scenario("paper").target.acceleration_covariance),
            rtol=1e-12,
        )
        assert variant.note == "0.15 rad/step, W × 0.166"
        if "-info-" in variant.name:
            assert scenario.attitude.max_angle_per_step == pytest.approx(
                VEHICLE_ANGULAR_RATE * scenario.time_step, rel=1e-15
            )
        else:
            assert type(scenario.attitude) is TrajectoryAttitude
            assert scenario.attitude.max_angular_rate == pytest.approx(VEHICLE_ANGULAR_RATE)
        make_uuv_diagram(scenario, log=False)


def test_vehicle_rate_and_acceleration_limit_leave_thrust_to_spare():
    vehicle = HoveringAuv()
    budget = utilisation_budget(
        vehicle.vehicle_model(),
        vehicle.allocator(),
        acceleration=0.6,  # tracking.max_acceleration of the group's loop
        speed=0.38,  # the speed its Bryson weight allows
        angular_rate=VEHICLE_ANGULAR_RATE,
        rate_step=VEHICLE_ANGULAR_RATE,
        tilt=math.pi / 2,  # the largest restoring moment
        attitude_bandwidth=vehicle.attitude_bandwidth,
        attitude_damping_ratio=vehicle.attitude_damping_ratio,
    )
    assert 0.8 < budget["total"] < 0.85


def test_attitude_vehicle_target_reaches_the_speed_budget_as_rms_final_speed():
    """The group's slowed W: closed form of the RMS final speed (to the three digits the
    group rounds the factor to), and a seeded sample of final speeds against it."""
    paper = load_scenario("paper")
    (row,) = [v for v in attitude_vehicle_variants() if v.name == "auv-info-0.15"]
    scenario = load_scenario("paper", list(row.overrides))
    v0 = np.asarray(paper.target.initial_velocity)
    W = np.asarray(scenario.target.acceleration_covariance)
    # Closed form: |v(0)|² + (N − 1) t² trace(s W) = 0.38², s rounded to three digits.
    walk = (paper.steps - 1) * paper.time_step**2 * np.trace(W)
    assert v0 @ v0 + walk == pytest.approx(VEHICLE_SPEED_BUDGET**2, rel=5e-3)
    # Seeded: the targets' final speed, v(0) + t Σ a(j) over N − 1 steps, a ~ N(0, s W).
    n, steps = 4000, paper.steps - 1
    rng = np.random.default_rng(1)
    sums = rng.standard_normal((n, 3)) * np.sqrt(steps * np.diag(W))  # Σ a(j), per axis
    speed2 = np.sum((v0 + paper.time_step * sums) ** 2, axis=1)
    variances = paper.time_step**2 * steps * np.diag(W)  # of each final velocity component
    std = np.sqrt(np.sum(2.0 * variances**2 + 4.0 * v0**2 * variances) / n)
    assert abs(speed2.mean() - (v0 @ v0 + walk)) < 4.0 * std
