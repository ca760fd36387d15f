"""The information-seeking attitude generator as a Drake system."""

import dataclasses
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pydrake.systems.framework import DiagramBuilder

from drake_uuv.attitude import AttitudeSetting
from drake_uuv.attitude.information_seeking import InformationSeekingAttitude
from drake_uuv.estimators import make_estimator
from drake_uuv.models.attitude_candidates import rotation_angles
from drake_uuv.models.information import (
    EstimatorPlanningModel,
    PlannedMeasurement,
    TrackingPlanningModel,
)
from drake_uuv.models.so3 import exp_so3
from drake_uuv.scenario import InformationSeeking, LqrTracking, load_scenario
from drake_uuv.testing import discrete_update, fixed_context
from drake_uuv.tracking import LqrTrackingController, TrackingSetting
from tests.conftest import ETA, T, W

B = np.array([-1.0, 1.0, 0.0])
Q_STAR = np.array([-2.0, -2.0, 0.0])
R0 = exp_so3(np.array([0.4, -0.3, 1.2]))
X_HAT = np.array([-2.1, -1.8, 0.3, 0.05, -0.02, 0.01])
#: The paper's KF, and a raw-range estimator without a linear start.
KF = EstimatorPlanningModel(PlannedMeasurement.RANGE_DIFFERENCE)
RANGES = EstimatorPlanningModel(PlannedMeasurement.RANGES)


def setting(estimator: EstimatorPlanningModel = KF, reference_lag: int = 0) -> AttitudeSetting:
    """The paper's sonars and target, planning for ``estimator`` and a law holding q* in the
    body frame with ``reference_lag``."""
    return AttitudeSetting(
        time_step=T,
        baseline_B=B,
        noise_variances=ETA,
        samples_per_step=1,
        acceleration_covariance=W,
        estimator=estimator,
        tracking=TrackingPlanningModel(tuple(Q_STAR), reference_lag),
    )


def planning_system(
    estimator: EstimatorPlanningModel = KF,
    reference_lag: int = 0,
    **config,
) -> InformationSeekingAttitude:
    """The planner of ``InformationSeeking(**config)`` for :func:`setting`."""
    return InformationSeekingAttitude(
        InformationSeeking(**config), setting=setting(estimator, reference_lag)
    )


def covariance(seed: int = 0) -> np.ndarray:
    M = np.random.default_rng(seed).normal(size=(6, 6))
    return M @ M.T + 0.1 * np.eye(6)


def context_for(system: InformationSeekingAttitude, R=R0, x=X_HAT, P=None):
    P = covariance() if P is None else P
    return fixed_context(system, R_WB_nav=R.ravel(), x_TU_hat=x, P_TU=P.ravel())


def test_ports_and_sizes() -> None:
    system = planning_system()
    inputs = {
        system.get_input_port(i).get_name(): system.get_input_port(i).size()
        for i in range(system.num_input_ports())
    }
    outputs = {
        system.get_output_port(i).get_name(): system.get_output_port(i).size()
        for i in range(system.num_output_ports())
    }
    assert inputs == {"R_WB_nav": 9, "x_TU_hat": 6, "P_TU": 36}
    assert outputs == {"u2_W": 3, "R_WB_plan": 18}
    context = system.CreateDefaultContext()
    assert context.num_discrete_state_groups() == 3
    assert context.get_discrete_state(0).size() == 3 * 22 + 1
    assert context.get_discrete_state(1).size() == 10
    assert context.get_discrete_state(2).size() == 1


