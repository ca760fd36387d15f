"""The repository's study groups (``studies/``, loaded as ``drake-uuv compare`` loads them):
every group lists its variants, every variant loads and names what it sets, and the groups'
derived constants (the vehicle's rate and speed budget) hold what their comments say."""

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
    TrajectoryAttitude,
    load_scenario,
)
from drake_uuv.simulation import ClosedLoopSimulation
from drake_uuv.studies import Group, load_groups
from tests.conftest import STUDIES, study_module
from tests.studies.study_helpers import SHORT

GROUPS = load_groups(STUDIES)
paper = study_module("paper")
vehicle = study_module("vehicle")
VEHICLE_ANGULAR_RATE = vehicle.VEHICLE_ANGULAR_RATE
VEHICLE_SPEED_BUDGET = vehicle.VEHICLE_SPEED_BUDGET


def test_the_groups_in_order_and_the_paper_s_three_run_by_default():
    assert list(GROUPS) == [
        "attitude_noise", "alpha", "estimator", "tracking",
        "vehicle", "regimes", "attitude", "attitude_vehicle", "navigation", "robustness",
    ]  # fmt: skip
    assert [name for name, group in GROUPS.items() if group.paper] == [
        "attitude_noise",
        "alpha",
        "tracking",
    ]
    assert all(
        isinstance(group, Group) and "\n" not in group.description for group in GROUPS.values()
    )
    # The package's GROUPS list is the one the loader read.
    assert study_module().GROUPS == list(GROUPS.values())


@pytest.mark.slow
def test_every_variant_loads_and_variant_names_are_unique():
    variants = [v for group in GROUPS.values() for v in group.variants()]
    names = [variant.name for variant in variants]
    assert len(names) == len(set(names)) == 103 + 136 + 40
    for variant in variants:
        # Raises ScenarioError if not.
        load_scenario(variant.scenario or "paper", list(variant.overrides))


def test_alphas_are_labelled_by_the_proven_interval():
    low, high = ALPHA_PROVEN_INTERVAL
    for variant in paper.alpha_sweep_variants([0.29, 0.3, 1.7, 1.71]):
        alpha = float(variant.name.removeprefix("alpha-"))
        assert variant.note == ("proven" if low < alpha < high else "unproven")


def test_estimator_group_lists_its_five_estimators_explicitly_under_each_attitude():
    variants = GROUPS["estimator"].variants()
    estimators = ("kf", "ekf", "iekf", "ukf", "particle_filter")
    modes = ("fixed", "random", "trajectory")
    assert [v.name for v in variants] == [f"{e}-{m}" for e in estimators for m in modes]
    tags = {"kf": "PaperKf", "ekf": "Ekf", "iekf": "Iekf", "ukf": "Ukf",
            "particle_filter": "ParticleFilter"}  # fmt: skip
    for variant in variants:
        estimator, mode = variant.name.split("-")
        scenario = load_scenario("paper", list(variant.overrides))
        assert type(scenario.estimator).__name__ == tags[estimator]
        assert type(scenario.attitude).__name__ == f"{mode.capitalize()}Attitude"
        assert variant.ratio_table  # its rows make compare.md's RMSE / PCRLB tables
    # No other group's rows enter the ratio tables.
    others = [v for n, g in GROUPS.items() if n != "estimator" for v in g.variants()]
    assert not any(variant.ratio_table for variant in others)


BUDGET_ROWS = ("alg2", "alg2-0.1", "info-0.1", "alg2-0.2", "info-0.2", "alg2-0.39", "info-0.39")


def test_attitude_group_pairs_each_budget_with_algorithm_2_limited_to_it_and_builds():
    variants = GROUPS["attitude"].variants()
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
    rows = {v.name: v for v in GROUPS["attitude"].variants()}
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
    variants = GROUPS["attitude_vehicle"].variants()
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
    (row,) = [v for v in GROUPS["attitude_vehicle"].variants() if v.name == "auv-info-0.15"]
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


def test_navigation_group_varies_one_error_source_at_a_time_and_names_it():
    navigation = study_module("navigation")
    rows = {v.name: v for v in navigation.source_variants()}
    # 2 laws × (the error-free row with one model + 7 sources × 2 models) × 4 estimators.
    assert len(rows) == 2 * (1 + 7 * 2) * 4
    zero = {"attitude_noise_deg": [0.0, 0.0, 0.0], "heading_bias_deg": 0.0,
            "velocity_noise": 0.0, "velocity_bias": 0.0}  # fmt: skip
    expected = {
        "ideal": {},
        "ahrs": {"attitude_noise_deg": [0.5, 0.5, 2.0]},
        "compass": {"heading_bias_deg": 2.0},
        "dvl": {"velocity_noise": 0.01, "velocity_bias": 0.005},
    }
    for source, figures in expected.items():
        s = load_scenario("paper", list(rows[f"lqr-{source}-pf-modelled"].overrides))
        if not figures:
            assert type(s.navigation).__name__ == "PerfectNavigation"
            continue
        nav = s.navigation
        got = {name: getattr(nav, name) for name in zero}
        assert got == {**zero, **figures}
        assert s.sonar.ping_offsets == [0.0, 0.0] and s.sonar.latency == 0.0
    timing = {"pings": ("ping_offsets", [0.0, 0.25]), "latency": ("latency", 0.2),
              "sound": ("sound_speed_error", 0.005)}  # fmt: skip
    for source, (field, value) in timing.items():
        s = load_scenario("paper", list(rows[f"paper-{source}-kf-ideal"].overrides))
        assert getattr(s.sonar, field) == value
        assert type(s.navigation).__name__ == "PerfectNavigation"
        assert type(s.estimator) is PaperKf and s.estimator.error_model == "ideal"
    lqr = load_scenario("paper", list(rows["lqr-all-ukf-modelled"].overrides))
    assert type(lqr.tracking) is LqrTracking and lqr.tracking.reference_frame == "world"
    assert lqr.tracking.max_acceleration == 3.0
    assert lqr.estimator.vehicle_motion == "navigation"


