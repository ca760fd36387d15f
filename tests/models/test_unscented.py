"""The unscented update: exact on linear models, the documented sigma-point rule, the range UKF."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from drake_uuv.models.filters import ekf_update
from drake_uuv.models.unscented import (
    SigmaPointParameters,
    sigma_points,
    ukf_range_update,
    unscented_update,
)

RNG = np.random.default_rng(7)
_M = RNG.standard_normal((6, 6))
P_PRED = _M @ _M.T / 6 + 0.05 * np.eye(6)
X_PRED = np.array([-1.8, -2.3, 0.4, 0.05, 0.0, -0.02])
Q_S = np.array([-0.6, 1.1, 0.5])
R2 = np.diag([0.01, 0.02])


def kalman(x, P, z, H, R):
    """The textbook KF update, an independent formulation."""
    S = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S)
    nu = z - H @ x
    return x + K @ nu, P - K @ S @ K.T, float(nu @ np.linalg.inv(S) @ nu)


@pytest.mark.parametrize(
    "parameters",
    [
        SigmaPointParameters(),
        SigmaPointParameters(0.5, 2.0, 0.0),
        SigmaPointParameters(1.0, 0.0, 1.0),
    ],
)
@pytest.mark.parametrize("rows", [1, 2, 3])
def test_ukf_is_the_kf_on_a_linear_gaussian_model(parameters, rows):
    H = RNG.standard_normal((rows, 6))
    R = np.diag(RNG.uniform(0.01, 0.1, rows))
    z = H @ X_PRED + RNG.standard_normal(rows)
    x, P, nis = unscented_update(X_PRED, P_PRED, z, R, lambda X: X @ H.T, parameters)
    x_kf, P_kf, nis_kf = kalman(X_PRED, P_PRED, z, H, R)
    assert_allclose(x, x_kf, rtol=0, atol=1e-12)
    assert_allclose(P, P_kf, rtol=0, atol=1e-12)
    assert nis == pytest.approx(nis_kf, rel=1e-10)


def test_sigma_points_reproduce_mean_and_covariance_with_the_documented_weights():
    points, Wm, Wc = sigma_points(X_PRED, P_PRED)
    assert points.shape == (13, 6)
    # α = 1, β = 2, κ = 3 − n: n + λ = 3, W0m = −1, Wi = 1/6, W0c = 1.
    assert Wm[0] == pytest.approx(-1.0) and Wc[0] == pytest.approx(1.0)
    assert_allclose(Wm[1:], 1.0 / 6.0)
    assert_allclose(Wc[1:], 1.0 / 6.0)
    assert_allclose(Wm @ points, X_PRED, atol=1e-14)
    d = points - X_PRED
    assert_allclose((Wc[:, None] * d).T @ d, P_PRED, atol=1e-13)
    # ±√3 standard deviations along each Cholesky column.
    L = np.linalg.cholesky(P_PRED)
    assert_allclose(points[1:7] - X_PRED, np.sqrt(3.0) * L.T, atol=1e-14)


def test_on_the_position_block_the_rule_is_the_three_dimensional_cubature_rule():
    # The docstring's claim: h depends only on q, so the predicted measurement is the
    # 3-D cubature rule (±√3 σ along the columns of chol(P_qq), weights 1/6).
    z_hat_ukf = []

    def capture(X):
        out = np.linalg.norm(X[:, :3] + 0.5 * Q_S, axis=1)[:, None]
        z_hat_ukf.append(out)
        return out

    points, Wm, _ = sigma_points(X_PRED, P_PRED)
    ukf_mean = float(Wm @ capture(points)[:, 0])
    L3 = np.linalg.cholesky(P_PRED[:3, :3])
    cubature = [X_PRED[:3] + s * np.sqrt(3.0) * L3[:, j] for j in range(3) for s in (1, -1)]
    expected = np.mean([np.linalg.norm(p + 0.5 * Q_S) for p in cubature])
    assert ukf_mean == pytest.approx(expected, rel=1e-12)


def test_predicted_range_carries_the_second_order_term():
    # q on the x axis, variance only across the line of sight: mean range ≈ d + tr(P⊥)/(2d).
    d, s2 = 10.0, 0.04
    x = np.array([d, 0, 0, 0, 0, 0.0])
    P = np.diag([1e-8, s2, s2, 1e-6, 1e-6, 1e-6])
    captured = {}

    def h(X):
        captured["z"] = np.linalg.norm(X[:, :3], axis=1)[:, None]
        return captured["z"]

    unscented_update(x, P, np.array([d]), np.array([[0.01]]), h)
    _, Wm, _ = sigma_points(x, P)
    z_hat = float(Wm @ captured["z"][:, 0])
    assert z_hat - d == pytest.approx(2 * s2 / (2 * d), rel=1e-3)


def test_range_ukf_tends_to_the_ekf_for_a_small_prior():
    P = 1e-8 * P_PRED
    z = np.array([2.9, 3.1])
    x_u, P_u, nis_u = ukf_range_update(X_PRED, P, z, Q_S, R2)
    x_e, P_e, nis_e = ekf_update(X_PRED, P, z, Q_S, R2)
    assert_allclose(x_u, x_e, rtol=0, atol=1e-12)
    assert_allclose(P_u, P_e, rtol=1e-6, atol=1e-20)
    assert nis_u == pytest.approx(nis_e, rel=1e-6)


@pytest.mark.parametrize("sonar", [0, 1])
def test_one_sonar_update_uses_only_its_range(sonar):
    z = np.array([2.9, 3.1])
    z_masked = z.copy()
    z_masked[1 - sonar] = np.nan
    x, P, nis = ukf_range_update(X_PRED, P_PRED, z_masked, Q_S, R2, sonars=(sonar,))
    sign = 1.0 if sonar == 0 else -1.0

    def h(X):
        return np.linalg.norm(X[:, :3] + sign * 0.5 * Q_S, axis=1)[:, None]

    expected = unscented_update(X_PRED, P_PRED, z[[sonar]], R2[[sonar]][:, [sonar]], h)
    assert_allclose(x, expected[0], atol=1e-14)
    assert_allclose(P, expected[1], atol=1e-14)
    assert nis == pytest.approx(expected[2])


def test_posterior_covariance_is_symmetric_positive_definite_and_joseph_equals_standard():
    z = np.array([2.0, 4.5])  # far from the prediction: strongly nonlinear
    x, P, _ = ukf_range_update(X_PRED, P_PRED, z, Q_S, R2)
    assert_allclose(P, P.T, rtol=0, atol=0)
    assert np.linalg.eigvalsh(P).min() > 0.0
    # The standard form P − K S Kᵀ from the same transform (independent arithmetic).
    points, Wm, Wc = sigma_points(X_PRED, P_PRED)
    Z = np.stack(
        [
            np.linalg.norm(points[:, :3] + 0.5 * Q_S, axis=1),
            np.linalg.norm(points[:, :3] - 0.5 * Q_S, axis=1),
        ],
        axis=1,
    )
    dz = Z - Wm @ Z
    S = (Wc[:, None] * dz).T @ dz + R2
    Pxz = (Wc[:, None] * (points - X_PRED)).T @ dz
    K = Pxz @ np.linalg.inv(S)
    assert_allclose(P, P_PRED - K @ S @ K.T, atol=1e-12)
    assert_allclose(x, X_PRED + K @ (z - Wm @ Z), atol=1e-12)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"alpha": 0.0}, r"^alpha: must be > 0, got 0.0$"),
        ({"beta": float("nan")}, r"^beta: must be finite, got nan$"),
        ({"kappa": float("inf")}, r"^kappa: must be finite or None, got inf$"),
    ],
)
def test_bad_parameters_raise(kwargs, message):
    with pytest.raises(ValueError, match=message):
        SigmaPointParameters(**kwargs)


def test_spread_must_be_positive_and_sonars_must_be_valid():
    with pytest.raises(ValueError, match=r"^kappa: n \+ kappa must be > 0 for n = 6, got -6.0$"):
        sigma_points(X_PRED, P_PRED, SigmaPointParameters(kappa=-6.0))
    with pytest.raises(
        ValueError, match=r"^sonars: must be a non-empty subset of \(0, 1\), got \(2,\)$"
    ):
        ukf_range_update(X_PRED, P_PRED, np.ones(2), Q_S, R2, sonars=(2,))