@pytest.mark.parametrize(
    "field, value, message",
    [
        ("estimator", "kf", r"^estimator: must be a EstimatorPlanningModel, got 'kf'"),
        ("tracking", None, r"^tracking: must be a TrackingPlanningModel, got None"),
        ("baseline_B", [0.0, 0.0, 0.0], r"^baseline_B: must be a non-zero 3-vector"),
        ("noise_variances", [0.01], r"^noise_variances: must be 2 finite numbers, got \[0.01\]"),
        ("samples_per_step", 0, r"^samples_per_step: must be an integer ≥ 1, got 0"),
        ("time_step", -1.0, r"^time_step: must be > 0, got -1.0"),
    ],
)
def test_a_bad_setting_names_the_field(field: str, value, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        dataclasses.replace(setting(), **{field: value})


@pytest.mark.parametrize(
    "options",
    [{}, {"estimator": RANGES, "position_prediction": "reference", "reference_lag": 1}],
)
def test_planned_next_attitude_is_the_plants_next_attitude(options: dict) -> None:
    system = planning_system(**options)
    context = context_for(system)
    u2 = system.GetOutputPort("u2_W").Eval(context)
    plan = system.GetOutputPort("R_WB_plan").Eval(context)
    R_next = exp_so3(u2 * T) @ R0  # the plant's eq. (2)
    assert_allclose(plan[:9].reshape(3, 3), R_next, atol=1e-14)
    # The outputs are the planner's choice on the same inputs (no state yet).
    step = system.planner.plan(X_HAT, covariance(), R0, np.zeros((0, 3)))
    assert_allclose(R_next, step.R_next, atol=1e-14)
    assert 0.9 * 0.39 <= np.linalg.norm(u2) * T <= 0.39 + 1e-12
    # R(k+2): the planner once more from R(k+1), its P(k+1|k+1) and the history with q_s(k).
    after = system.planner.plan(X_HAT, step.P_next, step.R_next, (R0 @ B)[np.newaxis], R0)
    assert_allclose(plan[9:].reshape(3, 3), after.R_next, atol=1e-14)
    assert rotation_angles(np.array([R_next, after.R_next]))[0] <= 0.39 + 1e-12


def test_update_shifts_the_baseline_history_and_keeps_the_attitude() -> None:
    system = planning_system()
    context = context_for(system)
    history = discrete_update(system, context, 0)
    assert history[-1] == 1
    assert_allclose(history[-4:-1], R0 @ B)
    assert_allclose(history[:-4], 0.0)
    assert_allclose(discrete_update(system, context, 1), np.append(R0.ravel(), 1.0))
    # A full history drops its oldest entry.
    state = np.append(np.arange(66.0), 22.0)
    context.get_mutable_discrete_state(0).SetFromVector(state)
    history = discrete_update(system, context, 0)
    assert_allclose(history[:63], np.arange(3.0, 66.0))
    assert_allclose(history[63:66], R0 @ B)
    assert history[-1] == 22


def test_linear_start_is_mirrored_one_way() -> None:
    """For a raw-range estimator the planner plans for the paper's ``Y`` until the filtered
    ``trace P_qq`` reaches the hand-over threshold, then for the ranges, for good."""
    threshold = 0.5
    ranges = planning_system(
        EstimatorPlanningModel(PlannedMeasurement.RANGES, threshold), position_prediction="hold"
    )
    linear = planning_system()
    # Least known along the line of sight: Y would measure it, the ranges already do (trace
    # P_qq 1.2 m² and 0.3 m²).
    wide, narrow = 0.4 * np.eye(6), 0.1 * np.eye(6)
    sight = X_HAT[:3] / np.linalg.norm(X_HAT[:3])
    wide[:3, :3] = 0.1 * np.eye(3) + 0.9 * np.outer(sight, sight)

    # A history that excites every direction, so that the floor leaves the choice free.
    history = np.sqrt(2.0) * np.tile(np.eye(3), (8, 1))[:22]

    def plan(system, P, handed_over=0.0):
        context = context_for(system, P=P)
        context.get_mutable_discrete_state(0).SetFromVector(np.append(history.ravel(), 22))
        context.get_mutable_discrete_state(2).SetFromVector([handed_over])
        return system.GetOutputPort("R_WB_plan").Eval(context)[:9], context

    before, context = plan(ranges, wide)
    assert_allclose(before, plan(linear, wide)[0], atol=1e-14)
    assert discrete_update(ranges, context, 2)[0] == 0.0
    after, context = plan(ranges, narrow)
    assert discrete_update(ranges, context, 2)[0] == 1.0
    expected = ranges.planner.plan(X_HAT, narrow, R0, history)
    assert_allclose(after, expected.R_next.ravel(), atol=1e-14)
    # Once handed over, a wide covariance no longer brings the linear model back.
    again, context = plan(ranges, wide, handed_over=1.0)
    assert_allclose(again, ranges.planner.plan(X_HAT, wide, R0, history).R_next.ravel())
    assert not np.allclose(again, before)
    assert discrete_update(ranges, context, 2)[0] == 1.0


def test_state_feeds_the_plan() -> None:
    """The stored history and previous attitude are the planner's: a reference limit
    computed from the stored ``R(k−1)`` holds."""
    limit = 1.0
    system = planning_system(max_reference_acceleration=limit)
    R_previous = exp_so3(np.array([0.0, 0.0, -0.3])) @ R0
    context = context_for(system)
    context.get_mutable_discrete_state(1).SetFromVector(np.append(R_previous.ravel(), 1.0))
    R_next = system.GetOutputPort("R_WB_plan").Eval(context)[:9].reshape(3, 3)
    second = (R_next - 2.0 * R0 + R_previous) @ Q_STAR / T**2
    assert np.linalg.norm(second) <= limit + 1e-9
    expected = system.planner.plan(X_HAT, covariance(), R0, np.zeros((0, 3)), R_previous)
    assert_allclose(R_next, expected.R_next, atol=1e-14)


def test_outputs_are_reproducible() -> None:
    first = planning_system(RANGES, position_prediction="hold")
    second = planning_system(RANGES, position_prediction="hold")
    a = first.GetOutputPort("R_WB_plan").Eval(context_for(first))
    b = second.GetOutputPort("R_WB_plan").Eval(context_for(second))
    assert np.array_equal(a, b)


def test_reads_the_filtered_estimate_without_an_algebraic_loop_through_lqr() -> None:
    """Estimator → planner → LQR (reads ``R_WB_plan``) → applied acceleration → estimator:
    no algebraic loop, because the filtered estimate never depends on the acceleration."""
    builder = DiagramBuilder()
    estimator = builder.AddSystem(make_estimator(load_scenario("paper")))  # the paper's KF
    attitude = builder.AddSystem(planning_system())
    lqr = LqrTracking(desired_relative_position=Q_STAR.tolist())
    controller = builder.AddSystem(LqrTrackingController(lqr, setting=TrackingSetting(T)))
    builder.Connect(estimator.GetOutputPort("x_TU_hat"), attitude.GetInputPort("x_TU_hat"))
    builder.Connect(estimator.GetOutputPort("P_TU"), attitude.GetInputPort("P_TU"))
    builder.Connect(estimator.GetOutputPort("x_TU_hat"), controller.GetInputPort("x_TU_hat"))
    builder.Connect(attitude.GetOutputPort("R_WB_plan"), controller.GetInputPort("R_WB_plan"))
    builder.Connect(controller.GetOutputPort("u1_W"), estimator.GetInputPort("u1_W"))
    for port in ("range_samples", "sonar_status"):
        builder.ExportInput(estimator.GetInputPort(port), port)
    builder.ExportInput(estimator.GetInputPort("R_WB_nav"), "R_WB_estimator")
    builder.ExportInput(attitude.GetInputPort("R_WB_nav"), "R_WB_attitude")
    builder.ExportInput(controller.GetInputPort("R_WB_nav"), "R_WB_controller")
    builder.ExportOutput(attitude.GetOutputPort("u2_W"), "u2_W")
    diagram = builder.Build()  # raises on an algebraic loop
    assert not diagram.HasDirectFeedthrough(
        diagram.GetInputPort("R_WB_controller").get_index(),
        diagram.GetOutputPort("u2_W").get_index(),
    )
    context = diagram.CreateDefaultContext()
    q_s = R0 @ B
    ranges = [np.linalg.norm(X_HAT[:3] + 0.5 * q_s), np.linalg.norm(X_HAT[:3] - 0.5 * q_s)]
    for name, value in (("range_samples", ranges), ("sonar_status", [0.0, 0.0]),
                        ("R_WB_estimator", R0.ravel()), ("R_WB_attitude", R0.ravel()),
                        ("R_WB_controller", R0.ravel())):  # fmt: skip
        diagram.GetInputPort(name).FixValue(context, np.asarray(value, dtype=float))
    u2 = diagram.GetOutputPort("u2_W").Eval(context)
    assert 0.0 < np.linalg.norm(u2) * T <= 0.39 + 1e-12


def test_a_long_run_of_the_system_keeps_budget_and_floor() -> None:
    """The system stepped with its own update on random estimates: every rotation within
    the budget, every window of N = 24 steps above the floor."""
    rng = np.random.default_rng(3)
    system = planning_system(max_angle_per_step=0.2)
    context = system.CreateDefaultContext()
    R = [R0]
    for _ in range(200):
        M = rng.normal(size=(6, 6))
        system.GetInputPort("R_WB_nav").FixValue(context, R[-1].ravel())
        system.GetInputPort("x_TU_hat").FixValue(context, rng.normal(size=6) * 2)
        system.GetInputPort("P_TU").FixValue(context, (M @ M.T + 1e-3 * np.eye(6)).ravel())
        u2 = system.GetOutputPort("u2_W").Eval(context)
        state = system.EvalUniquePeriodicDiscreteUpdate(context)
        context.SetDiscreteState(state)
        R.append(exp_so3(u2 * T) @ R[-1])
    R = np.array(R)
    assert rotation_angles(R).max() <= 0.2 + 1e-12
    baselines = R @ B
    windows = np.lib.stride_tricks.sliding_window_view(baselines, (24, 3))[:, 0]
    low = np.linalg.eigvalsh(np.einsum("wki,wkj->wij", windows, windows))[:, 0]
    assert low.min() >= 1.0
    assert math.isclose(np.linalg.norm(R[-1] @ B), np.linalg.norm(B), rel_tol=1e-9)
