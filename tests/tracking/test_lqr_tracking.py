"""The LQR tracking law: gain, feed-forward, eigenvalues, acceleration limit, the attitude plan."""

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pydrake.math import RollPitchYaw, RotationMatrix
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, LeafSystem
from pydrake.systems.primitives import Adder, ConstantVectorSource, LogVectorOutput, Multiplexer

from drake_uuv.attitude import TrajectoryAttitudeGenerator, attitude_setting
from drake_uuv.diagram import make_uuv_diagram
from drake_uuv.models.motion import double_integrator
from drake_uuv.models.so3 import exp_so3
from drake_uuv.models.tracking_laws import (
    closed_loop_eigenvalues,
    lqr_gain,
    paper_gain_matrix,
    reference_feedforward,
    saturate_norm,
)
from drake_uuv.plants import KinematicUuvPlant, PlantSetting
from drake_uuv.scenario import (
    KinematicUuv,
    Scenario,
    ScenarioError,
    TrajectoryAttitude,
    load_scenario,
)
from drake_uuv.simulation import ClosedLoopSimulation
from drake_uuv.testing import fixed_context
from drake_uuv.tracking import LqrTrackingController, PaperTrackingController
from tests.conftest import T
from tests.tracking.controllers import lqr_controller, paper_controller

#: The paper's attitude setting: t, the baseline b = [−1, 1, 0].
ATTITUDE = attitude_setting(load_scenario("paper"))
q_star = np.array([-2.0, -2.0, 0.0])
R = RotationMatrix(RollPitchYaw(0.1, 0.5, -0.8)).matrix()
WEIGHTS = (1.0, 0.25, 0.1)  # the shipped defaults


