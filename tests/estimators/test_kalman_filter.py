"""The paper's KF LeafSystem alone: ports, the update against the information form, the
prediction, missing returns and the NIS gate."""

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pydrake.systems.analysis import Simulator

from drake_uuv.estimators import RangeDifferenceKalmanFilter, make_estimator
from drake_uuv.models.measurement import DROPPED, GATED, OUT_OF_BEAM, OUT_OF_RANGE, VALID
from drake_uuv.models.motion import double_integrator
from drake_uuv.scenario import load_scenario
from drake_uuv.simulation import simulate
from drake_uuv.testing import discrete_update, fixed_context
from tests.conftest import T, W

x0 = np.array([0.3, -0.2, 0.1, 0.05, 0.0, -0.02])
P0 = np.diag([1.0, 2.0, 0.5, 0.3, 0.2, 0.1]) + 0.05


def make_filter() -> RangeDifferenceKalmanFilter:
    return RangeDifferenceKalmanFilter(T, W, x0, P0)


def inputs(**overrides: np.ndarray) -> dict[str, np.ndarray]:
    values = dict(
        Y=np.array([1.7]),
        m=np.array([0.004]),
        Gamma=np.array([0.3]),
        b_W=np.array([-0.6, 1.1, 0.5]),
        u1_W=np.array([1.0, -3.0, 0.5]),
        sonar_status=np.zeros(2),
    )
    values.update(overrides)
    return values


def test_ports_and_feedthrough() -> None:
    kf = make_filter()
    sizes = {"Y": 1, "m": 1, "Gamma": 1, "b_W": 3, "sonar_status": 2, "u1_W": 3}
    inputs_ = [kf.get_input_port(i) for i in range(kf.num_input_ports())]
    assert {p.get_name(): p.size() for p in inputs_} == sizes
    outputs = {"x_TU_hat": 6, "P_TU": 36, "x_TU_prior": 6, "P_TU_prior": 36,
               "measurement_status": 1, "nis": 1}  # fmt: skip
    outputs_ = [kf.get_output_port(i) for i in range(kf.num_output_ports())]
    assert {p.get_name(): p.size() for p in outputs_} == outputs
    x_hat = kf.GetOutputPort("x_TU_hat").get_index()
    # The filtered estimate feeds through from the measurement, not from the control input.
    for name in ("Y", "m", "Gamma", "b_W"):
        assert kf.HasDirectFeedthrough(kf.GetInputPort(name).get_index(), x_hat)
    assert not kf.HasDirectFeedthrough(kf.GetInputPort("u1_W").get_index(), x_hat)
    # The prior depends on state only, so a sonar may point at it without an algebraic loop.
    x_prior = kf.GetOutputPort("x_TU_prior").get_index()
    assert not any(kf.HasDirectFeedthrough(i, x_prior) for i in range(kf.num_input_ports()))


def test_update_matches_the_information_form() -> None:
    """Filtered estimate against an independent formulation: the information filter."""
    kf = make_filter()
    u = inputs()
    context = fixed_context(kf, **u)
    C = np.concatenate([u["b_W"], np.zeros(3)])[None, :]
    gamma = u["Gamma"][0]
    information = np.linalg.inv(P0) + C.T @ C / gamma
    P_expected = np.linalg.inv(information)
    x_expected = P_expected @ (np.linalg.solve(P0, x0) + C[0] * (u["Y"][0] - u["m"][0]) / gamma)
    assert_allclose(kf.GetOutputPort("x_TU_hat").Eval(context), x_expected, rtol=1e-12)
    P = kf.GetOutputPort("P_TU").Eval(context).reshape(6, 6)
    assert_allclose(P, P_expected, rtol=1e-10, atol=1e-14)
    assert_allclose(P, P.T, atol=0)


def test_prediction_is_the_next_discrete_state() -> None:
    kf = make_filter()
    u = inputs()
    context = fixed_context(kf, **u)
    x = kf.GetOutputPort("x_TU_hat").Eval(context)
    P = kf.GetOutputPort("P_TU").Eval(context).reshape(6, 6)
    A, B = double_integrator(T)
    assert_allclose(discrete_update(kf, context, group=0), A @ x + B @ u["u1_W"], rtol=1e-14)
    P_next = discrete_update(kf, context, group=1).reshape(6, 6)
    assert_allclose(P_next, A @ P @ A.T + B @ W @ B.T, rtol=1e-13)


def test_a_measurement_along_the_baseline_only_informs_that_direction() -> None:
    kf = RangeDifferenceKalmanFilter(T, W, np.zeros(6), np.eye(6))
    context = fixed_context(kf, **inputs(b_W=np.array([1.0, 0.0, 0.0]), Y=[2.0], m=[0.0]))
    P = kf.GetOutputPort("P_TU").Eval(context).reshape(6, 6)
    x = kf.GetOutputPort("x_TU_hat").Eval(context)
    assert_allclose(np.diag(P)[1:], 1.0)  # y, z and the velocities are untouched
    assert P[0, 0] < 1.0
    assert_allclose(x, [2.0 / 1.3, 0, 0, 0, 0, 0])  # K = 1/(1 + Γ) with P = I, Γ = 0.3


def test_update_reports_its_nis_and_status() -> None:
    kf = make_filter()
    u = inputs()
    context = fixed_context(kf, **u)
    C = np.concatenate([u["b_W"], np.zeros(3)])
    innovation = u["Y"][0] - C @ x0 - u["m"][0]
    S = C @ P0 @ C + u["Gamma"][0]
    assert kf.GetOutputPort("nis").Eval(context)[0] == pytest.approx(innovation**2 / S)
    assert kf.GetOutputPort("measurement_status").Eval(context)[0] == VALID
    assert_allclose(kf.GetOutputPort("x_TU_prior").Eval(context), x0)


