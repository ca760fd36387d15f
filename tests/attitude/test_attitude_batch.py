"""Every attitude generator steps a batch of runs: one step of B runs is, bit for bit, each
run alone (outputs and update), on random batches that mix every branch in one batch."""

import math

import numpy as np
import pytest

from drake_uuv.attitude import (
    AttitudeSetting,
    FixedAttitudeGenerator,
    InformationSeekingAttitude,
    RandomAttitudeGenerator,
    TrajectoryAttitudeGenerator,
    attitude_setting,
    make_attitude_generator,
)
from drake_uuv.models.attitude_plans import attitude_commands, trajectory_attitude
from drake_uuv.models.information import (
    EstimatorPlanningModel,
    PlannedMeasurement,
    TrackingPlanningModel,
)
from drake_uuv.models.so3 import exp_so3, matrix_from_quaternion
from drake_uuv.scenario import (
    FixedAttitude,
    InformationSeeking,
    RandomAttitude,
    TrajectoryAttitude,
    load_scenario,
)
from drake_uuv.testing import assert_batch_equals_runs
from tests.conftest import ETA, T, W

SETTING = attitude_setting(load_scenario("paper"))
B_BODY = np.array([-1.0, 1.0, 0.0])
Q_STAR = np.array([-2.0, -2.0, 0.0])
#: The rate limit of the limited variants [rad/s]: 0.25 rad a step at t = 0.5 s.
RATE = 0.5


def rotations(rng: np.random.Generator, count: int, scale: float = 2.0) -> np.ndarray:
    return np.array([exp_so3(scale * rng.normal(size=3)) for _ in range(count)])


def mixed_attitudes(rng: np.random.Generator, desired: np.ndarray, count: int) -> np.ndarray:
    """Attitudes alternately near ``desired`` (within the rate limit) and far from it."""
    R = []
    for i in range(count):
        near = i % 2 == 0
        turn = rng.normal(size=3)
        turn *= (0.1 if near else 1.5) / np.linalg.norm(turn)
        R.append(exp_so3(turn) @ desired[i % len(desired)])
    return np.array(R)


def assert_rate_limit_mixed(R_desired: np.ndarray, R_WB: np.ndarray) -> None:
    """The batch holds runs the limit scales and runs it leaves alone."""
    free = np.linalg.norm(attitude_commands(R_desired, R_WB, T, None), axis=1)
    assert (free > RATE).any() and (free < RATE).any()


@pytest.mark.parametrize("batch_size", [1, 2, 5])
def test_fixed_batch_is_each_run_alone(batch_size: int) -> None:
    rng = np.random.default_rng(batch_size)
    R = rotations(rng, batch_size).reshape(batch_size, 9)
    assert_batch_equals_runs(
        lambda B: FixedAttitudeGenerator(FixedAttitude(), setting=SETTING, batch_size=B),
        {"R_WB_nav": R},
    )


@pytest.mark.parametrize("max_rate", [None, RATE])
@pytest.mark.parametrize("batch_size", [1, 2, 5])
def test_random_batch_is_each_run_alone(batch_size: int, max_rate: float | None) -> None:
    rng = np.random.default_rng(10 + batch_size)
    noise = rng.normal(size=(batch_size, 4))
    # The sampled rotation of each run, and attitudes near and far from it.
    desired = np.array([matrix_from_quaternion(q / np.linalg.norm(q)) for q in noise])
    R = mixed_attitudes(rng, desired, batch_size)
    if max_rate is not None and batch_size > 1:
        assert_rate_limit_mixed(desired, R)
    config = RandomAttitude(max_angular_rate=max_rate)
    assert_batch_equals_runs(
        lambda B: RandomAttitudeGenerator(config, setting=SETTING, batch_size=B),
        {"R_WB_nav": R.reshape(batch_size, 9), "rotation_noise": noise},
    )


@pytest.mark.parametrize("k", [0, 7, 31])
@pytest.mark.parametrize("max_rate", [None, RATE])
@pytest.mark.parametrize("batch_size", [1, 2, 5])
def test_trajectory_batch_is_each_run_alone(
    batch_size: int, max_rate: float | None, k: int
) -> None:
    rng = np.random.default_rng(20 + batch_size + k)
    config = TrajectoryAttitude(max_angular_rate=max_rate)
    desired = trajectory_attitude(k, B_BODY, config.rho, config.h_amplitude, config.h_frequency)
    R = mixed_attitudes(rng, desired[np.newaxis], batch_size)
    if max_rate is not None and batch_size > 1:
        assert_rate_limit_mixed(desired, R)
    assert_batch_equals_runs(
        lambda B: TrajectoryAttitudeGenerator(config, setting=SETTING, batch_size=B),
        {"R_WB_nav": R.reshape(batch_size, 9)},
        time=k * T,
    )


