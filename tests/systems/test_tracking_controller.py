import numpy as np
from numpy.testing import assert_allclose
from pydrake.math import RollPitchYaw, RotationMatrix

from drake_uuv.controllers import TrackingController
from drake_uuv.testing import fixed_context

T, ALPHA = 0.5, 1.2
q_star = np.array([-2.0, -2.0, 0.0])
R = RotationMatrix(RollPitchYaw(0.1, 0.5, -0.8)).matrix()
x_hat = np.array([0.4, -1.0, 3.0, 0.2, -0.1, 0.05])


def test_ports() -> None:
    controller = TrackingController(T, ALPHA, q_star)
    assert controller.GetInputPort("x_hat").size() == 6
    assert controller.GetInputPort("R_WB").size() == 9
    assert controller.GetOutputPort("u1_B").size() == 3
    assert controller.GetOutputPort("a_W").size() == 3


def test_papers_law() -> None:
    controller = TrackingController(T, ALPHA, q_star)
    context = fixed_context(controller, x_hat=x_hat, R_WB=R.ravel())
    u1 = -(2 * ALPHA / T**2) * (R.T @ x_hat[:3] - q_star) - (2 / T) * R.T @ x_hat[3:]
    assert_allclose(controller.GetOutputPort("u1_B").Eval(context), u1, rtol=1e-14)
    assert_allclose(controller.GetOutputPort("a_W").Eval(context), R @ u1, rtol=1e-14)


def test_tracking_error_contracts_by_one_minus_alpha_with_perfect_knowledge() -> None:
    """With q̂ = q, ϑ̂ = ϑ and a fixed attitude, e(k+1) = (1 − α) e(k) (paper §III-B)."""
    controller = TrackingController(T, ALPHA, q_star)
    context = fixed_context(controller, x_hat=x_hat, R_WB=R.ravel())
    a = controller.GetOutputPort("a_W").Eval(context)
    q_next = x_hat[:3] + T * x_hat[3:] + 0.5 * T**2 * a
    assert_allclose(q_next - R @ q_star, (1 - ALPHA) * (x_hat[:3] - R @ q_star), atol=1e-12)
    # …and the relative velocity is not damped: ϑ(k+1) = −ϑ(k) − (2α/t)(q(k) − R q*).
    v_next = x_hat[3:] + T * a
    assert_allclose(v_next, -x_hat[3:] - 2 * ALPHA / T * (x_hat[:3] - R @ q_star), atol=1e-12)