def test_navigation_group_s_realistic_rows_start_every_estimator_from_the_scenario_s_prior():
    navigation = study_module("navigation")
    rows = {v.name: v for v in navigation.realistic_variants()}
    assert len(rows) == 2 * 4 * 2
    own = load_scenario("realistic")
    for name, variant in rows.items():
        assert variant.scenario == "realistic"
        s = load_scenario("realistic", list(variant.overrides))
        assert s.estimator.initial_covariance == own.estimator.initial_covariance, name
        assert s.estimator.error_model == name.rsplit("-", 1)[1]
        plant = HoveringAuv if "-auv-" in name else KinematicUuv
        assert type(s.plant) is plant
        if "-pf-" in name:  # the scenario's own particle filter, 20 000 particles
            assert s.estimator.particle_count == own.estimator.particle_count == 20_000


def test_the_robustness_group_runs_every_shipped_scenario_and_a_fifth_on_the_vehicle():
    rows = {variant.name: variant for variant in GROUPS["robustness"].variants()}
    shipped = {name[len("robust-") :] for name in rows if name.count("-") == 1}
    assert {"paper", "noisy_sonar", "far_standoff", "hovering_auv", "realistic"} <= shipped
    assert rows["robust-hovering_auv"].runs(1000) == 200
    assert rows["robust-realistic-kinematic-ekf"].runs(1000) == 1000
    assert rows["robust-realistic-auv-ekf"].runs(1000) == 200
    # The realistic scenario's 20 000-particle filter: a tenth, on either plant.
    assert rows["robust-realistic"].runs(1000) == 100
    assert rows["robust-realistic-kinematic-pf"].runs(1000) == 100
    assert rows["robust-realistic-auv-pf"].overrides == ()  # the scenario's own filter
    for name in ("robust-paper-ekf", "robust-far-ukf", "robust-noisy-pf"):
        assert rows[name].runs(1000) == 1000


def test_the_robustness_group_runs_the_consistency_options_and_the_lqr_law_in_every_regime():
    rows = {variant.name: variant for variant in GROUPS["robustness"].variants()}
    regimes = ("paper", "lqr", "far", "noisy", "realistic-auv", "realistic-kinematic")
    for regime in regimes:
        for estimator in ("ekf", "ekf2", "ukf", "ukf2", "pf"):  # and pf2: below
            assert f"robust-{regime}-{estimator}" in rows
    ekf2 = load_scenario("paper", list(rows["robust-lqr-ekf2"].overrides))
    assert (ekf2.estimator.second_order, ekf2.estimator.linearisation_correlation) == ("full", 7)
    assert ekf2.tracking.reference_frame == "world" and ekf2.tracking.max_acceleration == 3
    textbook = load_scenario("paper", list(rows["robust-lqr-ekf"].overrides))
    assert textbook.estimator.second_order == "none"
    far = load_scenario("far_standoff", list(rows["robust-far-ekf2"].overrides))
    assert far.estimator.second_order == "full"
    assert rows["robust-lqr-pf"].runs(1000) == 1000
    ukf2 = load_scenario("paper", list(rows["robust-paper-ukf2"].overrides))
    assert ukf2.estimator.linearisation_correlation == 4
    # The range-bearing kernel where the scenario's own filter does not have it already.
    for regime in regimes:
        assert (f"robust-{regime}-pf2" in rows) == (regime != "far")
    realistic = load_scenario("realistic", list(rows["robust-realistic-auv-pf2"].overrides))
    assert realistic.estimator.particle_kernel == "range_bearing"
    assert realistic.estimator.particle_count == 20_000  # the scenario's own filter otherwise
    for regime, scenario in (("paper", "paper"), ("lqr", "paper"), ("noisy", "noisy_sonar")):
        pf2 = load_scenario(scenario, list(rows[f"robust-{regime}-pf2"].overrides))
        assert pf2.estimator.particle_kernel == "range_bearing"
        pf = load_scenario(scenario, list(rows[f"robust-{regime}-pf"].overrides))
        assert pf.estimator.particle_kernel == "cartesian"
    assert load_scenario("far_standoff").estimator.particle_kernel == "range_bearing"


@pytest.mark.parametrize(
    ("scenario", "overrides", "share"),
    [
        ("paper", (), 1.0),
        ("paper", ("estimator=ParticleFilter",), 1.0),  # 5000 particles
        ("paper", ("estimator=!ParticleFilter {particle_count: 20000}",), 0.1),
        ("paper", ("estimator=!MarginalizedParticleFilter {particle_count: 20000}",), 0.1),
        ("hovering_auv", (), 0.2),
        ("realistic", (), 0.1),  # the vehicle and 20 000 particles: the smaller share
        ("realistic", ("plant=KinematicUuv", "estimator=Ekf"), 1.0),  # a bridge, not a filter
        ("realistic", ("estimator=Ekf",), 0.2),
    ],
)
def test_a_row_s_share_of_the_runs_follows_what_its_runs_cost(scenario, overrides, share):
    shares = study_module("shares")
    assert shares.run_share(load_scenario(scenario, list(overrides))) == share


def test_every_group_s_rows_take_their_share_of_the_runs():
    shares = study_module("shares")
    for name in ("vehicle", "regimes", "attitude_vehicle", "navigation", "robustness"):
        for row in GROUPS[name].variants():
            scenario = load_scenario(row.scenario or "paper", list(row.overrides))
            assert row.run_fraction == shares.run_share(scenario), (name, row.name)
