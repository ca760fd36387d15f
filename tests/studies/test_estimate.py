"""The wall-time estimate of a batch: configurations, the arithmetic with a fake timer, the text."""

import pytest

from drake_uuv.scenario import load_scenario
from drake_uuv.studies import (
    BaseScenario,
    Variant,
    WallTimeEstimate,
    configuration,
    estimate_wall_time,
    format_estimate,
    variant_studies,
)
from drake_uuv.studies import estimate as estimate_module
from drake_uuv.studies.estimate import duration, time_one_run
from drake_uuv.studies.storage import write_part
from tests.studies.study_helpers import SHORT, synthetic_chunk

KF = ("KinematicUuv", "PaperKf", "", "TrajectoryAttitude", 80, False)
KF_FIXED = ("KinematicUuv", "PaperKf", "", "FixedAttitude", 80, False)
PF = ("KinematicUuv", "ParticleFilter", "20000", "TrajectoryAttitude", 80, False)
PF_LATE = ("KinematicUuv", "ParticleFilter", "20000", "TrajectoryAttitude", 80, True)
VARIANTS = [
    Variant("kf", "g", ()),
    # Another noise model: the same configuration as "kf", timed once for both.
    Variant("kf-printed", "g", ("estimator.noise_model=paper_printed",)),
    Variant("pf", "g", ("estimator=!ParticleFilter {particle_count: 20000}",)),
    Variant("kf-fixed", "g", ("attitude=!FixedAttitude",)),
]
# Fake seconds of one run per configuration.
SECONDS = {KF: 0.5, PF: 4.0, KF_FIXED: 0.25}


def test_configuration_is_plant_estimator_particles_attitude_steps_and_late_ranges():
    assert configuration(load_scenario("paper")) == (
        "KinematicUuv", "PaperKf", "", "TrajectoryAttitude", 500, False,
    )  # fmt: skip
    vehicle = load_scenario("paper", ["plant=!HoveringAuv", "estimator=!Ekf", *SHORT])
    # The EKF carries particles for its bridge: their count sets its cost too.
    assert configuration(vehicle) == (
        "HoveringAuv", "Ekf", "5000", "TrajectoryAttitude", 80, False,
    )  # fmt: skip
    printed = load_scenario("paper", ["estimator.noise_model=paper_printed"])
    assert configuration(printed) == configuration(load_scenario("paper"))


def test_late_ranges_are_their_own_configuration_only_where_the_estimator_models_them():
    pf = ["estimator=!ParticleFilter {particle_count: 20000}", *SHORT]
    late = ["sonar.ping_offsets=[0.0, 0.25]", "sonar.latency=0.2"]
    assert configuration(load_scenario("paper", pf)) == PF
    # Each particle steps through the window of ranges in flight: a run costs more.
    assert configuration(load_scenario("paper", [*pf, *late])) == PF_LATE
    # An estimator that takes every range at its tick pays nothing for the timing.
    ideal = load_scenario("paper", [*pf, *late, "estimator.error_model=ideal"])
    assert configuration(ideal) == PF


@pytest.fixture
def studies(tmp_path):
    return variant_studies(VARIANTS, tmp_path, 10, BaseScenario(overrides=SHORT))


def _timer(calls):
    def timer(scenario):
        calls.append(scenario)
        return SECONDS[configuration(scenario)]

    return timer


def test_one_run_of_each_configuration_is_timed_and_scaled_by_runs_and_workers(studies):
    calls = []
    estimate = estimate_wall_time(studies, workers=2, timer=_timer(calls))
    # Three configurations, each timed once, on the first scenario that has it.
    assert [configuration(s) for s in calls] == [KF, PF, KF_FIXED]
    assert calls[0] is studies[0].scenario
    assert estimate.costs == {KF: (0.5, 20), PF: (4.0, 10), KF_FIXED: (0.25, 10)}
    assert (estimate.variants, estimate.runs_per_variant, estimate.runs) == (4, 10, 40)
    assert estimate.run_seconds == 0.5 * 20 + 4.0 * 10 + 0.25 * 10 == 52.5
    assert estimate.seconds == 52.5 / 2
    # More workers than runs: one run each, the rest idle.
    assert estimate_wall_time(studies, 100, timer=_timer([])).seconds == 52.5 / 40
    # A cluster's size is unknown before it connects: one worker's time.
    assert estimate_wall_time(studies, None, timer=_timer([])).seconds == 52.5


