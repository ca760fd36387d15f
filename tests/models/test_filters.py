"""Filter steps: prediction, linear KF, EKF and IEKF updates, the linear-KF start."""

import numpy as np
import pytest

from drake_uuv.models.filters import (
    ekf_update,
    iekf_update,
    predict,
    range_difference_update,
)
from drake_uuv.models.measurement import range_difference_noise, range_measurement
from drake_uuv.models.motion import double_integrator, process_noise_covariance


def _random_spd(rng: np.random.Generator, n: int = 6, scale: float = 1.0) -> np.ndarray:
    M = rng.normal(size=(n, n))
    return scale * (M @ M.T / n + 0.1 * np.eye(n))


def _y_measurement(z: np.ndarray, variances: np.ndarray) -> tuple[float, float, float]:
    """The paper's Y from two ranges, with the derived moments (d² estimated by z² − σ²)."""
    m, Gamma = range_difference_noise("derived", variances, z * z)
    return 0.5 * (z[0] ** 2 - z[1] ** 2), m, Gamma


def _map_cost(x, x_pred, P_pred, z, q_s, R):
    r = z - range_measurement(x, q_s)
    e = x - x_pred
    return 0.5 * r @ np.linalg.solve(R, r) + 0.5 * e @ np.linalg.solve(P_pred, e)


def test_predict_closed_form():
    A, B = double_integrator(0.5)
    Q = process_noise_covariance(np.diag([0.004, 0.001, 0.001]), 0.5)
    x = np.array([1.0, 2.0, 3.0, 0.1, 0.2, 0.3])
    a = np.array([0.4, -0.4, 0.0])
    x1, P1 = predict(x, np.eye(6), a, A, B, Q)
    np.testing.assert_allclose(x1[:3], x[:3] + 0.5 * x[3:] + 0.125 * a)
    np.testing.assert_allclose(x1[3:], x[3:] + 0.5 * a)
    np.testing.assert_allclose(P1, A @ A.T + Q)


