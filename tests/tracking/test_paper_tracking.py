"""The paper's tracking law alone: ports, the law in closed form, its closed loop."""

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pydrake.math import RollPitchYaw, RotationMatrix

from drake_uuv.models.tracking_laws import closed_loop_eigenvalues
from drake_uuv.testing import fixed_context
from tests.tracking.controllers import paper_controller

T, ALPHA = 0.5, 1.2
q_star = np.array([-2.0, -2.0, 0.0])
R = RotationMatrix(RollPitchYaw(0.1, 0.5, -0.8)).matrix()
x_hat = np.array([0.4, -1.0, 3.0, 0.2, -0.1, 0.05])


def test_ports() -> None:
    controller = paper_controller(q_star, ALPHA)
    assert controller.GetInputPort("x_TU_hat").size() == 6
    assert controller.GetInputPort("R_WB_nav").size() == 9
    assert controller.GetOutputPort("u1_B").size() == 3
    assert controller.GetOutputPort("u1_W").size() == 3


def test_papers_law() -> None:
    controller = paper_controller(q_star, ALPHA)
    context = fixed_context(controller, x_TU_hat=x_hat, R_WB_nav=R.ravel())
    u1 = -(2 * ALPHA / T**2) * (R.T @ x_hat[:3] - q_star) - (2 / T) * R.T @ x_hat[3:]
    assert_allclose(controller.GetOutputPort("u1_B").Eval(context), u1, rtol=1e-14)
    assert_allclose(controller.GetOutputPort("u1_W").Eval(context), R @ u1, rtol=1e-14)


def test_tracking_error_contracts_by_one_minus_alpha_with_perfect_knowledge() -> None:
    """With q̂ = q, ϑ̂ = ϑ and a fixed attitude, e(k+1) = (1 − α) e(k) (paper §III-B)."""
    controller = paper_controller(q_star, ALPHA)
    context = fixed_context(controller, x_TU_hat=x_hat, R_WB_nav=R.ravel())
    a = controller.GetOutputPort("u1_W").Eval(context)
    q_next = x_hat[:3] + T * x_hat[3:] + 0.5 * T**2 * a
    assert_allclose(q_next - R @ q_star, (1 - ALPHA) * (x_hat[:3] - R @ q_star), atol=1e-12)
    # …and the relative velocity is not damped: ϑ(k+1) = −ϑ(k) − (2α/t)(q(k) − R q*).
    v_next = x_hat[3:] + T * a
    assert_allclose(v_next, -x_hat[3:] - 2 * ALPHA / T * (x_hat[:3] - R @ q_star), atol=1e-12)


def test_gain_matrix_is_the_law_in_the_world_frame() -> None:
    """a = −K (x̂ − [R q*, 0]) with the controller's K equals R u1; its closed loop has the
    eigenvalues 1 − α and −1 (each three times)."""
    controller = paper_controller(q_star, ALPHA)
    context = fixed_context(controller, x_TU_hat=x_hat, R_WB_nav=R.ravel())
    K = controller.gain
    a = -K @ (x_hat - np.concatenate([R @ q_star, np.zeros(3)]))
    assert_allclose(controller.GetOutputPort("u1_W").Eval(context), a, rtol=1e-12)
    eigenvalues = np.sort(closed_loop_eigenvalues(T, K).real)
    assert_allclose(eigenvalues, [-1.0] * 3 + [1.0 - ALPHA] * 3, atol=1e-6)


def test_acceleration_limit_keeps_the_direction() -> None:
    free = paper_controller(q_star, ALPHA)
    limited = paper_controller(q_star, ALPHA, max_acceleration=0.5)
    u_free = free.GetOutputPort("u1_B").Eval(
        fixed_context(free, x_TU_hat=x_hat, R_WB_nav=R.ravel())
    )
    context = fixed_context(limited, x_TU_hat=x_hat, R_WB_nav=R.ravel())
    u = limited.GetOutputPort("u1_B").Eval(context)
    assert np.linalg.norm(u) == pytest.approx(0.5)
    assert_allclose(u / 0.5, u_free / np.linalg.norm(u_free), rtol=1e-12)
