"""Navigation errors as noise: the Jacobians against finite differences, the covariances
against seeded Monte Carlo with tolerances from the sample size."""

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pydrake.math import RollPitchYaw, RotationMatrix

from drake_uuv.models.measurement import range_measurement
from drake_uuv.models.navigation_errors import (
    acceleration_attitude_covariance,
    attitude_covariance,
    difference_attitude_variance,
    heading_jacobian,
    range_attitude_jacobian,
)
from drake_uuv.models.so3 import exp_so3, log_so3

RPY = np.array([0.3, -0.4, 1.1])
R_WB = RotationMatrix(RollPitchYaw(RPY)).matrix()
Q = np.array([-2.0, -2.2, 0.6])
Q_S = R_WB @ np.array([-1.0, 1.0, 0.0])


def test_range_jacobian_is_the_derivative_of_the_ranges_under_a_rotated_baseline():
    J = range_attitude_jacobian(Q, Q_S)
    eps = 1e-7
    for k, e in enumerate(np.eye(3)):
        plus = range_measurement(np.r_[Q, 0, 0, 0], exp_so3(eps * e) @ Q_S)
        minus = range_measurement(np.r_[Q, 0, 0, 0], exp_so3(-eps * e) @ Q_S)
        assert_allclose(J[:, k], (plus - minus) / (2 * eps), rtol=1e-6, atol=1e-9)


def test_the_difference_variance_is_the_rotated_baselines_y():
    sigma = np.diag([1e-4, 4e-4, 9e-4])
    g = np.array([(np.dot(exp_so3(1e-7 * e) @ Q_S, Q) - np.dot(exp_so3(-1e-7 * e) @ Q_S, Q)) / 2e-7
                  for e in np.eye(3)])  # fmt: skip
    assert difference_attitude_variance(Q, Q_S, sigma) == pytest.approx(g @ sigma @ g, rel=1e-6)


def test_euler_noise_maps_to_the_world_rotation_covariance():
    """Monte Carlo: perturb roll, pitch, yaw; the rotation vectors Log(R_nav Rᵀ) have the
    covariance E diag(σ²) Eᵀ within sampling error (n = 20000: each variance within 5 of its
    standard errors √(2/n) σ²)."""
    sigma = np.radians([0.5, 0.5, 2.0])
    rng = np.random.default_rng(4)
    n = 20000
    vectors = np.empty((n, 3))
    for i in range(n):
        noisy = RotationMatrix(RollPitchYaw(RPY + sigma * rng.standard_normal(3))).matrix()
        vectors[i] = log_so3(noisy @ R_WB.T)
    expected = attitude_covariance(R_WB, sigma)
    sample = np.cov(vectors.T)
    scale = np.sqrt(np.outer(np.diag(expected), np.diag(expected)))
    assert np.all(np.abs(sample - expected) <= 5 * np.sqrt(2.0 / n) * scale + 1e-12)


def test_the_commanded_acceleration_error_covariance():
    a = np.array([3.0, -1.0, 0.5])
    sigma = attitude_covariance(R_WB, np.radians([0.5, 0.5, 2.0]))
    rng = np.random.default_rng(5)
    n = 20000
    theta = rng.multivariate_normal(np.zeros(3), sigma, size=n)
    errors = np.array([exp_so3(-th) @ a - a for th in theta])  # R u1 − R_nav u1
    expected = acceleration_attitude_covariance(a, sigma)
    sample = np.cov(errors.T)
    scale = np.sqrt(np.outer(np.diag(expected), np.diag(expected))) + 1e-12
    assert np.all(np.abs(sample - expected) <= 5 * np.sqrt(2.0 / n) * scale + 1e-9)


def test_a_heading_bias_rotates_the_relative_state_about_z():
    x = np.array([-2.0, -2.0, 0.5, 0.3, -0.1, 0.2])
    b = 1e-6
    Rz = exp_so3(np.array([0.0, 0.0, b]))
    rotated = np.concatenate([Rz @ x[:3], Rz @ x[3:]])
    assert_allclose(heading_jacobian(x), (rotated - x) / b, rtol=1e-5, atol=1e-9)
