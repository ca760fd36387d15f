"""Navigation errors in the bound: attitude noise as range and process noise, the floors."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pydrake.math import RollPitchYaw, RotationMatrix

from drake_uuv.models.measurement import batch_ranges
from drake_uuv.models.navigation_noise import (
    commanded_acceleration_noise,
    euler_rate_jacobian,
    heading_bias_floor,
    range_attitude_jacobian,
    rotation_vector_covariance,
    sound_speed_floor,
)
from drake_uuv.models.so3 import exp_so3, hat, log_so3

ATTITUDES = [[0.0, 0.0, 0.0], [0.3, -0.4, 2.0], [-1.2, 1.1, -2.9], [2.5, 0.2, 0.7]]


def _rotation(rpy) -> np.ndarray:
    return RotationMatrix(RollPitchYaw(np.asarray(rpy, dtype=float))).matrix()


@pytest.mark.parametrize("rpy", ATTITUDES)
def test_the_euler_jacobian_is_the_derivative_of_drakes_roll_pitch_yaw(rpy) -> None:
    R, h = _rotation(rpy), 1e-6
    E = euler_rate_jacobian(R)
    for axis in range(3):
        step = h * np.eye(3)[axis]
        plus = log_so3(_rotation(np.add(rpy, step)) @ R.T)
        minus = log_so3(_rotation(np.subtract(rpy, step)) @ R.T)
        assert_allclose(E[:, axis], (plus - minus) / (2 * h), atol=1e-8)
    assert_allclose(euler_rate_jacobian(np.stack([R, R])), np.stack([E, E]))


@pytest.mark.slow
def test_the_rotation_vector_covariance_is_that_of_sampled_attitude_noise() -> None:
    """Σ_θ against the sample covariance of ``Log(R(rpy + n) R(rpy)ᵀ)``, n ~ N(0, diag σ²)."""
    rpy, sigma, runs = np.array([0.3, -0.4, 2.0]), np.array([0.01, 0.02, 0.03]), 20_000
    R = _rotation(rpy)
    n = np.random.default_rng(0).normal(size=(runs, 3)) * sigma
    theta = np.array([log_so3(_rotation(rpy + draw) @ R.T) for draw in n])
    Sigma = rotation_vector_covariance(R, sigma)
    sample = theta.T @ theta / runs
    # Sampling error √(2/n) ≈ 1 % of the diagonal scale; the first-order model is off by O(σ).
    scale = np.sqrt(np.outer(np.diag(Sigma), np.diag(Sigma)))
    assert np.all(np.abs(sample - Sigma) <= 0.06 * scale)
    assert not np.allclose(Sigma, np.diag(np.diag(Sigma)), atol=1e-6)  # turned off the axes


def test_the_range_jacobian_in_attitude_is_the_derivative_of_the_ranges() -> None:
    rng = np.random.default_rng(1)
    q, q_s, h = np.array([-2.0, -1.5, 0.7]), rng.normal(size=3), 1e-6
    p_TS = np.stack([q + 0.5 * q_s, q - 0.5 * q_s])
    J = range_attitude_jacobian(p_TS, q_s)
    for axis in range(3):
        step = h * np.eye(3)[axis]
        plus = batch_ranges(q[:, None], exp_so3(step) @ q_s)[:, 0]
        minus = batch_ranges(q[:, None], exp_so3(-step) @ q_s)[:, 0]
        assert_allclose(J[:, axis], (plus - minus) / (2 * h), atol=1e-8)
    # Each sonar's baseline may be given on its own (pings at different times).
    assert_allclose(range_attitude_jacobian(p_TS, np.stack([q_s, q_s])), J)
    # A turn about the baseline moves neither sonar.
    assert_allclose(J @ q_s, 0.0, atol=1e-14)


def test_the_commanded_acceleration_noise_is_the_covariance_of_theta_cross_a() -> None:
    rng = np.random.default_rng(2)
    a = rng.normal(size=(5, 3)) * 10.0
    G = rng.normal(size=(3, 3))
    Sigma = 1e-4 * G @ G.T
    expected = np.stack([hat(ak) @ Sigma @ hat(ak).T for ak in a])
    assert_allclose(commanded_acceleration_noise(a, Sigma), expected, rtol=1e-12)
    # The believed acceleration Exp(θ) a is the true one turned: its error is θ × a.
    theta = np.array([1e-4, -2e-4, 3e-4])
    second_order = (theta @ theta) * np.linalg.norm(a[0])
    assert_allclose(exp_so3(theta) @ a[0] - a[0], np.cross(theta, a[0]), atol=second_order)


def test_the_heading_floor_on_a_circle() -> None:
    """q on a circle of radius r about z with angular rate ω: σ_ψ² r² in position, σ_ψ² r² ω²
    in velocity; and it is the mean square of the whole frame turned by the bias."""
    r, omega, sigma, z = 2.5, 0.3, math.radians(2.0), 1.2
    angle = omega * np.linspace(0.0, 10.0, 21)
    q = np.column_stack([r * np.cos(angle), r * np.sin(angle), np.full_like(angle, z)])
    v = np.column_stack([-r * omega * np.sin(angle), r * omega * np.cos(angle), 0 * angle])
    floor = heading_bias_floor(q, v, sigma)
    assert_allclose(np.trace(floor[:, :3, :3], axis1=1, axis2=2), sigma**2 * r**2, rtol=1e-12)
    assert_allclose(np.trace(floor[:, 3:, 3:], axis1=1, axis2=2), (sigma * r * omega) ** 2,
                    rtol=1e-12)  # fmt: skip
    # The first-order turn of the state, b [e_z × q, e_z × ϑ], as a covariance.
    g = np.concatenate([np.cross([0.0, 0.0, 1.0], q[3]), np.cross([0.0, 0.0, 1.0], v[3])])
    assert_allclose(floor[3], sigma**2 * np.outer(g, g), rtol=1e-12, atol=1e-18)
    # E|Rz(b) x − x|² = 2 (1 − E cos b) |x_xy|² = 2 (1 − e^{−σ²/2}) |x_xy|²: σ² to O(σ⁴).
    exact = 2.0 * (1.0 - math.exp(-(sigma**2) / 2)) * (r**2 + (r * omega) ** 2)
    assert np.trace(floor[0]) == pytest.approx(exact, rel=sigma**2)
    # The premise: a heading bias turns the whole world about z, and ranges do not see it.
    rpy, b = np.array([0.3, -0.4, 2.0]), 0.1
    Rz = _rotation([0.0, 0.0, b])
    assert_allclose(_rotation(rpy + [0.0, 0.0, b]), Rz @ _rotation(rpy), atol=1e-15)
    q_s = _rotation(rpy) @ np.array([-1.0, 1.0, 0.0])
    assert_allclose(batch_ranges((Rz @ q[0])[:, None], Rz @ q_s),
                    batch_ranges(q[0][:, None], q_s), rtol=1e-14)  # fmt: skip


def _scaled_fix(q: np.ndarray, q_s: np.ndarray, epsilon: float) -> np.ndarray:
    """The least-norm change of q whose ranges are the true ones scaled by 1 + ε (Gauss-
    Newton on the two ranges)."""
    target = (1.0 + epsilon) * batch_ranges(q[:, None], q_s)[:, 0]
    delta = np.zeros(3)
    for _ in range(20):
        p = q + delta
        H = np.stack([(p + 0.5 * q_s) / np.linalg.norm(p + 0.5 * q_s),
                      (p - 0.5 * q_s) / np.linalg.norm(p - 0.5 * q_s)])  # fmt: skip
        residual = target - batch_ranges(p[:, None], q_s)[:, 0]
        delta = delta + np.linalg.pinv(H) @ residual
    return delta


@pytest.mark.parametrize("distance", [2.0 * math.sqrt(2.0), 30.0, 3000.0])
def test_the_sound_speed_floor_is_the_far_field_error_of_scaled_ranges(distance) -> None:
    """Across the baseline, the two-range fix of scaled ranges is off by
    ε (1 + |q_s|²/4|q|²) q: the floor ε² |q|² is its far-field limit."""
    epsilon, q_s = 1e-4, np.array([-1.0, 1.0, 0.0])
    q = distance * np.array([-1.0, -1.0, 0.0]) / math.sqrt(2.0)  # ⊥ q_s
    floor = sound_speed_floor(q[None], epsilon)[0]
    assert np.trace(floor[:3, :3]) == pytest.approx(epsilon**2 * distance**2, rel=1e-12)
    assert_allclose(floor[3:], 0.0)
    delta = _scaled_fix(q, q_s, epsilon)
    near = (1.0 + (q_s @ q_s) / (4.0 * distance**2)) ** 2
    assert delta @ delta == pytest.approx(near * np.trace(floor), rel=1e-3)
    if distance > 1000.0:
        assert delta @ delta == pytest.approx(np.trace(floor), rel=1e-6)