def test_on_resume_only_the_runs_not_on_disk_count(studies):
    write_part(studies[0].out_dir, synthetic_chunk(range(4)))  # 4 of kf's 10 runs
    write_part(studies[2].out_dir, synthetic_chunk(range(10)))  # all of pf's
    calls = []
    estimate = estimate_wall_time(studies, workers=1, resume=True, timer=_timer(calls))
    assert [configuration(s) for s in calls] == [KF, KF_FIXED]  # nothing of pf to run
    assert estimate.costs == {KF: (0.5, 16), KF_FIXED: (0.25, 10)}
    assert estimate.runs == 26 and estimate.seconds == 0.5 * 16 + 0.25 * 10
    # Without --resume the runs on disk are computed again.
    assert estimate_wall_time(studies, 1, timer=_timer([])).runs == 40


def test_the_text_states_runs_time_and_what_was_measured():
    estimate = WallTimeEstimate(
        variants=4,
        runs_per_variant=10,
        runs=36,
        costs={KF: (0.5, 16), PF_LATE: (4.0, 10), KF_FIXED: (0.25, 10)},
        workers=2,
    )
    assert format_estimate(estimate) == (
        "36 runs to compute (4 variants × 10 runs, 4 on disk already): about 25 s on 2 workers,\n"
        "from two timed batches of each configuration (plant, estimator, particles, attitude, "
        "steps, late ranges):\n"
        "     4.00 s ×    10  KinematicUuv, ParticleFilter 20000, TrajectoryAttitude, 80 steps, "
        "late ranges\n"
        "     0.50 s ×    16  KinematicUuv, PaperKf, TrajectoryAttitude, 80 steps\n"
        "     0.25 s ×    10  KinematicUuv, PaperKf, FixedAttitude, 80 steps"
    )
    one = WallTimeEstimate(1, 1, 1, {KF: (0.5, 1)}, None)
    assert format_estimate(one).splitlines()[0] == (
        "1 run to compute (1 variant × 1 run): about 0 s on one worker (a cluster divides it "
        "by its worker threads),"
    )
    assert format_estimate(WallTimeEstimate(2, 3, 0, {}, 2)) == (
        "0 runs to compute (2 variants × 3 runs, 6 on disk already)"
    )


@pytest.mark.parametrize(
    ("seconds", "text"),
    [
        (0.4, "0 s"),
        (59.4, "59 s"),
        (59.6, "1 min 00 s"),
        (754, "12 min 34 s"),
        (7530, "2 h 05 min"),
    ],
)
def test_durations(seconds, text):
    assert duration(seconds) == text


def test_a_run_is_timed_in_two_short_batches_as_a_study_runs_them(monkeypatch):
    """32 runs of 40 and of 80 steps from the first seed: the difference is the later steps'
    cost per step; what the first batch took beyond its steps is the batch's fixed cost, paid
    once per batch of max_batch_size runs."""
    from drake_uuv.studies.runner import max_batch_size

    clock = iter([10.0, 12.0, 20.0, 23.2])
    calls = []
    monkeypatch.setattr(estimate_module, "perf_counter", lambda: next(clock))
    monkeypatch.setattr(
        estimate_module, "run_seeds", lambda scenario, s: calls.append((scenario.steps, s))
    )
    scenario = load_scenario("paper", ["steps=200", "steady_state_start=100"], seed=42)
    per_step = (3.2 - 2.0) / 40 / 32
    fixed = 2.0 - per_step * 40 * 32
    want = per_step * 200 + fixed / max_batch_size(scenario)
    assert time_one_run(scenario) == pytest.approx(want)
    assert calls == [(40, list(range(42, 74))), (80, list(range(42, 74)))]


def test_a_scenario_too_short_to_sample_twice_is_timed_whole(monkeypatch):
    clock = iter([10.0, 12.0])
    monkeypatch.setattr(estimate_module, "perf_counter", lambda: next(clock))
    monkeypatch.setattr(estimate_module, "run_seeds", lambda scenario, s: None)
    scenario = load_scenario("paper", ["steps=30", "steady_state_start=10"])
    assert time_one_run(scenario) == pytest.approx(2.0 / 32)
