"""The PCRLB recursion and the KF's Riccati covariance."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from drake_uuv.models.attitude_plans import trajectory_attitude
from drake_uuv.models.measurement import range_measurement
from drake_uuv.models.motion import double_integrator, process_noise_covariance
from drake_uuv.models.pcrlb import (
    bound_rmse,
    kf_riccati_covariance,
    measurement_information,
    pcrlb_along_trajectory,
    pcrlb_over_runs,
    pcrlb_recursion,
    symmetrise,
)
from tests.conftest import ETA, T, W

N = 200


def _psd_le(a: np.ndarray, b: np.ndarray, rtol: float = 1e-9) -> bool:
    """a ⪯ b (all stacked matrices), up to rounding."""
    gap = np.linalg.eigvalsh(b - a).min(axis=-1)
    return bool(np.all(gap >= -rtol * np.abs(b).max()))


@pytest.fixture(scope="module")
def paper_geometry() -> tuple[np.ndarray, np.ndarray]:
    """q = R q* exactly (ideal tracking) and q_s = R b under Algorithm 2."""
    b = np.array([-1.0, 1.0, 0.0])
    q_star = np.array([-2.0, -2.0, 0.0])
    Rs = np.stack(
        [np.eye(3)] + [trajectory_attitude(k, b, 1 / 24, 0.5, 1 / 6) for k in range(N - 1)]
    )
    return Rs @ q_star, Rs @ b


def _kf_covariances(H: np.ndarray, R: np.ndarray, P0: np.ndarray, steps: int) -> np.ndarray:
    """An independent textbook KF covariance recursion (standard, not Joseph, update)."""
    A, _ = double_integrator(T)
    Q = process_noise_covariance(W, T)
    P_pred, out = P0, []
    for _ in range(steps):
        K = P_pred @ H.T @ np.linalg.inv(H @ P_pred @ H.T + R)
        P = (np.eye(6) - K @ H) @ P_pred
        out.append(P)
        P_pred = A @ P @ A.T + Q
    return np.array(out)


def test_pcrlb_equals_kf_covariance_in_a_linear_gaussian_model():
    rng = np.random.default_rng(0)
    H = rng.normal(size=(2, 6))  # a fixed linear measurement, velocity included
    R = np.diag([0.02, 0.05])
    P0 = 2.0 * np.eye(6)
    M = np.broadcast_to(H.T @ np.linalg.inv(R) @ H, (N, 6, 6))
    np.testing.assert_allclose(
        pcrlb_recursion(M, P0, W, T), _kf_covariances(H, R, P0, N), rtol=1e-7, atol=1e-12
    )


def test_pcrlb_with_the_paper_measurement_is_the_kf_riccati(paper_geometry):
    _, q_s = paper_geometry
    Gamma = np.linspace(0.1, 0.2, N)
    C = np.zeros((N, 1, 6))
    C[:, 0, :3] = q_s
    M = np.swapaxes(C, 1, 2) @ C / Gamma[:, None, None]
    P0 = np.eye(6)
    np.testing.assert_allclose(
        pcrlb_recursion(M, P0, W, T),
        kf_riccati_covariance(q_s, P0, W, Gamma, T),
        rtol=1e-6,
        atol=1e-10,
    )


def test_measurement_information_is_that_of_the_mean_ranges():
    q = np.array([[-2.0, -2.0, 0.5]])
    q_s = np.array([[-1.0, 1.0, 0.0]])
    f = 4
    M = measurement_information(q, q_s, ETA, f)[0]
    u = np.array([(q[0] + s * q_s[0]) / np.linalg.norm(q[0] + s * q_s[0]) for s in (0.5, -0.5)])
    np.testing.assert_allclose(M[:3, :3], u.T @ np.diag(f / ETA) @ u)
    np.testing.assert_array_equal(M[3:], 0.0)
    assert np.linalg.matrix_rank(M) == 2  # no information along q_s × q


def test_bound_decreases_as_eta_decreases(paper_geometry):
    q, q_s = paper_geometry
    P0 = np.eye(6)
    bounds = [pcrlb_along_trajectory(q, q_s, P0, W, e * ETA, 1, T) for e in (4.0, 1.0, 0.25)]
    rmse = [bound_rmse(b, 100) for b in bounds]
    assert rmse[0][0] > rmse[1][0] > rmse[2][0]
    assert rmse[0][1] > rmse[1][1] > rmse[2][1]
    assert _psd_le(bounds[1], bounds[0]) and _psd_le(bounds[2], bounds[1])
    # f samples of variance η carry the information of one sample of variance η/f.
    np.testing.assert_allclose(
        pcrlb_along_trajectory(q, q_s, P0, W, ETA, 4, T), bounds[2], rtol=1e-10, atol=1e-14
    )


def test_pcrlb_is_below_the_kf_riccati_covariance(paper_geometry):
    """Y is a function of the ranges, so the raw-range bound is below the KF's covariance."""
    q, q_s = paper_geometry
    x = np.hstack([q, np.zeros_like(q)])
    d = np.array([range_measurement(xk, qk) for xk, qk in zip(x, q_s, strict=True)])
    Gamma = (d**2) @ ETA + 0.5 * ETA @ ETA
    P0 = np.eye(6)
    pcrlb = pcrlb_along_trajectory(q, q_s, P0, W, ETA, 1, T)
    kf = kf_riccati_covariance(q_s, P0, W, Gamma, T)
    assert _psd_le(pcrlb, kf)
    assert bound_rmse(kf, 100)[0] > 2.0 * bound_rmse(pcrlb, 100)[0]