def riccati_by_iteration(
    A: np.ndarray, B: np.ndarray, Q: np.ndarray, Rw: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The DARE's stabilising solution by iterating the Riccati recursion from S = Q."""
    S = Q.copy()
    for _ in range(10_000):
        gain = np.linalg.solve(Rw + B.T @ S @ B, B.T @ S @ A)
        S_next = Q + A.T @ S @ (A - B @ gain)
        if np.max(np.abs(S_next - S)) < 1e-14 * np.max(np.abs(S)):
            break
        S = 0.5 * (S_next + S_next.T)
    else:
        raise AssertionError("Riccati recursion did not converge")
    return np.linalg.solve(Rw + B.T @ S @ B, B.T @ S @ A), S


def lqr_scenario(*overrides: str) -> Scenario:
    return load_scenario("paper", ["tracking=!LqrTracking", *overrides])


# ----------------------------------------------------------------------------- the gain


@pytest.mark.parametrize("weights", [WEIGHTS, (1.0, 0.0, 1.0), (4.0, 2.0, 0.01), (0.1, 0.0, 3)])
def test_gain_matches_an_independent_dare_solution(weights: tuple[float, float, float]) -> None:
    K, S = lqr_gain(T, *weights)
    A, B = double_integrator(T)
    wp, wv, wa = weights
    K_ref, S_ref = riccati_by_iteration(A, B, np.diag([wp] * 3 + [wv] * 3), wa * np.eye(3))
    assert K.shape == (3, 6)
    assert_allclose(K, K_ref, rtol=1e-8, atol=1e-10)
    assert_allclose(S, S_ref, rtol=1e-8, atol=1e-10)


def test_closed_loop_eigenvalues_lie_inside_the_unit_circle() -> None:
    eigenvalues = closed_loop_eigenvalues(T, lqr_gain(T, *WEIGHTS)[0])
    assert eigenvalues.shape == (6,)
    assert np.max(np.abs(eigenvalues)) < 1.0
    for weights in [(1.0, 0.0, 1e-4), (1.0, 10.0, 100.0), (1e-3, 0.0, 1.0)]:
        assert np.max(np.abs(closed_loop_eigenvalues(T, lqr_gain(T, *weights)[0]))) < 1.0


def test_papers_law_has_eigenvalues_one_minus_alpha_and_minus_one() -> None:
    """The paper's velocity mode sits on the unit circle: it is never damped."""
    eigenvalues = closed_loop_eigenvalues(T, paper_gain_matrix(T, 1.2))
    assert_allclose(sorted(eigenvalues.real), [-1, -1, -1, -0.2, -0.2, -0.2], atol=1e-12)
    assert_allclose(eigenvalues.imag, 0, atol=1e-12)


def test_metrics_report_the_spectral_radius() -> None:
    metrics = ClosedLoopSimulation(lqr_scenario("steps=40", "steady_state_start=20")).run().metrics
    assert metrics["tracking_spectral_radius"] == pytest.approx(
        np.max(np.abs(closed_loop_eigenvalues(T, lqr_gain(T, *WEIGHTS)[0])))
    )


# ------------------------------------------------------------------- the law, one step


def test_ports_are_the_paper_controllers_plus_the_plan() -> None:
    controller = lqr_controller(q_star)
    paper = paper_controller(q_star, 1.2)
    for i in range(paper.num_input_ports()):
        name = paper.get_input_port(i).get_name()
        assert controller.GetInputPort(name).size() == paper.get_input_port(i).size()
    assert controller.GetInputPort("R_WB_plan").size() == 18
    assert controller.GetOutputPort("u1_B").size() == 3
    assert controller.GetOutputPort("u1_W").size() == 3
    # Static: no state, hence nothing that could wind up under the acceleration limit.
    assert controller.num_discrete_state_groups() == 0
    assert controller.num_continuous_states() == 0


def test_one_step_is_the_closed_form_law() -> None:
    R1 = exp_so3(np.array([0.1, -0.2, 0.3])) @ R
    R2 = exp_so3(np.array([0.0, 0.3, 0.1])) @ R1
    x_hat = np.array([0.4, -1.0, 3.0, 0.2, -0.1, 0.05])
    controller = lqr_controller(q_star)
    context = fixed_context(
        controller, x_TU_hat=x_hat, R_WB_nav=R.ravel(), R_WB_plan=np.r_[R1.ravel(), R2.ravel()]
    )
    r0, r1, r2 = R @ q_star, R1 @ q_star, R2 @ q_star
    nu = (-3 * r0 + 4 * r1 - r2) / (2 * T)
    a_ff = (r0 - 2 * r1 + r2) / T**2
    K, _ = lqr_gain(T, *WEIGHTS)
    a = a_ff - K @ (x_hat - np.r_[r0, nu])
    assert_allclose(controller.GetOutputPort("u1_W").Eval(context), a, rtol=1e-12)
    assert_allclose(controller.GetOutputPort("u1_B").Eval(context), R.T @ a, rtol=1e-12)


def test_feedforward_lands_on_the_next_point_and_its_residual_is_the_third_difference() -> None:
    rng = np.random.default_rng(3)
    A, B = double_integrator(T)
    r = rng.normal(size=(4, 3))
    x_ref, a_ff = reference_feedforward(r[0], r[1], r[2], T)
    x_next, _ = reference_feedforward(r[1], r[2], r[3], T)
    predicted = A @ x_ref + B @ a_ff
    assert_allclose(predicted[:3], r[1], atol=1e-12)
    third_difference = r[3] - 3 * r[2] + 3 * r[1] - r[0]
    assert_allclose(predicted[3:] - x_next[3:], third_difference / (2 * T), atol=1e-12)


def test_perfect_knowledge_on_a_quadratic_reference_converges_to_zero() -> None:
    """Closed form on the double integrator: a reference quadratic in k is tracked exactly."""
    A, B = double_integrator(T)
    K, _ = lqr_gain(T, *WEIGHTS)
    c0, c1, c2 = np.array([1.0, -2, 0.5]), np.array([0.3, 0.1, -0.2]), np.array([0.02, -0.01, 0])

    def r(k: int) -> np.ndarray:
        return c0 + c1 * k + c2 * k * k

    x = np.zeros(6)
    errors = []
    for k in range(80):
        x_ref, a_ff = reference_feedforward(r(k), r(k + 1), r(k + 2), T)
        x = A @ x + B @ (a_ff - K @ (x - x_ref))
        errors.append(np.linalg.norm(x[:3] - r(k + 1)))
    assert errors[0] > 0.1
    assert max(errors[60:]) < 1e-9


def test_acceleration_limit_keeps_the_direction() -> None:
    a = np.array([3.0, -4.0, 12.0])
    assert_allclose(saturate_norm(a, 6.5), a / 2)
    assert_allclose(saturate_norm(a, 20.0), a)
    assert saturate_norm(a, None) is a


# ----------------------------------------------------- perfect state knowledge, in Drake


def run_with_perfect_knowledge(
    controller: LeafSystem,
    steps: int,
    rho: float = 1 / 24,
    h_amplitude: float = 0.5,
    h_frequency: float = 1 / 6,
) -> dict[str, np.ndarray]:
    """Vehicle, Algorithm 2 and ``controller`` fed the true relative state (a still target).

    With the target at rest and no noise, ``x_hat = [p − p̄, v]`` is the true relative state.
    """
    builder = DiagramBuilder()
    at_rest = PlantSetting(T, np.zeros(3), np.zeros(3), np.eye(3))
    uuv = builder.AddSystem(KinematicUuvPlant(KinematicUuv(), setting=at_rest))
    algorithm_2 = TrajectoryAttitude(rho=rho, h_amplitude=h_amplitude, h_frequency=h_frequency)
    attitude = builder.AddSystem(TrajectoryAttitudeGenerator(algorithm_2, setting=ATTITUDE))
    builder.AddSystem(controller)
    target = builder.AddSystem(ConstantVectorSource(-np.r_[1.0, 2.0, 2.0, 0, 0, 0]))
    relative = builder.AddSystem(Adder(2, 6))
    state = builder.AddSystem(Multiplexer([3, 3]))
    connect = builder.Connect
    connect(uuv.GetOutputPort("p_WU"), state.get_input_port(0))
    connect(uuv.GetOutputPort("v_WU"), state.get_input_port(1))
    connect(state.get_output_port(), relative.get_input_port(0))
    connect(target.get_output_port(), relative.get_input_port(1))
    connect(relative.get_output_port(), controller.GetInputPort("x_TU_hat"))
    connect(uuv.GetOutputPort("R_WB"), controller.GetInputPort("R_WB_nav"))
    connect(uuv.GetOutputPort("R_WB"), attitude.GetInputPort("R_WB_nav"))
    if controller.HasInputPort("R_WB_plan"):
        connect(attitude.GetOutputPort("R_WB_plan"), controller.GetInputPort("R_WB_plan"))
    connect(controller.GetOutputPort("u1_B"), uuv.GetInputPort("u1_B"))
    connect(attitude.GetOutputPort("u2_W"), uuv.GetInputPort("u2_W"))
    logs = {
        "x": LogVectorOutput(relative.get_output_port(), builder, T),
        "R": LogVectorOutput(uuv.GetOutputPort("R_WB"), builder, T),
        "a": LogVectorOutput(controller.GetOutputPort("u1_W"), builder, T),
    }
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo((steps - 1) * T)
    data = {k: v.FindLog(simulator.get_context()).data().T[:steps] for k, v in logs.items()}
    reference = data["R"].reshape(-1, 3, 3) @ q_star
    return {
        "error": np.linalg.norm(data["x"][:, :3] - reference, axis=1),
        "speed": np.linalg.norm(data["x"][:, 3:], axis=1),
        "acceleration": np.linalg.norm(data["a"], axis=1),
        "reference": reference,
    }


def residual_gain(K: np.ndarray) -> float:
    """``Σ_j ‖[(A − BK)^j]_{q,ϑ}‖₂``: bounds |e| by this times the largest velocity residual."""
    A, B = double_integrator(T)
    A_cl, power, total = A - B @ K, np.eye(6), 0.0
    for _ in range(500):
        total += np.linalg.norm(power[:3, 3:], 2)
        power = power @ A_cl
    return total


def test_perfect_knowledge_follows_a_smooth_algorithm_2_plan() -> None:
    """A slow Algorithm 2 plan: the error converges to within the feed-forward residual."""
    steps, slow_plan = 300, (1 / 480, 0.3, 1 / 120)
    run = run_with_perfect_knowledge(lqr_controller(q_star), steps, *slow_plan)
    r = run["reference"]
    residual = np.max(np.linalg.norm(r[3:] - 3 * r[2:-1] + 3 * r[1:-2] - r[:-3], axis=1)) / (2 * T)
    bound = residual_gain(lqr_gain(T, *WEIGHTS)[0]) * residual
    assert run["error"][0] > 2.0  # starts ~3 m away
    assert np.max(run["error"][100:]) <= bound + 1e-9
    assert np.max(run["error"][100:]) < 1e-3
    # Bounded velocity: after the approach, no faster than the reference itself (+ 1 %).
    reference_speed = np.linalg.norm(np.diff(r, axis=0), axis=1) / T
    assert np.max(run["speed"][100:]) <= 1.01 * np.max(reference_speed) + 1e-6


def test_perfect_knowledge_on_the_papers_plan_stays_bounded_unlike_the_papers_law() -> None:
    steps = 300
    lqr = run_with_perfect_knowledge(lqr_controller(q_star), steps)
    paper = run_with_perfect_knowledge(paper_controller(q_star, 1.2), steps)
    r = lqr["reference"]
    residual = np.max(np.linalg.norm(r[3:] - 3 * r[2:-1] + 3 * r[1:-2] - r[:-3], axis=1)) / (2 * T)
    assert np.max(lqr["error"][50:]) <= residual_gain(lqr_gain(T, *WEIGHTS)[0]) * residual
    reference_speed = np.linalg.norm(np.diff(r, axis=0), axis=1) / T
    assert np.max(lqr["speed"][50:]) < np.max(reference_speed)  # 7.6 m/s
    assert np.max(lqr["acceleration"][50:]) < 20.0
    # The paper's law resonates with the plan: its alternating velocity keeps growing.
    assert np.max(paper["speed"][250:]) > 5 * np.max(lqr["speed"][50:])
    assert np.max(paper["speed"][250:]) > 1.5 * np.max(paper["speed"][50:100])


def test_without_feedforward_the_law_lags() -> None:
    lagging = lqr_controller(q_star, feedforward=False)
    run = run_with_perfect_knowledge(lagging, 300, 1 / 480, 0.3, 1 / 120)
    assert np.min(run["error"][100:]) > 1e-3


# -------------------------------------------------------------------- the closed loop


@pytest.mark.parametrize("law", ["LqrTracking", "PaperTracking"])
@pytest.mark.slow
def test_acceleration_limit_is_never_exceeded(law: str) -> None:
    limit = 7.0
    scenario = load_scenario(
        "paper", [f"tracking=!{law}", f"tracking.max_acceleration={limit}"], seed=4
    )
    log = ClosedLoopSimulation(scenario).run().log
    applied = np.linalg.norm(log["u1_W"], axis=1)
    assert np.max(applied) <= limit + 1e-12
    assert np.max(np.linalg.norm(log["u1_B"], axis=1)) <= limit + 1e-12
    assert np.sum(applied > limit - 1e-9) >= 3  # the limit was active
    # The vehicle moved with the saturated acceleration (the filter saw the same one).
    assert_allclose(log["v_WU"][1:], log["v_WU"][:-1] + T * log["u1_W"][:-1], atol=1e-9)


def test_diagram_picks_the_law_by_variant() -> None:
    built = make_uuv_diagram(lqr_scenario())
    controller = built.systems["tracking_controller"]
    assert isinstance(controller, LqrTrackingController)
    assert_allclose(controller.gain, lqr_gain(T, *WEIGHTS)[0])
    paper = make_uuv_diagram(load_scenario("paper")).systems["tracking_controller"]
    assert isinstance(paper, PaperTrackingController)
    assert_allclose(paper.gain, paper_gain_matrix(T, 1.2))


@pytest.mark.slow
def test_lqr_closed_loop_is_smooth_and_tracks() -> None:
    """One seeded paper-scenario run: a far smaller acceleration than the paper's law."""
    lqr = ClosedLoopSimulation(lqr_scenario()).run(seed=1).metrics
    paper = ClosedLoopSimulation(load_scenario("paper")).run(seed=1).metrics
    assert lqr["acceleration_mean"] < 0.05 * paper["acceleration_mean"]
    assert lqr["relative_speed_peak"] < 10.0
    assert lqr["tracking_rmse"] < paper["tracking_rmse"]


# ------------------------------------------------------------------------ the scenario


def test_shipped_scenario_holds_the_defaults() -> None:
    assert load_scenario("paper").tracking == Scenario().tracking
    assert lqr_scenario().tracking.position_weight == WEIGHTS[0]


@pytest.mark.parametrize(
    "override, message",
    [
        ("tracking.position_weight=0", r"^tracking.position_weight: must be > 0, got 0"),
        ("tracking.velocity_weight=-1", r"^tracking.velocity_weight: must be ≥ 0, got -1"),
        ("tracking.input_weight=0.0", r"^tracking.input_weight: must be > 0, got 0.0"),
        ("tracking.max_acceleration=-7", r"^tracking.max_acceleration: must be > 0, got -7"),
        ("tracking.max_acceleration=fast", r"^tracking.max_acceleration: must be a number"),
        ("tracking.feedforward=1", r"^tracking.feedforward: must be true or false"),
        ("tracking.alpha=1", r"^tracking.alpha: unknown field 'alpha' in 'tracking' \(fields of LqrTracking: "),
    ],
)  # fmt: skip
def test_bad_tracking_fields_are_named(override: str, message: str) -> None:
    with pytest.raises(ScenarioError, match=message):
        load_scenario("paper", ["tracking=!LqrTracking", override])