@pytest.mark.parametrize(
    "tag", ["FixedAttitude", "RandomAttitude", "TrajectoryAttitude", "InformationSeeking"]
)
def test_factory_passes_the_batch_size(tag: str) -> None:
    system = make_attitude_generator(load_scenario("paper", [f"attitude=!{tag}"]), batch_size=4)
    assert system.batch_size == 4
    assert system.GetInputPort("R_WB_nav").size() == 36
    assert system.GetOutputPort("u2_W").size() == 12
    assert system.GetOutputPort("R_WB_plan").size() == 72
    with pytest.raises(ValueError, match=r"^batch_size: must be an integer ≥ 1, got 0"):
        make_attitude_generator(load_scenario("paper", [f"attitude=!{tag}"]), batch_size=0)


@pytest.mark.parametrize("max_rate", [None, RATE])
def test_a_nan_run_leaves_the_others_unchanged(max_rate: float | None) -> None:
    """A run whose attitude (or noise) is NaN gives NaN without raising; the other runs are
    the same bits as alone."""
    rng = np.random.default_rng(5)
    noise = rng.normal(size=(4, 4))
    noise[2, 1] = np.nan
    R = rotations(rng, 4)
    R[1, 0, 0] = np.nan
    inputs = {"R_WB_nav": R.reshape(4, 9)}
    for make in (
        lambda B: TrajectoryAttitudeGenerator(
            TrajectoryAttitude(max_angular_rate=max_rate), setting=SETTING, batch_size=B
        ),
        lambda B: FixedAttitudeGenerator(FixedAttitude(), setting=SETTING, batch_size=B),
    ):
        assert_batch_equals_runs(make, inputs, time=3 * T)
    config = RandomAttitude(max_angular_rate=max_rate)
    assert_batch_equals_runs(
        lambda B: RandomAttitudeGenerator(config, setting=SETTING, batch_size=B),
        {**inputs, "rotation_noise": noise},
    )
    system = RandomAttitudeGenerator(config, setting=SETTING, batch_size=4)
    context = system.CreateDefaultContext()
    system.GetInputPort("R_WB_nav").FixValue(context, R.ravel())
    system.GetInputPort("rotation_noise").FixValue(context, noise.ravel())
    u2 = system.GetOutputPort("u2_W").Eval(context).reshape(4, 3)
    assert np.isnan(u2[[1, 2]]).all() and np.isfinite(u2[[0, 3]]).all()


# ------------------------------------------------------------- the information-seeking planner

#: A raw-range estimator whose linear start ends at trace P_qq ≤ 0.5 m².
RANGES = EstimatorPlanningModel(PlannedMeasurement.RANGES, 0.5)
KF = EstimatorPlanningModel(PlannedMeasurement.RANGE_DIFFERENCE)

#: (estimator, reference lag, config): every model, criterion, block, prediction and limit.
PLANNERS = {
    "kf": (KF, 1, {}),
    "kf_d_full_h2": (KF, 1, {"criterion": "d_optimal", "block": "full", "horizon": 2}),
    "kf_e_coast": (KF, 1, {"criterion": "e_optimal", "position_prediction": "coast"}),
    "kf_e_full": (KF, 1, {"criterion": "e_optimal", "block": "full"}),
    "kf_limit": (KF, 1, {"max_reference_acceleration": 1.0, "max_angle_per_step": 0.6}),
    "kf_no_floor": (KF, 1, {"excitation_floor": 0.0}),
    "ranges_hold": (RANGES, 0, {"position_prediction": "hold"}),
    "ranges_reference": (RANGES, 1, {"position_prediction": "reference"}),
    "ranges_reference_limit": (
        RANGES,
        0,
        {"position_prediction": "reference", "max_reference_acceleration": 1.0},
    ),
}


def planner_setting(estimator: EstimatorPlanningModel, lag: int) -> AttitudeSetting:
    return AttitudeSetting(
        time_step=T,
        baseline_B=B_BODY,
        noise_variances=ETA,
        samples_per_step=2,
        acceleration_covariance=W,
        estimator=estimator,
        tracking=TrackingPlanningModel(tuple(Q_STAR), lag),
    )


def planner_maker(name: str):
    estimator, lag, options = PLANNERS[name]
    config = InformationSeeking(**options)
    setting = planner_setting(estimator, lag)
    return lambda B: InformationSeekingAttitude(config, setting=setting, batch_size=B)