def test_monte_carlo_averages_are_ordered(paper_geometry):
    """Averaged M (the bound) ⪯ (mean J)⁻¹ ⪯ mean J⁻¹ (concavity, Jensen)."""
    q, q_s = paper_geometry
    rng = np.random.default_rng(1)
    runs = q + rng.normal(scale=0.7, size=(8, *q.shape))  # run-dependent geometry
    P0 = np.eye(6)
    exact, mean_inverse = pcrlb_over_runs(runs, q_s, P0, W, ETA, 1, T)
    per_run = np.array([pcrlb_along_trajectory(r, q_s, P0, W, ETA, 1, T) for r in runs])
    mean_J_inverse = np.linalg.inv(np.mean(np.linalg.inv(per_run), axis=0))
    np.testing.assert_allclose(mean_inverse, per_run.mean(axis=0))
    assert _psd_le(exact, mean_J_inverse, rtol=1e-7)
    assert _psd_le(mean_J_inverse, mean_inverse, rtol=1e-7)
    # With identical runs all three coincide.
    same = np.broadcast_to(q, (3, *q.shape))
    single = pcrlb_along_trajectory(q, q_s, P0, W, ETA, 1, T)
    for bound in pcrlb_over_runs(same, q_s, P0, W, ETA, 1, T):
        np.testing.assert_allclose(bound, single)


def test_bound_rmse():
    covs = np.zeros((10, 6, 6))
    covs[:, :3, :3] = np.diag([1.0, 2.0, 1.0])
    covs[5:, 3:, 3:] = 4.0 * np.eye(3)
    assert bound_rmse(covs, 5) == pytest.approx((2.0, np.sqrt(12.0)))
    assert bound_rmse(covs, 0) == pytest.approx((2.0, np.sqrt(6.0)))
    with pytest.raises(ValueError, match="start must be in"):
        bound_rmse(covs, 10)


def test_shape_errors_name_the_argument():
    with pytest.raises(ValueError, match="q_true must have shape"):
        pcrlb_along_trajectory(np.zeros(3), np.zeros((1, 3)), np.eye(6), W, ETA, 1, T)
    with pytest.raises(ValueError, match="Gamma has 2 entries for 3 steps"):
        kf_riccati_covariance(np.ones((3, 3)), np.eye(6), W, np.ones(2), T)


