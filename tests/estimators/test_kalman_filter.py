"""The paper's KF LeafSystem alone: ports, the update against the information form, the
prediction, missing returns, the NIS gate and the two vehicle-motion formulations."""

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pydrake.systems.analysis import Simulator

from drake_uuv.estimators import EstimatorSetting, RangeDifferenceKalmanFilter, make_estimator
from drake_uuv.models.measurement import (
    DROPPED,
    GATED,
    OUT_OF_BEAM,
    OUT_OF_RANGE,
    VALID,
    range_difference_noise,
)
from drake_uuv.models.motion import double_integrator
from drake_uuv.scenario import PaperKf, ScenarioError, load_scenario
from drake_uuv.simulation import simulate
from drake_uuv.testing import discrete_update, fixed_context
from tests.conftest import ETA_UNEQUAL, T, W

x0 = np.array([0.3, -0.2, 0.1, 0.05, 0.0, -0.02])
P0 = np.diag([1.0, 2.0, 0.5, 0.3, 0.2, 0.1]) + 0.05
B_BODY = np.array([-0.6, 1.1, 0.5])
SETTING = EstimatorSetting(
    time_step=T, acceleration_covariance=W, noise_variances=ETA_UNEQUAL, baseline_B=B_BODY
)
# An attitude: 0.7 rad about a tilted axis, so q_s = R b differs from b.
_axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
_K = np.array([[0, -_axis[2], _axis[1]], [_axis[2], 0, -_axis[0]], [-_axis[1], _axis[0], 0]])
R_WB = np.eye(3) + np.sin(0.7) * _K + (1 - np.cos(0.7)) * _K @ _K
RANGES = np.array([3.1, 2.4])


def make_filter(**fields) -> RangeDifferenceKalmanFilter:
    config = PaperKf(initial_estimate=x0.tolist(), initial_covariance=P0.tolist(), **fields)
    return RangeDifferenceKalmanFilter(config, setting=SETTING)


def inputs(**overrides: np.ndarray) -> dict[str, np.ndarray]:
    values = dict(
        range_samples=RANGES,
        sonar_status=np.zeros(2),
        R_WB_nav=R_WB.ravel(),
        u1_W=np.array([1.0, -3.0, 0.5]),
    )
    values.update(overrides)
    return values


def papers_measurement(d: np.ndarray) -> tuple[float, float, float, np.ndarray]:
    """``(Y, m, Γ, C)`` by the paper's formulas, independently of the filter."""
    m, gamma = range_difference_noise("derived", ETA_UNEQUAL, d * d)
    C = np.concatenate([R_WB @ B_BODY, np.zeros(3)])
    return 0.5 * (d[0] ** 2 - d[1] ** 2), float(m), float(gamma), C


def test_ports_and_feedthrough() -> None:
    kf = make_filter()
    sizes = {"range_samples": 2, "sonar_status": 2, "R_WB_nav": 9, "u1_W": 3}
    inputs_ = [kf.get_input_port(i) for i in range(kf.num_input_ports())]
    assert {p.get_name(): p.size() for p in inputs_} == sizes
    outputs = {"x_TU_hat": 6, "P_TU": 36, "x_TU_prior": 6, "P_TU_prior": 36,
               "measurement_status": 1, "nis": 1}  # fmt: skip
    outputs_ = [kf.get_output_port(i) for i in range(kf.num_output_ports())]
    assert {p.get_name(): p.size() for p in outputs_} == outputs
    x_hat = kf.GetOutputPort("x_TU_hat").get_index()
    # The filtered estimate feeds through from the measurement, not from the control input.
    for name in ("range_samples", "sonar_status", "R_WB_nav"):
        assert kf.HasDirectFeedthrough(kf.GetInputPort(name).get_index(), x_hat)
    assert not kf.HasDirectFeedthrough(kf.GetInputPort("u1_W").get_index(), x_hat)
    # The prior depends on state only, so a sonar may point at it without an algebraic loop.
    x_prior = kf.GetOutputPort("x_TU_prior").get_index()
    assert not any(kf.HasDirectFeedthrough(i, x_prior) for i in range(kf.num_input_ports()))


def test_update_matches_the_information_form() -> None:
    """Filtered estimate against an independent formulation: the information filter, with Y,
    m, Γ from the paper's formulas and C = [(R b)ᵀ, 0]."""
    kf = make_filter()
    context = fixed_context(kf, **inputs())
    Y, m, gamma, C = papers_measurement(RANGES)
    information = np.linalg.inv(P0) + np.outer(C, C) / gamma
    P_expected = np.linalg.inv(information)
    x_expected = P_expected @ (np.linalg.solve(P0, x0) + C * (Y - m) / gamma)
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
    setting = EstimatorSetting(
        time_step=T, acceleration_covariance=W, noise_variances=ETA_UNEQUAL,
        baseline_B=np.array([1.0, 0.0, 0.0]),
    )  # fmt: skip
    kf = RangeDifferenceKalmanFilter(PaperKf(), setting=setting)
    context = fixed_context(kf, **inputs(R_WB_nav=np.eye(3).ravel()))
    P = kf.GetOutputPort("P_TU").Eval(context).reshape(6, 6)
    x = kf.GetOutputPort("x_TU_hat").Eval(context)
    assert_allclose(np.diag(P)[1:], 1.0)  # y, z and the velocities are untouched
    assert P[0, 0] < 1.0
    Y, m, gamma, _ = papers_measurement(RANGES)
    assert_allclose(x, [(Y - m) / (1.0 + gamma), 0, 0, 0, 0, 0])  # K = 1/(1 + Γ) with P = I


