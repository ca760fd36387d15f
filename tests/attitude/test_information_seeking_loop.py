"""The information-seeking planner in the closed loop: a variant of the attitude slot."""

import numpy as np
import pytest

from drake_uuv import ClosedLoopSimulation, load_scenario
from drake_uuv.attitude import InformationSeekingAttitude, make_attitude_generator
from drake_uuv.models.attitude_candidates import rotation_angles
from drake_uuv.scenario import ScenarioError


@pytest.mark.parametrize(
    "overrides, measurement",
    [
        ([], "range_difference"),
        (["estimator=!Ekf", "tracking=!LqrTracking"], "ranges"),
    ],
)
@pytest.mark.slow
def test_closed_loop_is_reproducible_and_keeps_the_budget(
    overrides: list[str], measurement: str
) -> None:
    scenario = load_scenario(
        "paper",
        ["attitude=!InformationSeeking {max_angle_per_step: 0.2}", "steps=120",
         "steady_state_start=60", *overrides],
    )  # fmt: skip
    simulation = ClosedLoopSimulation(scenario)
    planner = simulation.built.systems["attitude_generator"]
    assert isinstance(planner, InformationSeekingAttitude)
    assert planner.planner.measurement_model == measurement
    first, second = simulation.run(3), simulation.run(3)
    np.testing.assert_array_equal(first.log["R_WB"], second.log["R_WB"])
    np.testing.assert_array_equal(first.log["x_TU_hat"], second.log["x_TU_hat"])
    assert rotation_angles(first.log["R_WB"]).max() <= 0.2 + 1e-9
    assert first.metrics["rotation_peak"] <= 0.2 + 1e-9
    assert first.metrics["excitation_min"] >= 1.0
    assert not np.array_equal(first.log["R_WB"], simulation.run(4).log["R_WB"])


def test_the_world_frame_reference_plans_with_a_held_position() -> None:
    scenario = load_scenario(
        "paper", ["attitude=!InformationSeeking", "estimator=!Ekf",
                  "tracking.reference_frame=world"],
    )  # fmt: skip
    planner = make_attitude_generator(scenario).planner
    assert planner.position_prediction == "hold" and planner.q_star is None
    assert planner.measurement_model == "ranges" and planner.max_reference_acceleration is None


def test_the_planner_plans_for_the_scenarios_estimator_and_tracking_law() -> None:
    """The factory's wiring: the estimator's measurement and linear start, the law's q* (body
    frame) and its lag (none with the LQR law's feed-forward), the planner's own window."""
    scenario = load_scenario(
        "paper", ["attitude=!InformationSeeking {excitation_window: 30}", "estimator=!Ekf",
                  "estimator.handover=threshold", "estimator.linear_start_position_variance=0.7",
                  "tracking=!LqrTracking", "tracking.desired_relative_position=[1, 2, 3]"],
    )  # fmt: skip
    planner = make_attitude_generator(scenario).planner
    assert planner.measurement_model == "ranges"
    assert planner.linear_start_position_variance == 0.7
    np.testing.assert_array_equal(planner.q_star, [1.0, 2.0, 3.0])
    assert planner.reference_lag == 0 and planner.position_prediction == "reference"
    assert planner.pe_window == 30 and scenario.analysis.pe_window == 24
    lagging = load_scenario("paper", ["attitude=!InformationSeeking", "tracking.alpha=1.1"])
    planner = make_attitude_generator(lagging).planner
    assert planner.measurement_model == "range_difference"
    assert planner.reference_lag == 1 and planner.position_prediction == "hold"


@pytest.mark.parametrize(
    "override, message",
    [
        ("attitude.max_angle_per_step=0", r"^attitude.max_angle_per_step: must be in \(0, π\], got 0"),
        ("attitude.criterion=best", r"^attitude.criterion: must be one of d_optimal, a_optimal, e_optimal, got 'best'"),
        ("attitude.pe_lead=22", r"^attitude.pe_lead: must be ≤ attitude.excitation_window − 3 = 21, got 22"),
        ("attitude.excitation_window=2", r"^attitude.excitation_window: must be in \[3, 1e6\], got 2"),
        ("attitude.horizon=0", r"^attitude.horizon: must be in \[1, 50\], got 0"),
    ],
)  # fmt: skip
def test_bad_fields_are_named(override: str, message: str) -> None:
    with pytest.raises(ScenarioError, match=message):
        load_scenario("paper", ["attitude=!InformationSeeking", override])
