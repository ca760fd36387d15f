"""The information of a candidate attitude and the information-seeking planner (plain numpy)."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from drake_uuv.models.attitude_candidates import (
    ball_rotations,
    cap_directions,
    minimal_rotation_vectors,
    rotate_vectors,
    rotation_angles,
)
from drake_uuv.models.filters import ekf_update, range_difference_update
from drake_uuv.models.information import (
    criterion_values,
    excitation_eigenvalues,
    posterior_covariances,
    range_difference_rows,
    range_rows,
)
from drake_uuv.models.information_planner import InformationSeekingPlanner
from drake_uuv.models.measurement import range_jacobian
from drake_uuv.models.motion import double_integrator, process_noise_covariance
from drake_uuv.models.so3 import exp_so3, log_so3, minimal_rotation
from tests.conftest import ETA, T, W

B = np.array([-1.0, 1.0, 0.0])
Q_STAR = np.array([-2.0, -2.0, 0.0])


def planner(**options) -> InformationSeekingPlanner:
    return InformationSeekingPlanner(T, B, W, ETA, **options)


def random_spd(rng: np.random.Generator, n: int = 6) -> np.ndarray:
    M = rng.normal(size=(n, n))
    return M @ M.T * rng.uniform(0.01, 3.0) + 1e-3 * np.eye(n)


def random_unit(rng: np.random.Generator, n: int) -> np.ndarray:
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def angle_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1))


# ----------------------------------------------------------------------- geometry


@pytest.mark.parametrize("max_angle", [0.05, 0.39, math.pi / 2])
def test_cap_grid_lies_in_the_cap_and_covers_it(max_angle: float) -> None:
    rng = np.random.default_rng(1)
    u0 = random_unit(rng, 1)[0]
    grid = cap_directions(u0, max_angle, rings=6)
    assert_allclose(grid[0], u0)
    assert_allclose(np.linalg.norm(grid, axis=1), 1.0, atol=1e-12)
    angles = angle_between(grid, u0)
    assert angles.max() <= max_angle + 1e-12
    assert_allclose(angles.max(), max_angle, rtol=1e-12)  # the outer ring is the boundary
    # Every direction of the cap is within one grid spacing of a grid point.
    samples = random_unit(rng, 20000)
    inside = samples[angle_between(samples, u0) <= max_angle]
    nearest = angle_between(inside[:, np.newaxis, :], grid[np.newaxis, :, :]).min(axis=1)
    assert nearest.max() <= max_angle / 6


@pytest.mark.slow
def test_ball_grid_lies_in_the_ball_and_covers_it() -> None:
    rng = np.random.default_rng(2)
    ball = ball_rotations(0.3, rings=4)
    assert_allclose(ball[0], 0.0)
    norms = np.linalg.norm(ball, axis=1)
    assert norms.max() <= 0.3 + 1e-12 and np.isclose(norms.max(), 0.3)
    samples = rng.uniform(-0.3, 0.3, size=(20000, 3))
    samples = samples[np.linalg.norm(samples, axis=1) <= 0.3]
    nearest = np.linalg.norm(samples[:, np.newaxis] - ball[np.newaxis], axis=2).min(axis=1)
    assert nearest.max() <= 0.3 / 4


def test_minimal_rotation_vectors_match_so3_minimal_rotation() -> None:
    rng = np.random.default_rng(3)
    u0 = random_unit(rng, 1)[0]
    targets = random_unit(rng, 50)
    targets = targets[targets @ u0 > -0.9]  # away from the antipode
    vectors = minimal_rotation_vectors(u0, np.vstack([u0, targets]))
    assert_allclose(vectors[0], 0.0)
    for phi, u in zip(vectors[1:], targets, strict=True):
        assert_allclose(exp_so3(phi), minimal_rotation(u0, u), atol=1e-12)
        assert_allclose(np.linalg.norm(phi), angle_between(u0, u), atol=1e-12)


def test_rotate_vectors_is_rodrigues() -> None:
    rng = np.random.default_rng(4)
    phis = np.vstack([np.zeros(3), rng.normal(size=(20, 3))])
    v = rng.normal(size=3)
    expected = np.array([exp_so3(phi) @ v for phi in phis])
    assert_allclose(rotate_vectors(phis, v), expected, atol=1e-12)


def test_rotation_angles_are_the_log_norms() -> None:
    rng = np.random.default_rng(5)
    steps = [np.zeros(3), 1e-9 * np.ones(3), [0.0, 0.0, math.pi - 1e-6], *rng.normal(size=(8, 3))]
    R = [exp_so3(rng.normal(size=3))]
    for phi in steps:
        R.append(exp_so3(np.asarray(phi, dtype=float)) @ R[-1])
    R = np.array(R)
    expected = [np.linalg.norm(log_so3(R[k + 1] @ R[k].T)) for k in range(len(R) - 1)]
    assert_allclose(rotation_angles(R), expected, atol=1e-9)


# ------------------------------------------------------------------- information


def test_range_difference_rows_closed_form() -> None:
    q = np.array([1.0, -2.0, 0.5])
    eta = np.array([0.01, 0.04])
    baselines = np.array([[-1.0, 1.0, 0.0], [0.0, 0.0, 1.4], [0.3, 0.2, -1.0]])
    H, R = range_difference_rows(q, baselines, eta)
    for i, q_s in enumerate(baselines):
        d1 = np.linalg.norm(q + q_s / 2)
        d2 = np.linalg.norm(q - q_s / 2)
        gamma = eta[0] * d1**2 + eta[1] * d2**2 + 0.5 * (eta[0] ** 2 + eta[1] ** 2)
        assert_allclose(R[i, 0, 0], gamma, rtol=1e-12)
        assert_allclose(H[i, 0], np.concatenate([q_s, np.zeros(3)]))


def test_range_difference_noise_does_not_depend_on_the_direction_for_equal_sonars() -> None:
    # d1² + d2² = 2|q|² + ½|q_s|²: only the direction of q_s carries the choice.
    rng = np.random.default_rng(6)
    baselines = math.sqrt(2.0) * random_unit(rng, 30)
    _, R = range_difference_rows(np.array([-2.0, -2.0, 0.3]), baselines, ETA)
    assert_allclose(R.ravel(), R.ravel()[0], rtol=1e-12)


def test_range_rows_are_the_range_jacobians() -> None:
    rng = np.random.default_rng(7)
    q = rng.normal(size=3) * 3
    baselines = rng.normal(size=(10, 3))
    H, R = range_rows(q, baselines, ETA, 4)
    for i, q_s in enumerate(baselines):
        assert_allclose(H[i], range_jacobian(np.concatenate([q, np.zeros(3)]), q_s), atol=1e-14)
        assert_allclose(R[i], np.diag(ETA / 4))


def test_posterior_equals_information_form_and_the_filters_update() -> None:
    rng = np.random.default_rng(8)
    P = random_spd(rng)
    q = np.array([-2.0, -1.5, 0.4])
    baselines = rng.normal(size=(5, 3))
    for rows in (range_difference_rows(q, baselines, ETA), range_rows(q, baselines, ETA, 1)):
        H, R = rows
        posterior = posterior_covariances(P, H, R)
        for i in range(len(baselines)):
            information = np.linalg.inv(P) + H[i].T @ np.linalg.solve(R[i], H[i])
            assert_allclose(posterior[i], np.linalg.inv(information), rtol=1e-8, atol=1e-12)
    # The same covariances as the filters' own updates (Joseph form there).
    x = np.concatenate([q, np.zeros(3)])
    H, R = range_difference_rows(q, baselines[:1], ETA)
    _, P_kf, _ = range_difference_update(x, P, 0.0, 0.0, R[0, 0, 0], baselines[0])
    assert_allclose(posterior_covariances(P, H, R)[0], P_kf, rtol=1e-9, atol=1e-12)
    H, R = range_rows(q, baselines[:1], ETA, 1)
    _, P_ekf, _ = ekf_update(x, P, np.ones(2), baselines[0], R[0])
    assert_allclose(posterior_covariances(P, H, R)[0], P_ekf, rtol=1e-9, atol=1e-12)


def test_criteria_on_each_block() -> None:
    rng = np.random.default_rng(9)
    P = np.array([random_spd(rng) for _ in range(4)])
    for block, size in (("position", 3), ("full", 6)):
        covariance = P[:, :size, :size]
        information = np.linalg.inv(covariance)
        assert_allclose(criterion_values(P, "d_optimal", block), np.log(np.linalg.det(information)))
        assert_allclose(
            criterion_values(P, "a_optimal", block), -np.trace(covariance, axis1=1, axis2=2)
        )
        assert_allclose(
            criterion_values(P, "e_optimal", block),
            np.linalg.eigvalsh(information)[:, 0],
            rtol=1e-9,
        )
    with pytest.raises(ValueError, match="criterion: .*'c_optimal'"):
        criterion_values(P, "c_optimal")
    with pytest.raises(ValueError, match="block: .*'velocity'"):
        criterion_values(P, "a_optimal", "velocity")


def test_horizon_scores_equal_an_explicit_rollout() -> None:
    rng = np.random.default_rng(10)
    P = random_spd(rng)
    x = np.concatenate([Q_STAR, [0.1, -0.2, 0.05]])
    R_WB = exp_so3(rng.normal(size=3))
    p = planner(horizon=3, criterion="d_optimal", position_prediction="coast")
    rotation = p.candidate_rotations(R_WB)[[0, 5, 40]]
    scores, first = p.horizon_scores(x, P, R_WB, rotation)
    A, _ = double_integrator(T)
    Q = process_noise_covariance(W, T)
    for i, phi in enumerate(rotation):
        covariance, total = P, 0.0
        for j in range(1, 4):
            q_s = exp_so3(j * phi) @ R_WB @ B
            q = x[:3] + j * T * x[3:]
            d1, d2 = np.linalg.norm(q + q_s / 2), np.linalg.norm(q - q_s / 2)
            gamma = 0.01 * (d1**2 + d2**2) + 0.01**2
            C = np.concatenate([q_s, np.zeros(3)])
            prior = A @ covariance @ A.T + Q
            covariance = np.linalg.inv(np.linalg.inv(prior) + np.outer(C, C) / gamma)
            total += -np.log(np.linalg.det(covariance[:3, :3]))
            if j == 1:
                assert_allclose(first[i], covariance, rtol=1e-8, atol=1e-12)
        assert_allclose(scores[i], total, rtol=1e-9)


# ------------------------------------------------------------------------- planner


@pytest.mark.parametrize("criterion", ["d_optimal", "a_optimal", "e_optimal"])
@pytest.mark.parametrize("budget", [0.2, 0.39, 1.2])
def test_one_step_isotropic_prior_turns_the_baseline_toward_the_least_known_axis(
    criterion: str, budget: float
) -> None:
    """With ``P(k|k) = σ² I`` the prior position block is ``σ²(1 + t²) I + (t⁴/4) W``: the
    target's largest acceleration variance (x) makes the x axis the least known. For one
    scalar measurement every criterion then increases with ``(u·e_x)²``, so the optimum in
    the cap is ``±e_x`` if the cap holds it, else the cap's boundary point on the geodesic
    toward the nearer of ``±e_x``. The choice must also beat every direction of an
    independent random sample of the cap (scored in information form)."""
    rng = np.random.default_rng(11)
    R_WB = exp_so3(np.array([0.3, -0.7, 0.4]))
    p = planner(criterion=criterion, max_angle_per_step=budget, excitation_floor=0.0)
    x = np.concatenate([Q_STAR, np.zeros(3)])
    step = p.plan(x, 0.5 * np.eye(6), R_WB, np.zeros((0, 3)))
    u0 = R_WB @ B / np.linalg.norm(B)
    chosen = step.baseline / np.linalg.norm(B)

    e_x = np.array([1.0, 0.0, 0.0]) * np.sign(u0[0])
    distance = angle_between(u0, e_x)
    if distance <= budget:
        expected = e_x
    else:
        axis = np.cross(u0, e_x) / np.linalg.norm(np.cross(u0, e_x))
        expected = exp_so3(axis * budget) @ u0
    spacing = min(budget, math.pi / 2) / p.grid_rings
    assert angle_between(chosen, expected) <= spacing

    A, _ = double_integrator(T)
    prior = A @ (0.5 * np.eye(6)) @ A.T + process_noise_covariance(W, T)

    def score(u: np.ndarray) -> float:
        q_s = np.linalg.norm(B) * u
        d1, d2 = np.linalg.norm(Q_STAR + q_s / 2), np.linalg.norm(Q_STAR - q_s / 2)
        C = np.concatenate([q_s, np.zeros(3)])
        post = np.linalg.inv(
            np.linalg.inv(prior) + np.outer(C, C) / (0.01 * (d1**2 + d2**2) + 1e-4)
        )
        block = post[:3, :3]
        return {
            "d_optimal": -np.log(np.linalg.det(block)),
            "a_optimal": -np.trace(block),
            "e_optimal": 1.0 / np.linalg.eigvalsh(block)[-1],
        }[criterion]

    samples = random_unit(rng, 4000)
    samples = samples[angle_between(samples, u0) <= min(budget, math.pi / 2)]
    best_sampled = max(score(u) for u in samples)
    assert score(chosen) >= best_sampled - 1e-3 * abs(best_sampled)
    assert np.linalg.norm(step.rotation_vector) <= budget + 1e-12


def test_anisotropic_prior_picks_the_largest_eigenvector_inside_the_cap() -> None:
    """A position prior with its largest variance along e_z, reachable within the budget:
    the D-optimal baseline is ``±e_z`` (to the grid's resolution)."""
    P = np.diag([0.1, 0.2, 3.0, 0.01, 0.01, 0.01])
    R_WB = exp_so3(np.array([0.5, 0.0, 0.0]))  # baseline tilted 0.35 rad out of the xy plane
    u0 = R_WB @ B / np.linalg.norm(B)
    budget = 1.4
    assert angle_between(u0, np.array([0.0, 0.0, np.sign(u0[2])])) < budget
    p = planner(criterion="d_optimal", max_angle_per_step=budget, excitation_floor=0.0)
    step = p.plan(np.concatenate([Q_STAR, np.zeros(3)]), P, R_WB, np.zeros((0, 3)))
    assert abs(step.baseline[2]) / np.linalg.norm(B) >= math.cos(budget / p.grid_rings)


def _run(p: InformationSeekingPlanner, seed: int, steps: int) -> np.ndarray:
    """The attitudes of a run of the planner on random estimates and covariances."""
    rng = np.random.default_rng(seed)
    R = [exp_so3(2.0 * rng.normal(size=3))]
    history: list[np.ndarray] = []
    for _ in range(steps):
        x = np.concatenate([3.0 * rng.normal(size=3), rng.normal(size=3)])
        previous = R[-2] if len(R) > 1 else None
        step = p.plan(x, random_spd(rng), R[-1], np.array(history[-p.history_length :]), previous)
        history.append(R[-1] @ B)
        R.append(step.R_next)
    return np.array(R)


@pytest.mark.parametrize(
    "options",
    [
        {"max_angle_per_step": 0.1},
        {"max_angle_per_step": 0.39, "measurement_model": "ranges"},
        {"max_angle_per_step": 2.5},  # clipped to π/2: no baseline line is farther
        {
            "max_angle_per_step": 0.3,
            "measurement_model": "ranges",
            "position_prediction": "reference",
            "desired_relative_position": Q_STAR,
        },
    ],
)
@pytest.mark.slow
def test_budget_is_never_exceeded_on_random_inputs(options: dict) -> None:
    p = planner(**options)
    angles = rotation_angles(_run(p, seed=12, steps=300))
    limit = min(options["max_angle_per_step"], math.pi / 2)
    if options.get("position_prediction") == "reference":
        limit = options["max_angle_per_step"]
    assert angles.max() <= limit + 1e-12
    assert angles.max() >= 0.9 * limit  # the budget is used, not avoided


@pytest.mark.parametrize("budget", [0.1, 0.2, 0.39])
@pytest.mark.parametrize("model", ["range_difference", "ranges"])
@pytest.mark.slow
def test_excitation_floor_holds_in_every_window_on_random_inputs(budget: float, model: str) -> None:
    """Random estimates each step (a new 'least known' direction every step, the hardest
    case for the floor); every window of N = 24 steps from the first has λ_min ≥ 1 m²."""
    p = planner(max_angle_per_step=budget, measurement_model=model)
    R = _run(p, seed=13, steps=400)
    low, _ = excitation_eigenvalues(R @ B, p.pe_window)
    assert len(low) == 401 - 24 + 1
    assert low.min() >= p.excitation_floor


def _riccati_run(p: InformationSeekingPlanner, steps: int = 300) -> np.ndarray:
    """The planner on the paper's KF covariance, the target held at R q* (a tracking loop)."""
    R, history, P = [np.eye(3)], [], np.eye(6)
    for _ in range(steps):
        q = R[-1] @ Q_STAR
        H, noise = p.measurement_rows(q, (R[-1] @ B)[np.newaxis])
        P = posterior_covariances(P, H, noise)[0]
        step = p.plan(np.concatenate([q, np.zeros(3)]), P, R[-1], np.array(history[-22:]))
        history.append(R[-1] @ B)
        R.append(step.R_next)
        P = p.predict_covariance(P)
    return np.array(R)


@pytest.mark.slow
def test_greedy_planning_alone_loses_excitation_and_the_floor_restores_it() -> None:
    """Why the floor exists: E-optimal greedy planning with 0.1 rad per step leaves a
    direction nearly unexcited for a whole window in the KF's own Riccati loop."""
    greedy = planner(criterion="e_optimal", max_angle_per_step=0.1, excitation_floor=0.0)
    low, _ = excitation_eigenvalues(_riccati_run(greedy, 500) @ B, 24)
    assert low.min() < 0.2
    floored = planner(criterion="e_optimal", max_angle_per_step=0.1)
    low, _ = excitation_eigenvalues(_riccati_run(floored, 500) @ B, 24)
    assert low.min() >= floored.excitation_floor


def test_reference_acceleration_limit_holds() -> None:
    limit = 1.5
    p = planner(
        max_angle_per_step=0.39, desired_relative_position=Q_STAR, max_reference_acceleration=limit
    )
    R = _run(p, seed=14, steps=300)
    r = R @ Q_STAR
    acceleration = np.linalg.norm(r[2:] - 2 * r[1:-1] + r[:-2], axis=1) / T**2
    # The first second difference follows the first step, chosen without R(k−1) and so
    # without the limit: after a full-budget first turn no candidate may meet it, and the
    # planner takes the least demanding one. From then on the limit holds.
    assert acceleration[1:].max() <= limit + 1e-9
    free = _run(planner(max_angle_per_step=0.39), seed=14, steps=300) @ Q_STAR
    assert (np.linalg.norm(free[2:] - 2 * free[1:-1] + free[:-2], axis=1) / T**2).max() > limit


def test_linear_start_plans_for_the_papers_y_on_the_sample_means() -> None:
    """A raw-range filter's linear start is the paper's KF on the means of f samples."""
    rng = np.random.default_rng(18)
    inputs = (
        rng.normal(size=6),
        random_spd(rng),
        exp_so3(rng.normal(size=3)),
        rng.normal(size=(22, 3)),
    )
    raw = InformationSeekingPlanner(
        T, B, W, ETA, 2, measurement_model="ranges", linear_start_position_variance=0.5
    )
    linear = InformationSeekingPlanner(T, B, W, ETA / 2, 1)
    assert_allclose(raw.plan(*inputs, linear_start=True).R_next, linear.plan(*inputs).R_next)
    assert not np.allclose(raw.plan(*inputs).R_next, linear.plan(*inputs).R_next)
    P = np.diag([0.15, 0.15, 0.15, 1.0, 1.0, 1.0])  # trace P_qq 0.45 m²
    assert raw.hands_over(P) and not raw.hands_over(2.0 * P)
    assert planner(linear_start_position_variance=0.5).hands_over(2.0 * P)  # a KF has no start


def test_plan_is_reproducible() -> None:
    rng = np.random.default_rng(15)
    inputs = (
        rng.normal(size=6),
        random_spd(rng),
        exp_so3(rng.normal(size=3)),
        rng.normal(size=(22, 3)),
    )
    p = planner(measurement_model="ranges")
    first, second = p.plan(*inputs), p.plan(*inputs)
    assert np.array_equal(first.R_next, second.R_next)
    assert np.array_equal(first.P_next, second.P_next)
    assert np.array_equal(_run(p, 16, 30), _run(p, 16, 30))


def test_reference_prediction_turns_the_target_with_the_body() -> None:
    p = planner(position_prediction="reference", desired_relative_position=Q_STAR, reference_lag=0)
    rng = np.random.default_rng(17)
    R_WB = exp_so3(rng.normal(size=3))
    rotation = rng.normal(size=(4, 3)) * 0.2
    q = p.predicted_positions(2, np.zeros(6), rotation, R_WB)
    assert_allclose(q, [exp_so3(2 * phi) @ R_WB @ Q_STAR for phi in rotation], atol=1e-12)
    lagged = planner(
        position_prediction="reference", desired_relative_position=Q_STAR, reference_lag=1
    )
    assert lagged.scored_horizon == 2
    assert_allclose(
        lagged.predicted_positions(1, np.zeros(6), rotation, R_WB),
        np.tile(R_WB @ Q_STAR, (4, 1)),
        atol=1e-12,
    )


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"time_step": 0.0}, r"time_step: must be > 0, got 0.0"),
        ({"baseline_B": [0.0, 0.0, 0.0]}, r"baseline_B: .*\[0.0, 0.0, 0.0\]"),
        ({"noise_variances": [0.01, -1.0]}, r"noise_variances: .*-1.0"),
        ({"samples_per_step": 0}, r"samples_per_step: .*got 0"),
        ({"measurement_model": "bearing"}, r"measurement_model: .*'bearing'"),
        ({"criterion": "t_optimal"}, r"criterion: .*'t_optimal'"),
        ({"horizon": 0}, r"horizon: .*got 0"),
        ({"max_angle_per_step": 0.0}, r"max_angle_per_step: must be in \(0, π\], got 0.0"),
        ({"max_angle_per_step": 4.0}, r"max_angle_per_step: .*got 4.0"),
        ({"pe_window": 2}, r"pe_window: .*got 2"),
        ({"excitation_floor": -1.0}, r"excitation_floor: must be ≥ 0, got -1.0"),
        ({"pe_lead": 22}, r"pe_lead: .*got 22"),
        ({"max_reference_acceleration": 2.0}, r"desired_relative_position: needed .*got None"),
        (
            {"max_reference_acceleration": -2.0, "desired_relative_position": Q_STAR},
            r"max_reference_acceleration: .*-2.0",
        ),
        ({"position_prediction": "reference"}, r"desired_relative_position: needed .*got None"),
        ({"position_prediction": "guess"}, r"position_prediction: .*'guess'"),
        ({"reference_lag": 2}, r"reference_lag: must be 0 or 1, got 2"),
        ({"grid_rings": 0}, r"grid_rings: .*got 0"),
        ({"linear_start_position_variance": 0.0}, r"linear_start_position_variance: .*got 0.0"),
    ],
)
def test_bad_parameters_name_the_parameter_and_the_value(options: dict, message: str) -> None:
    arguments = {
        "time_step": T,
        "baseline_B": B,
        "acceleration_covariance": W,
        "noise_variances": ETA,
    }
    arguments.update(options)
    with pytest.raises(ValueError, match=message):
        InformationSeekingPlanner(**arguments)


