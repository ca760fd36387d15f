import numpy as np
from numpy.testing import assert_allclose

from drake_uuv.estimators import RangeDifferenceKalmanFilter
from drake_uuv.plants.double_integrator import double_integrator
from drake_uuv.testing import discrete_update, fixed_context

T = 0.5
W = np.diag([0.004, 0.001, 0.001])
x0 = np.array([0.3, -0.2, 0.1, 0.05, 0.0, -0.02])
P0 = np.diag([1.0, 2.0, 0.5, 0.3, 0.2, 0.1]) + 0.05


def make_filter() -> RangeDifferenceKalmanFilter:
    return RangeDifferenceKalmanFilter(T, W, x0, P0)


def inputs(**overrides: np.ndarray) -> dict[str, np.ndarray]:
    values = dict(
        Y=np.array([1.7]),
        m=np.array([0.004]),
        Gamma=np.array([0.3]),
        q_s=np.array([-0.6, 1.1, 0.5]),
        a_W=np.array([1.0, -3.0, 0.5]),
    )
    values.update(overrides)
    return values


def test_ports_and_feedthrough() -> None:
    kf = make_filter()
    sizes = {"Y": 1, "m": 1, "Gamma": 1, "q_s": 3, "a_W": 3}
    assert {n: kf.GetInputPort(n).size() for n in sizes} == sizes
    assert kf.GetOutputPort("x_hat").size() == 6 and kf.GetOutputPort("P").size() == 36
    x_hat = kf.GetOutputPort("x_hat").get_index()
    # The filtered estimate feeds through from the measurement, not from the control input.
    for name in ("Y", "m", "Gamma", "q_s"):
        assert kf.HasDirectFeedthrough(kf.GetInputPort(name).get_index(), x_hat)
    assert not kf.HasDirectFeedthrough(kf.GetInputPort("a_W").get_index(), x_hat)


def test_update_matches_the_information_form() -> None:
    """Filtered estimate against an independent formulation: the information filter."""
    kf = make_filter()
    u = inputs()
    context = fixed_context(kf, **u)
    C = np.concatenate([u["q_s"], np.zeros(3)])[None, :]
    gamma = u["Gamma"][0]
    information = np.linalg.inv(P0) + C.T @ C / gamma
    P_expected = np.linalg.inv(information)
    x_expected = P_expected @ (np.linalg.solve(P0, x0) + C[0] * (u["Y"][0] - u["m"][0]) / gamma)
    assert_allclose(kf.GetOutputPort("x_hat").Eval(context), x_expected, rtol=1e-12)
    P = kf.GetOutputPort("P").Eval(context).reshape(6, 6)
    assert_allclose(P, P_expected, rtol=1e-10, atol=1e-14)
    assert_allclose(P, P.T, atol=0)


def test_prediction_is_the_next_discrete_state() -> None:
    kf = make_filter()
    u = inputs()
    context = fixed_context(kf, **u)
    x = kf.GetOutputPort("x_hat").Eval(context)
    P = kf.GetOutputPort("P").Eval(context).reshape(6, 6)
    A, B = double_integrator(T)
    next_state = discrete_update(kf, context)
    assert_allclose(next_state[:6], A @ x + B @ u["a_W"], rtol=1e-14)
    assert_allclose(next_state[6:].reshape(6, 6), A @ P @ A.T + B @ W @ B.T, rtol=1e-13)


def test_a_measurement_along_the_baseline_only_informs_that_direction() -> None:
    kf = RangeDifferenceKalmanFilter(T, W, np.zeros(6), np.eye(6))
    context = fixed_context(kf, **inputs(q_s=np.array([1.0, 0.0, 0.0]), Y=[2.0], m=[0.0]))
    P = kf.GetOutputPort("P").Eval(context).reshape(6, 6)
    x = kf.GetOutputPort("x_hat").Eval(context)
    assert_allclose(np.diag(P)[1:], 1.0)  # y, z and the velocities are untouched
    assert P[0, 0] < 1.0
    assert_allclose(x, [2.0 / 1.3, 0, 0, 0, 0, 0])  # K = 1/(1 + Γ) with P = I, Γ = 0.3