def _recursion_by_np_linalg(M: np.ndarray, P0: np.ndarray, A: np.ndarray, Q: np.ndarray):
    """The recursion written with ``np.linalg.inv``, one step at a time."""
    bounds = np.empty_like(M)
    P_pred = np.broadcast_to(P0, M.shape[:-3] + (6, 6))
    for k in range(M.shape[-3]):
        if k > 0:
            P_pred = symmetrise(A @ bounds[..., k - 1, :, :] @ A.T + Q)
        J = symmetrise(np.linalg.inv(P_pred) + M[..., k, :, :])
        bounds[..., k, :, :] = symmetrise(np.linalg.inv(J))
    return bounds


def test_the_recursion_is_np_linalgs_and_a_singular_run_is_nan_alone() -> None:
    rng = np.random.default_rng(3)
    G = rng.standard_normal((3, 40, 6, 6))
    M = G @ np.swapaxes(G, -1, -2)
    A, _ = double_integrator(0.5)
    Q = process_noise_covariance(0.01 * np.eye(3), 0.5)
    bounds = pcrlb_recursion(M, np.eye(6), 0.01 * np.eye(3), 0.5)
    assert_allclose(bounds, _recursion_by_np_linalg(M, np.eye(6), A, Q), rtol=1e-9, atol=1e-14)
    for run in range(3):  # each run alone: the same bits
        alone = pcrlb_recursion(M[run], np.eye(6), 0.01 * np.eye(3), 0.5)
        assert np.array_equal(bounds[run], alone)
    M[1, 7] = np.nan  # a failed run: NaN from its step 7 on, the others unchanged
    failed = pcrlb_recursion(M, np.eye(6), 0.01 * np.eye(3), 0.5)
    assert np.all(np.isfinite(failed[1, :7])) and np.all(np.isnan(failed[1, 7:]))
    assert np.array_equal(failed[[0, 2]], bounds[[0, 2]])
    singular = pcrlb_recursion(np.zeros((3, 6, 6)), np.zeros((6, 6)), np.eye(3), 0.5)
    assert np.all(np.isnan(singular))


def test_bounds_drop_the_information_of_missing_returns() -> None:
    rng = np.random.default_rng(4)
    q, q_s = rng.normal(size=(6, 3)) * 2, rng.normal(size=(6, 3))
    available = np.array([[1, 1], [1, 0], [0, 1], [0, 0], [1, 1], [0, 1]], dtype=bool)
    full = measurement_information(q, q_s, np.array([0.01, 0.02]), 3)
    masked = measurement_information(q, q_s, np.array([0.01, 0.02]), 3, available)
    for k, (first, second) in enumerate(available):
        alone = [measurement_information(q[k : k + 1], q_s[k : k + 1], np.array([0.01, 0.02]), 3, [[i == 0, i == 1]])
                 for i in (0, 1)]  # fmt: skip
        expected = first * alone[0][0] + second * alone[1][0]
        assert_allclose(masked[k], expected, atol=1e-12)
    assert_allclose(masked[[0, 4]], full[[0, 4]])
    # Y needs both ranges: the KF's Riccati recursion only predicts at the other steps.
    gamma = np.full(6, 0.1)
    covs = kf_riccati_covariance(q_s, np.eye(6), W, gamma, T, available)
    A, _ = double_integrator(T)
    Q = process_noise_covariance(W, T)
    assert_allclose(covs[1], A @ covs[0] @ A.T + Q, rtol=1e-12)
    assert_allclose(covs[3], A @ covs[2] @ A.T + Q, rtol=1e-12)
    with pytest.raises(ValueError, match=r"available must have shape \(6, 2\)"):
        measurement_information(q, q_s, np.array([0.01, 0.02]), 3, available[:3])