def planner_batch(rng: np.random.Generator, count: int, kept: int = 22):
    """Inputs and states of ``count`` runs that differ in every branch: covariances on both
    sides of the hand-over threshold, histories empty, short and full (the floor's novelty
    fallback and its free choice), ``R(k−1)`` unknown, near (the limit met) and far (no
    candidate meets it: the least demanding), hand-over done or not."""
    R = rotations(rng, count)
    x = np.concatenate([Q_STAR + rng.normal(size=(count, 3)), rng.normal(size=(count, 3))], 1)
    P = []
    for i in range(count):
        M = rng.normal(size=(6, 6))
        S = M @ M.T + 0.01 * np.eye(6)
        P.append(S * ((0.05 if i % 2 else 2.0) / np.trace(S[:3, :3])))
    history = np.zeros((count, 3 * kept + 1))
    previous = np.zeros((count, 10))
    handed = np.zeros((count, 1))
    for i in range(count):
        filled = (0, 1, 3, kept)[i % 4]
        directions = rng.normal(size=(filled, 3))
        directions *= math.sqrt(2.0) / np.linalg.norm(directions, axis=1, keepdims=True)
        history[i, 3 * (kept - filled) : 3 * kept] = directions.ravel()
        history[i, -1] = filled
        kind = (i + 1) % 3  # 0: no R(k−1); 1: near; 2: far
        if kind:
            turn = rng.normal(size=3)
            turn *= (0.02 if kind == 1 else 0.6) / np.linalg.norm(turn)
            previous[i] = np.append((exp_so3(turn) @ R[i]).ravel(), 1.0)
        handed[i] = float(i % 5 == 3)
    inputs = {
        "R_WB_nav": R.reshape(count, 9),
        "x_TU_hat": x,
        "P_TU": np.array(P).reshape(count, 36),
    }
    return inputs, [history, previous, handed]


@pytest.mark.parametrize("name", list(PLANNERS))
@pytest.mark.parametrize("batch_size", [1, 2, 7])
def test_information_seeking_batch_is_each_run_alone(name: str, batch_size: int) -> None:
    rng = np.random.default_rng([list(PLANNERS).index(name), batch_size])
    inputs, states = planner_batch(rng, batch_size)
    assert_batch_equals_runs(planner_maker(name), inputs, states)


def test_the_planner_batch_exercises_every_branch() -> None:
    """The random batch of the test above takes each branch in some run and not in another:
    the reference limit met and not, the floor met and its fallback, the linear start."""
    make = planner_maker("ranges_reference_limit")
    inputs, states = planner_batch(np.random.default_rng(0), 12)
    system = make(12)
    context = system.CreateDefaultContext()
    for port, value in inputs.items():
        system.GetInputPort(port).FixValue(context, value.ravel())
    for group, value in enumerate(states):
        context.SetDiscreteState(group, value.ravel())
    steps = system.plans(context)[0]
    limit = system.planner.max_reference_acceleration
    known = ~np.isnan(steps.reference_acceleration)
    assert (steps.reference_acceleration[known] <= limit).any()
    assert (steps.reference_acceleration[known] > limit).any()
    assert (~known).any()
    window = system.planner.pe_window - system.planner.pe_lead
    filled = np.minimum(states[0][:, -1], window - 2)
    required = system.planner.excitation_floor * np.minimum((filled + 2) / window, 1.0)
    met = steps.excitation >= required
    assert met.any() and (~met).any()
    linear = system._linear_start(context, inputs["P_TU"].reshape(12, 6, 6))
    assert (linear > 0).any() and (linear == 0).any()


def test_a_nan_run_of_the_planner_leaves_the_others_unchanged() -> None:
    rng = np.random.default_rng(9)
    for name in ("kf_limit", "ranges_reference_limit", "kf_e_full"):
        inputs, states = planner_batch(rng, 5)
        inputs["P_TU"][1, 7] = np.nan
        inputs["x_TU_hat"][2, 0] = np.inf
        inputs["R_WB_nav"][3, 4] = np.nan
        states[0][4, 5] = np.nan
        states[0][0, -1] = np.nan
        assert_batch_equals_runs(planner_maker(name), inputs, states)
    system = planner_maker("kf")(5)
    context = system.CreateDefaultContext()
    for port, value in inputs.items():
        system.GetInputPort(port).FixValue(context, value.ravel())
    u2 = system.GetOutputPort("u2_W").Eval(context).reshape(5, 3)
    assert np.isnan(u2[3]).all() and np.isfinite(u2[[0, 4]]).all()