def test_ekf_update_hand_computed_step():
    """q = [3, 0, 0], q_s = [0, 2, 0], P = I, R = 0.01 I, innovations ±0.1.

    H = [[3, 1, 0], [3, −1, 0]]/√10, S = [[1.01, 0.8], [0.8, 1.01]] with eigenvalues 1.81
    (along [1, 1]) and 0.21 (along [1, −1]); ν = 0.1 [1, −1] so S⁻¹ν = ν/0.21 and
    K ν = Hᵀ S⁻¹ ν = (0.1/0.21)(2/√10) e_y. P_xx = 1 − 1.8/1.81, P_yy = 1 − 0.2/0.21.
    """
    x_pred = np.array([3.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    q_s = np.array([0.0, 2.0, 0.0])
    d = np.sqrt(10.0)
    z = np.array([d + 0.1, d - 0.1])
    x, P, nis = ekf_update(x_pred, np.eye(6), z, q_s, 0.01 * np.eye(2))
    np.testing.assert_allclose(x, [3.0, (0.1 / 0.21) * 2 / d, 0, 0, 0, 0], atol=1e-12)
    np.testing.assert_allclose(
        np.diag(P), [0.01 / 1.81, 0.01 / 0.21, 1.0, 1.0, 1.0, 1.0], rtol=1e-12, atol=1e-14
    )
    assert P[0, 1] == pytest.approx(0.0, abs=1e-14)
    np.testing.assert_allclose(P[3:, 3:], np.eye(3))
    assert nis == pytest.approx(0.02 / 0.21)


@pytest.mark.parametrize("seed", range(10))
def test_joseph_covariances_are_symmetric_pd_and_shrink(seed):
    rng = np.random.default_rng(seed)
    P_pred = _random_spd(rng, scale=rng.uniform(1e-3, 10.0))
    x_pred = rng.normal(scale=2.0, size=6)
    q_s = rng.normal(size=3)
    R = np.diag(rng.uniform(1e-4, 1e-1, size=2))
    z = range_measurement(x_pred, q_s) + rng.normal(scale=0.1, size=2)
    Y, m, Gamma = _y_measurement(z, np.diag(R))
    for _, P, nis in (
        ekf_update(x_pred, P_pred, z, q_s, R),
        iekf_update(x_pred, P_pred, z, q_s, R),
        range_difference_update(x_pred, P_pred, Y, m, Gamma, q_s),
    ):
        np.testing.assert_array_equal(P, P.T)
        assert np.linalg.eigvalsh(P).min() > 0.0
        assert np.linalg.eigvalsh(P_pred - P).min() > -1e-10 * np.abs(P_pred).max()
        assert nis >= 0.0


def test_range_difference_update_matches_information_form():
    rng = np.random.default_rng(3)
    P_pred = _random_spd(rng)
    x_pred = rng.normal(size=6)
    q_s = np.array([0.3, -1.2, 0.5])
    Y, m, Gamma = 0.7, 0.01, 0.05
    x, P, nis = range_difference_update(x_pred, P_pred, Y, m, Gamma, q_s)
    C = np.concatenate([q_s, np.zeros(3)])[None, :]
    P_info = np.linalg.inv(np.linalg.inv(P_pred) + C.T @ C / Gamma)
    np.testing.assert_allclose(P, P_info, rtol=1e-10, atol=1e-12)
    innovation = Y - (C @ x_pred)[0] - m
    np.testing.assert_allclose(x, x_pred + P_info @ C[0] * innovation / Gamma, rtol=1e-10)
    assert nis == pytest.approx(innovation**2 / ((C @ P_pred @ C.T)[0, 0] + Gamma))


def test_iekf_one_iteration_steps_like_the_ekf():
    rng = np.random.default_rng(11)
    x_true = np.array([-2.0, -2.0, 0.3, 0.1, 0.0, 0.0])
    q_s = np.array([-1.0, 1.0, 0.0])
    P_pred = 0.05 * np.eye(6)
    x_pred = x_true + rng.multivariate_normal(np.zeros(6), P_pred)
    R = 0.01 * np.eye(2)
    z = range_measurement(x_true, q_s) + rng.normal(scale=0.1, size=2)
    x_e, _, nis_e = ekf_update(x_pred, P_pred, z, q_s, R)
    x_i, P_i, nis_i = iekf_update(x_pred, P_pred, z, q_s, R, max_iterations=1)
    np.testing.assert_allclose(x_i, x_e, rtol=1e-12)
    assert nis_i == pytest.approx(nis_e, rel=1e-12)
    # The covariance is the Joseph form with the Jacobian at the updated estimate.
    _, P_at_update, _ = ekf_update(x_i, P_pred, z, q_s, R)
    np.testing.assert_allclose(P_i, P_at_update, rtol=1e-12, atol=1e-15)


def test_iekf_reaches_the_map_estimate_from_a_poor_prior():
    """Far from the truth the EKF step overshoots; the IEKF ends at a stationary point of
    the MAP cost, with a cost no higher than the EKF's."""
    x_true = np.array([-1.0, -2.0, -2.0, 0.0, 0.0, 0.0])
    q_s = np.array([-1.0, 1.0, 0.0])
    x_pred = np.array([0.5, -0.5, -1.0, 0.0, 0.0, 0.0])
    P_pred = np.eye(6)
    R = 0.01 * np.eye(2)
    z = range_measurement(x_true, q_s)
    x_e, _, _ = ekf_update(x_pred, P_pred, z, q_s, R)
    x_i, _, _ = iekf_update(x_pred, P_pred, z, q_s, R, max_iterations=50, tolerance=1e-12)
    cost = _map_cost(x_i, x_pred, P_pred, z, q_s, R)
    assert cost <= _map_cost(x_e, x_pred, P_pred, z, q_s, R)
    h = 1e-6
    gradient = [
        (
            _map_cost(x_i + h * e, x_pred, P_pred, z, q_s, R)
            - _map_cost(x_i - h * e, x_pred, P_pred, z, q_s, R)
        )
        / (2 * h)
        for e in np.eye(6)
    ]
    np.testing.assert_allclose(gradient, 0.0, atol=1e-5)