# --------------------------------------------------------------------- a batch of runs


PLANNER_VARIANTS = [
    {"criterion": "a_optimal"},
    {"criterion": "d_optimal", "block": "full", "horizon": 2, "position_prediction": "coast"},
    {"criterion": "e_optimal"},
    {"criterion": "e_optimal", "block": "full"},
    {"measurement_model": "ranges", "horizon": 2},
    {
        "measurement_model": "ranges",
        "position_prediction": "reference",
        "desired_relative_position": Q_STAR,
        "reference_lag": 1,
        "max_reference_acceleration": 1.0,
        "linear_start_position_variance": 0.5,
    },
]


@pytest.mark.parametrize("options", PLANNER_VARIANTS)
@pytest.mark.parametrize("linear_start", [False, True])
def test_horizon_scores_equal_the_numpy_rollout(options: dict, linear_start: bool) -> None:
    """The kernel's scores and first posteriors are the model's numpy rollout
    (:meth:`predicted_positions`, :meth:`measurement_rows`, :func:`posterior_covariances`,
    :func:`criterion_values`) for every model, criterion, block and prediction."""
    rng = np.random.default_rng(19)
    p = InformationSeekingPlanner(T, B, W, ETA, 2, **options)
    x = np.concatenate([Q_STAR + rng.normal(size=3), rng.normal(size=3)])
    P, R_WB = random_spd(rng), exp_so3(rng.normal(size=3))
    rotation = p.candidate_rotations(R_WB)
    scores, firsts = p.horizon_scores(x, P, R_WB, rotation, linear_start)
    expected, posterior = np.zeros(len(rotation)), P
    for j in range(1, p.scored_horizon + 1):
        q = p.predicted_positions(j, x, rotation, R_WB)
        H, noise = p.measurement_rows(q, rotate_vectors(j * rotation, R_WB @ B), linear_start)
        posterior = posterior_covariances(p.predict_covariance(posterior), H, noise)
        if j == 1:
            assert_allclose(firsts, posterior, rtol=1e-9, atol=1e-13)
        expected += criterion_values(posterior, p.criterion, p.block)
    assert_allclose(scores, expected, rtol=1e-9, atol=1e-12)


