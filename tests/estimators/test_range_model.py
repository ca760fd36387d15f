"""The range measurement model: values, Jacobian against finite differences, Y-noise moments."""

import numpy as np
import pytest

from drake_uuv.estimators.range_model import (
    linear_measurement_matrix,
    mean_ranges,
    process_noise_covariance,
    range_difference_measurement,
    range_jacobian,
    range_measurement,
    range_noise_covariance,
    relative_model_matrices,
)


def test_relative_model_matrices_closed_form():
    A, B = relative_model_matrices(0.5)
    assert A.shape == (6, 6) and B.shape == (6, 3)
    np.testing.assert_array_equal(A[:3, 3:], 0.5 * np.eye(3))
    np.testing.assert_array_equal(B, np.vstack([0.125 * np.eye(3), 0.5 * np.eye(3)]))
    # Constant acceleration a for one step from rest: p = t²/2 a, v = t a.
    a = np.array([1.0, -2.0, 3.0])
    np.testing.assert_allclose(A @ np.zeros(6) + B @ a, np.concatenate([0.125 * a, 0.5 * a]))
    with pytest.raises(ValueError, match="time_step must be > 0"):
        relative_model_matrices(0.0)


def test_process_noise_is_rank_three():
    Q = process_noise_covariance(np.diag([0.004, 0.001, 0.001]), 0.5)
    np.testing.assert_allclose(Q, Q.T)
    assert np.linalg.matrix_rank(Q) == 3


def test_ranges_are_the_sonar_distances():
    q = np.array([-2.0, -2.0, 0.5])
    q_s = np.array([-1.0, 1.0, 0.0])
    p_uuv = np.array([3.0, 1.0, -2.0])
    p_target = p_uuv - q
    s1, s2 = p_uuv + 0.5 * q_s, p_uuv - 0.5 * q_s
    d = range_measurement(np.concatenate([q, np.zeros(3)]), q_s)
    np.testing.assert_allclose(d, [np.linalg.norm(s1 - p_target), np.linalg.norm(s2 - p_target)])
    # ½(d1² − d2²) = q_sᵀ q exactly: the paper's linear measurement.
    C = linear_measurement_matrix(q_s)
    np.testing.assert_allclose(0.5 * (d[0] ** 2 - d[1] ** 2), (C @ np.concatenate([q, [0] * 3]))[0])


@pytest.mark.parametrize("seed", range(5))
def test_range_jacobian_matches_central_differences(seed):
    rng = np.random.default_rng(seed)
    x = rng.normal(scale=2.0, size=6)
    q_s = rng.normal(size=3)
    H = range_jacobian(x, q_s)
    assert H.shape == (2, 6)
    h = 1e-6
    H_fd = np.column_stack(
        [
            (range_measurement(x + h * e, q_s) - range_measurement(x - h * e, q_s)) / (2 * h)
            for e in np.eye(6)
        ]
    )
    np.testing.assert_allclose(H, H_fd, atol=1e-8)
    np.testing.assert_array_equal(H[:, 3:], 0.0)


def test_jacobian_stays_finite_on_a_sonar():
    q_s = np.array([-1.0, 1.0, 0.0])
    x = np.concatenate([-0.5 * q_s, np.zeros(3)])  # target exactly at sonar 1
    assert np.all(np.isfinite(range_jacobian(x, q_s)))


def test_mean_ranges_and_their_covariance():
    samples = np.array([1.0, 2.0, 3.0, 10.0, 20.0, 30.0])  # f = 3: s1 then s2
    np.testing.assert_allclose(mean_ranges(samples, 3), [2.0, 20.0])
    np.testing.assert_allclose(range_noise_covariance([0.01, 0.04], 4), np.diag([0.0025, 0.01]))


def test_range_difference_moments_match_monte_carlo():
    """m and Γ (derived model) against a seeded sample; tolerance from the sample size."""
    rng = np.random.default_rng(7)
    d = np.array([2.9, 2.6])
    var = np.array([0.01, 0.04])
    n = 400_000
    z = d + np.sqrt(var) * rng.standard_normal((n, 2))
    noise = 0.5 * (z[:, 0] ** 2 - z[:, 1] ** 2) - 0.5 * (d[0] ** 2 - d[1] ** 2)
    _, m, Gamma = range_difference_measurement(d, var, squared_ranges=d**2 + var)
    # 4σ bands: se(mean) = √(Γ/n); se(var) ≈ Γ √(2/n) (noise nearly Gaussian).
    assert abs(noise.mean() - m) < 4 * np.sqrt(Gamma / n)
    assert abs(noise.var() - Gamma) < 4 * Gamma * np.sqrt(2 / n)
    # Without squared_ranges the d² estimate is max(z² − σ², 0).
    Y, m2, Gamma2 = range_difference_measurement([0.05, 3.0], var)
    assert Y == pytest.approx(0.5 * (0.05**2 - 9.0))
    assert m2 == pytest.approx(-0.015)
    assert Gamma2 == pytest.approx(0.04 * (9.0 - 0.04) + 0.5 * (0.01**2 + 0.04**2))
