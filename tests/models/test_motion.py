"""The sampled double integrator and its process noise, in closed form."""

import numpy as np
import pytest

from drake_uuv.models.motion import (
    double_integrator,
    double_integrator_step,
    process_noise_covariance,
)


def test_double_integrator_closed_form() -> None:
    A, B = double_integrator(0.5)
    assert A.shape == (6, 6) and B.shape == (6, 3)
    np.testing.assert_array_equal(A[:3, 3:], 0.5 * np.eye(3))
    np.testing.assert_array_equal(B, np.vstack([0.125 * np.eye(3), 0.5 * np.eye(3)]))
    # Constant acceleration a for one step from rest: p = t²/2 a, v = t a.
    a = np.array([1.0, -2.0, 3.0])
    np.testing.assert_allclose(A @ np.zeros(6) + B @ a, np.concatenate([0.125 * a, 0.5 * a]))
    # Ten steps of constant acceleration are exactly the continuous motion.
    x = np.concatenate([[1.0, 2.0, 3.0], [0.1, -0.2, 0.3]])
    for _ in range(10):
        x = A @ x + B @ a
    T = 5.0
    expected_p = np.array([1.0, 2.0, 3.0]) + T * np.array([0.1, -0.2, 0.3]) + 0.5 * T * T * a
    np.testing.assert_allclose(x[:3], expected_p, rtol=1e-14)


@pytest.mark.parametrize("bad", [0.0, -0.5, float("nan")])
def test_time_step_must_be_positive(bad: float) -> None:
    with pytest.raises(ValueError, match=r"^time_step: must be > 0, got "):
        double_integrator(bad)


def test_process_noise_is_b_w_bt_and_rank_three() -> None:
    W = np.diag([0.004, 0.001, 0.001])
    Q = process_noise_covariance(W, 0.5)
    np.testing.assert_array_equal(Q, Q.T)
    assert np.linalg.matrix_rank(Q) == 3
    # Position–position block t⁴/4 W, position–velocity t³/2 W, velocity t² W.
    np.testing.assert_allclose(Q[:3, :3], 0.5**4 / 4 * W)
    np.testing.assert_allclose(Q[:3, 3:], 0.5**3 / 2 * W)
    np.testing.assert_allclose(Q[3:, 3:], 0.5**2 * W)


def test_the_step_without_matrices_is_the_matrix_form_to_the_bit() -> None:
    """The plant and the target step with ``double_integrator_step``; the filter with A and B."""
    rng = np.random.default_rng(0)
    A, B = double_integrator(0.5)
    for _ in range(2000):
        p, v, a = (rng.normal(size=3) * scale for scale in rng.uniform(0, 100, size=3))
        x = A @ np.concatenate([p, v]) + B @ a
        p_next, v_next = double_integrator_step(p, v, a, 0.5)
        np.testing.assert_array_equal(np.concatenate([p_next, v_next]), x)