def test_update_reports_its_nis_and_status() -> None:
    kf = make_filter()
    context = fixed_context(kf, **inputs())
    Y, m, gamma, C = papers_measurement(RANGES)
    innovation = Y - C @ x0 - m
    S = C @ P0 @ C + gamma
    assert kf.GetOutputPort("nis").Eval(context)[0] == pytest.approx(innovation**2 / S)
    assert kf.GetOutputPort("measurement_status").Eval(context)[0] == VALID
    assert_allclose(kf.GetOutputPort("x_TU_prior").Eval(context), x0)


@pytest.mark.parametrize(
    "status, code", [((1, 0), DROPPED), ((0, 2), OUT_OF_BEAM), ((3, 1), OUT_OF_RANGE)]
)
def test_without_both_returns_the_filter_only_predicts(status: tuple[int, int], code: int) -> None:
    kf = make_filter()
    samples = np.where(np.array(status) == VALID, RANGES, np.nan)
    u = inputs(sonar_status=np.array(status, float), range_samples=samples)
    context = fixed_context(kf, **u)
    assert_allclose(kf.GetOutputPort("x_TU_hat").Eval(context), x0)
    assert_allclose(kf.GetOutputPort("P_TU").Eval(context).reshape(6, 6), P0)
    assert kf.GetOutputPort("measurement_status").Eval(context)[0] == code
    assert np.isnan(kf.GetOutputPort("nis").Eval(context)[0])
    A, B = double_integrator(T)
    assert_allclose(discrete_update(kf, context, group=0), A @ x0 + B @ u["u1_W"])


def test_nis_gate_rejects_an_outlier_and_passes_a_normal_measurement() -> None:
    gated = make_filter(gate_probability=0.99)
    threshold = 6.634896601021214  # χ²(1) quantile at 0.99
    _, m, gamma, C = papers_measurement(RANGES)
    d2 = RANGES[1]
    for sigmas, expected in ((1.0, VALID), (3.0, GATED)):  # NIS ≈ 1 passes, ≈ 9 is gated
        # d1 puts Y `sigmas` innovation standard deviations (Γ at RANGES) off the prediction.
        Y = C @ x0 + m + sigmas * np.sqrt(C @ P0 @ C + gamma)
        d = np.array([np.sqrt(2 * Y + d2**2), d2])
        _, _, gamma_d, _ = papers_measurement(d)
        nis = (Y - C @ x0 - m) ** 2 / (C @ P0 @ C + gamma_d)
        context = fixed_context(gated, **inputs(range_samples=d))
        assert gated.GetOutputPort("nis").Eval(context)[0] == pytest.approx(nis, rel=1e-12)
        assert gated.GetOutputPort("measurement_status").Eval(context)[0] == expected
        assert (nis > threshold) == (expected == GATED)
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
    kf = make_filter(vehicle_motion="navigation")
    assert (
        not kf.HasInputPort("u1_W") and kf.HasInputPort("p_WU_nav") and kf.HasInputPort("v_WU_nav")
    )
    u = inputs()
    del u["u1_W"]
    p, v = np.array([4.0, -1.0, 0.5]), np.array([0.3, 0.1, -0.2])
    # Initialization makes the stored offset Υ̂(0|−1) − X(0): the prior is x0 whatever X(0).
    context = fixed_context(kf, **u, p_WU_nav=p, v_WU_nav=v)
    Simulator(kf, context).Initialize()
    assert_allclose(kf.GetOutputPort("x_TU_prior").Eval(context), x0, rtol=1e-14)
    # The periodic update predicts the target: the next prior at a new vehicle state X(k+1).
    x_hat = kf.GetOutputPort("x_TU_hat").Eval(context)
    A, _ = double_integrator(T)
    context.SetDiscreteState(kf.EvalUniquePeriodicDiscreteUpdate(context))
    X = np.concatenate([p, v])
    X_next = X + np.array([0.1, 0.2, 0.3, 0.0, 0.1, 0.0])
    kf.GetInputPort("p_WU_nav").FixValue(context, X_next[:3])
    kf.GetInputPort("v_WU_nav").FixValue(context, X_next[3:])
    assert_allclose(
        kf.GetOutputPort("x_TU_prior").Eval(context), X_next - A @ (X - x_hat), rtol=1e-12
    )


@pytest.mark.parametrize(
    "fields, error, message",
    [
        (dict(vehicle_motion="gps"), ScenarioError,
         r"^estimator.vehicle_motion: must be one of commanded, navigation, got 'gps'"),
        (dict(noise_model="exact"), ScenarioError,
         r"^estimator.noise_model: must be one of derived, paper_printed, got 'exact'"),
        (dict(initial_covariance=(-np.eye(6)).tolist()), ScenarioError,
         r"^estimator.initial_covariance: must be positive definite, got \[\[-1.0"),
    ],
)  # fmt: skip
def test_bad_config_names_the_field(fields: dict, error: type, message: str) -> None:
    with pytest.raises(error, match=message):
        RangeDifferenceKalmanFilter(PaperKf(**fields), setting=SETTING)


@pytest.mark.parametrize(
    "setting, message",
    [
        (dict(time_step=0.0), r"^time_step: must be > 0, got 0.0"),
        (dict(noise_variances=[0.01, -1.0]), r"^noise_variances: must be two numbers > 0"),
        (dict(samples_per_step=0), r"^samples_per_step: must be an integer ≥ 1, got 0"),
        (dict(acceleration_covariance=np.eye(2)), r"^acceleration_covariance: must be a finite 3×3"),
    ],
)  # fmt: skip
def test_bad_setting_names_the_field(setting: dict, message: str) -> None:
    values = dict(time_step=T, acceleration_covariance=W, noise_variances=ETA_UNEQUAL)
    with pytest.raises(ValueError, match=message):
        EstimatorSetting(**{**values, **setting})
