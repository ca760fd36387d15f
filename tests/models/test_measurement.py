"""The range measurement model: values, Jacobian against finite differences, Y-noise moments."""

import numpy as np
import pytest

from drake_uuv.models.measurement import (
    range_difference_noise,
    range_jacobian,
    range_measurement,
)


def test_ranges_are_the_sonar_distances():
    q = np.array([-2.0, -2.0, 0.5])
    q_s = np.array([-1.0, 1.0, 0.0])
    p_uuv = np.array([3.0, 1.0, -2.0])
    p_target = p_uuv - q
    s1, s2 = p_uuv + 0.5 * q_s, p_uuv - 0.5 * q_s
    d = range_measurement(np.concatenate([q, np.zeros(3)]), q_s)
    np.testing.assert_allclose(d, [np.linalg.norm(s1 - p_target), np.linalg.norm(s2 - p_target)])
    # ½(d1² − d2²) = q_sᵀ q exactly: the paper's linear measurement.
    assert 0.5 * (d[0] ** 2 - d[1] ** 2) == pytest.approx(q_s @ q, rel=1e-14)


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


def test_range_difference_moments_match_monte_carlo():
    """m and Γ (derived model) against a seeded sample; tolerance from the sample size."""
    rng = np.random.default_rng(7)
    d = np.array([2.9, 2.6])
    var = np.array([0.01, 0.04])
    n = 400_000
    z = d + np.sqrt(var) * rng.standard_normal((n, 2))
    noise = 0.5 * (z[:, 0] ** 2 - z[:, 1] ** 2) - 0.5 * (d[0] ** 2 - d[1] ** 2)
    # The mean of the squared noisy ranges is d² + η: the model then sees the true d².
    m, Gamma = range_difference_noise("derived", var, d**2 + var)
    # 4σ bands: se(mean) = √(Γ/n); se(var) ≈ Γ √(2/n) (noise nearly Gaussian).
    assert abs(noise.mean() - m) < 4 * np.sqrt(Gamma / n)
    assert abs(noise.var() - Gamma) < 4 * Gamma * np.sqrt(2 / n)
    # The d² estimate is max(mean(z²) − σ², 0): a near-zero range clips at zero.
    m2, Gamma2 = range_difference_noise("derived", var, np.array([0.05, 3.0]) ** 2)
    assert m2 == pytest.approx(-0.015)
    assert Gamma2 == pytest.approx(0.04 * (9.0 - 0.04) + 0.5 * (0.01**2 + 0.04**2))


def test_paper_printed_moments_are_the_printed_formula() -> None:
    eta = np.array([0.01, 0.04])
    squares = np.array([9.0, 4.0])
    m, Gamma = range_difference_noise("paper_printed", eta, squares)
    assert m == pytest.approx(0.05)
    assert Gamma == pytest.approx(
        2 * 0.01**2 + 2 * 0.04**2 + 4 * (9.0 - 0.01) * 0.01 + 4 * (4.0 - 0.04) * 0.04
    )
    with pytest.raises(
        ValueError, match=r"^estimator.noise_model: must be derived or paper_printed, got 'exact'"
    ):
        range_difference_noise("exact", eta, squares)