def _random_batch(rng: np.random.Generator, runs: int, kept: int = 22) -> tuple:
    """Inputs of ``runs`` runs differing in every branch (history length, R(k−1), start)."""
    x = np.concatenate([Q_STAR + rng.normal(size=(runs, 3)), rng.normal(size=(runs, 3))], 1)
    P = np.array([random_spd(rng) for _ in range(runs)])
    R = np.array([exp_so3(2.0 * rng.normal(size=3)) for _ in range(runs)])
    history = 1.4 * rng.normal(size=(runs, kept, 3))
    filled = np.array([(0, 1, 4, kept)[i % 4] for i in range(runs)], dtype=float)
    R_previous = np.array([exp_so3(rng.uniform(0.01, 0.8) * rng.normal(size=3)) @ r for r in R])
    known = np.array([float(i % 3 != 0) for i in range(runs)])
    linear = np.array([float(i % 2) for i in range(runs)])
    return x, P, R, history, filled, R_previous, known, linear


@pytest.mark.parametrize("options", PLANNER_VARIANTS)
def test_a_batch_plan_is_each_run_alone(options: dict) -> None:
    """``plan_runs`` of B runs is, bit for bit, ``plan`` of each run alone; the pair's second
    plan is ``plan`` from the first's ``R(k+1)``, ``P(k+1|k+1)`` and the history with q_s(k)."""
    p = InformationSeekingPlanner(T, B, W, ETA, 2, **options)
    inputs = _random_batch(np.random.default_rng(20), 8)
    x, P, R, history, filled, R_previous, known, linear = inputs
    batch, following = p.plan_pair_runs(*inputs)
    alone = p.plan_runs(*inputs)
    for name in ("rotation_vector", "R_next", "P_next", "score", "excitation"):
        np.testing.assert_array_equal(getattr(alone, name), getattr(batch, name))
    for i in range(len(x)):
        kept = history[i, len(history[i]) - int(filled[i]) :]
        step = p.plan(x[i], P[i], R[i], kept, R_previous[i] if known[i] else None, linear[i] > 0)
        np.testing.assert_array_equal(step.R_next, batch.R_next[i])
        np.testing.assert_array_equal(step.P_next, batch.P_next[i])
        np.testing.assert_array_equal(
            [step.score, step.excitation, step.reference_acceleration],
            [batch.score[i], batch.excitation[i], batch.reference_acceleration[i]],
        )
        x_next = x[i].copy()
        if p.position_prediction == "coast":
            x_next[:3] += T * x[i, 3:]
        following_linear = linear[i] > 0 and not p.hands_over(step.P_next)
        history_next = np.vstack([kept, R[i] @ B])[-p.history_length :]
        after = p.plan(x_next, step.P_next, step.R_next, history_next, R[i], following_linear)
        np.testing.assert_array_equal(after.R_next, following.R_next[i])


def test_a_nan_run_does_not_raise_or_touch_the_others() -> None:
    p = planner(max_reference_acceleration=1.0, desired_relative_position=Q_STAR)
    inputs = list(_random_batch(np.random.default_rng(21), 4))
    clean = p.plan_runs(*inputs)
    inputs[1] = inputs[1].copy()
    inputs[1][1, 2, 2] = np.nan  # P
    inputs[0] = inputs[0].copy()
    inputs[0][2, 0] = np.inf  # x̂
    inputs[2] = inputs[2].copy()
    inputs[2][3, 1, 1] = np.nan  # R(k)
    dirty = p.plan_runs(*inputs)
    np.testing.assert_array_equal(dirty.R_next[0], clean.R_next[0])
    assert np.isnan(dirty.R_next[3]).all()