@pytest.mark.parametrize(
    "status, code", [((1, 0), DROPPED), ((0, 2), OUT_OF_BEAM), ((3, 1), OUT_OF_RANGE)]
)
def test_without_both_returns_the_filter_only_predicts(status: tuple[int, int], code: int) -> None:
    kf = make_filter()
    u = inputs(sonar_status=np.array(status, float), Y=np.array([np.nan]))
    context = fixed_context(kf, **u)
    assert_allclose(kf.GetOutputPort("x_TU_hat").Eval(context), x0)
    assert_allclose(kf.GetOutputPort("P_TU").Eval(context).reshape(6, 6), P0)
    assert kf.GetOutputPort("measurement_status").Eval(context)[0] == code
    assert np.isnan(kf.GetOutputPort("nis").Eval(context)[0])
    A, B = double_integrator(T)
    assert_allclose(discrete_update(kf, context, group=0), A @ x0 + B @ u["u1_W"])


def test_nis_gate_rejects_an_outlier_and_passes_a_normal_measurement() -> None:
    gated = RangeDifferenceKalmanFilter(T, W, x0, P0, gate_probability=0.99)
    C = np.concatenate([inputs()["b_W"], np.zeros(3)])
    S = C @ P0 @ C + 0.3
    threshold = 6.634896601021214  # χ²(1) quantile at 0.99
    for sigmas, expected in ((1.0, VALID), (3.0, GATED)):  # 1σ passes; 3σ (NIS 9) is gated
        Y = C @ x0 + 0.004 + sigmas * np.sqrt(S)
        context = fixed_context(gated, **inputs(Y=np.array([Y])))
        assert gated.GetOutputPort("measurement_status").Eval(context)[0] == expected
        assert gated.GetOutputPort("nis").Eval(context)[0] == pytest.approx(sigmas**2)
        assert (sigmas**2 > threshold) == (expected == GATED)
        if expected == GATED:
            assert_allclose(gated.GetOutputPort("x_TU_hat").Eval(context), x0)
    assert gated.gate_threshold(1) == pytest.approx(threshold, rel=1e-9)


def test_factory_builds_the_papers_kf_with_the_scenarios_prior() -> None:
    scenario = load_scenario("paper", ["estimator.gate_probability=0.9"])
    kf = make_estimator(scenario)
    assert isinstance(kf, RangeDifferenceKalmanFilter)
    context = kf.CreateDefaultContext()
    assert_allclose(kf.GetOutputPort("x_TU_prior").Eval(context), np.zeros(6))
    assert_allclose(kf.GetOutputPort("P_TU_prior").Eval(context).reshape(6, 6), np.eye(6))
    assert kf.gate_threshold(1) == pytest.approx(2.705543454095404, rel=1e-9)  # χ²(1) at 0.9


def test_navigation_and_commanded_motion_agree_on_the_kinematic_vehicle() -> None:
    """Two formulations of the prediction: with the commanded acceleration (the paper's) and
    from the vehicle's known state (predicting the target). The kinematic vehicle moves
    exactly as commanded, so the two filters' estimates agree over a whole run."""
    common = ["steps=200", "steady_state_start=50"]
    commanded = simulate(load_scenario("paper", common, seed=2)).log
    navigation = simulate(
        load_scenario("paper", [*common, "estimator.vehicle_motion=navigation"], seed=2)
    ).log
    assert_allclose(navigation["x_TU_hat"], commanded["x_TU_hat"], rtol=1e-9, atol=1e-9)
    assert_allclose(navigation["P_TU"], commanded["P_TU"], rtol=1e-9, atol=1e-12)


def test_navigation_prediction_is_the_targets() -> None:
    """One step alone: X̄(k+1|k) = A (X(k) − Υ̂(k|k)), Υ̂(k+1|k) = X(k+1) − X̄(k+1|k)."""
    kf = RangeDifferenceKalmanFilter(T, W, x0, P0, vehicle_motion="navigation")
    assert not kf.HasInputPort("u1_W") and kf.HasInputPort("p_WU") and kf.HasInputPort("v_WU")
    u = inputs()
    del u["u1_W"]
    p, v = np.array([4.0, -1.0, 0.5]), np.array([0.3, 0.1, -0.2])
    # Initialization makes the stored offset Υ̂(0|−1) − X(0): the prior is x0 whatever X(0).
    kf_start = RangeDifferenceKalmanFilter(T, W, x0, P0, vehicle_motion="navigation")
    start = fixed_context(kf_start, **u, p_WU=p, v_WU=v)
    Simulator(kf_start, start).Initialize()
    assert_allclose(kf_start.GetOutputPort("x_TU_prior").Eval(start), x0, rtol=1e-14)
    # The periodic update predicts the target: the next prior at a new vehicle state X(k+1).
    x_hat = kf_start.GetOutputPort("x_TU_hat").Eval(start)
    A, _ = double_integrator(T)
    start.SetDiscreteState(kf_start.EvalUniquePeriodicDiscreteUpdate(start))
    X = np.concatenate([p, v])
    X_next = X + np.array([0.1, 0.2, 0.3, 0.0, 0.1, 0.0])
    kf_start.GetInputPort("p_WU").FixValue(start, X_next[:3])
    kf_start.GetInputPort("v_WU").FixValue(start, X_next[3:])
    assert_allclose(
        kf_start.GetOutputPort("x_TU_prior").Eval(start), X_next - A @ (X - x_hat), rtol=1e-12
    )
    with pytest.raises(
        ValueError, match=r"^vehicle_motion: must be one of commanded, navigation, got 'gps'"
    ):
        RangeDifferenceKalmanFilter(T, W, x0, P0, vehicle_motion="gps")
