"""The marginalised particle filter's kernels: the velocity part is a Kalman filter given the
position track (exact, to rounding), a drawn cloud carries ``E[v | q]`` and the Schur
complement, and a NaN run touches no other run."""

import numpy as np

from drake_uuv.models.marginalized_kernels import (
    condition_on_track,
    marginal_gain,
    marginalized_advance,
)
from drake_uuv.models.motion import double_integrator
from drake_uuv.models.particle_filter import ParticleFilterParameters
from drake_uuv.models.particle_random import cloud_keys

T = 0.5
W = np.diag([0.004, 0.001, 0.002])
A, BU = double_integrator(T)
Q = BU @ W @ BU.T


def kalman_on_track(x: np.ndarray, P: np.ndarray, a: np.ndarray, q_next: np.ndarray):
    """A 6-state Kalman filter's step: predict with ``a``, update on the position ``q_next``
    measured exactly (H = [I 0], R = 0)."""
    x = A @ x + BU @ a
    P = A @ P @ A.T + Q
    H = np.hstack([np.eye(3), np.zeros((3, 3))])
    S = H @ P @ H.T
    K = P @ H.T @ np.linalg.inv(S)
    x = x + K @ (q_next - H @ x)
    P = P - K @ H @ P
    return x, 0.5 * (P + P.T)


def test_the_velocity_part_is_a_kalman_filter_given_the_true_position_track() -> None:
    rng = np.random.default_rng(3)
    truth = np.array([-2.0, -2.0, 0.3, 0.1, 0.0, -0.05])
    m, Sigma = np.array([0.3, -0.2, 0.1]), np.diag([0.5, 0.3, 0.2])
    x, P = np.concatenate([truth[:3], m]), np.zeros((6, 6))
    P[3:, 3:] = Sigma
    for _ in range(40):
        a = rng.normal(size=3)
        w = rng.multivariate_normal(np.zeros(3), W)
        q = truth[:3].copy()
        truth = A @ truth + BU @ (a - w)
        m, Sigma = condition_on_track(q, m, Sigma, truth[:3].copy(), a, T, Q)
        x, P = kalman_on_track(x, P, a, truth[:3])
        np.testing.assert_allclose(m, x[3:], rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(Sigma, P[3:, 3:], rtol=1e-9, atol=1e-14)
        np.testing.assert_allclose(P[:3], 0.0, atol=1e-12)  # the position known exactly
    assert np.linalg.norm(m - truth[3:]) < 5 * np.sqrt(np.trace(Sigma))


def _advance(
    particles, log_weights, Sigma, keys, *, a, drawn=None, draw=None, threshold=0.0, **kernel
):
    """``kernel``: ``bandwidth`` (0), ``range_bearing`` (False), ``offset`` (6, zero), ``Q``."""
    B, n, _ = particles.shape
    offset = np.tile(kernel.get("offset", np.zeros(6)), (B, 1))
    process = np.broadcast_to(kernel.get("Q", Q), (B, 6, 6)).copy()
    drawn = np.zeros(B, dtype=bool) if drawn is None else drawn
    draw_x, draw_P = (np.zeros((B, 6)), np.zeros((B, 6, 6))) if draw is None else draw
    out, out_lw, out_S = np.empty_like(particles), np.empty((B, n)), np.empty((B, 3, 3))
    x, P = np.empty((B, 6)), np.empty((B, 6, 6))
    no = np.zeros(B, dtype=bool)
    marginalized_advance(
        particles, log_weights, Sigma, no, log_weights.copy(), np.exp(log_weights), x, P, keys,
        np.ones(B, dtype=bool), drawn, draw_x, draw_P, no, offset, np.zeros((B, 2)),
        np.zeros((B, 2), dtype=bool), np.zeros((B, 3)), np.ones((B, 2, 2)), T, a, process,
        threshold, kernel.get("bandwidth", 0.0), kernel.get("range_bearing", False), out, out_lw,
        out_S, x, P,
    )  # fmt: skip
    return out, out_lw, out_S, x, P


def test_each_particle_s_velocity_is_the_kalman_filter_on_its_own_drawn_track() -> None:
    """The kernel's move: every particle's ``m`` is the Kalman filter fed the particle's own
    sampled positions (no resampling), and ``Σ`` the filter's velocity covariance."""
    rng = np.random.default_rng(5)
    n = 12
    particles = np.tile(np.array([-2.0, -2.0, 0.3, 0.1, 0.0, -0.05]), (1, n, 1))
    particles[0, :, :3] += 0.1 * rng.normal(size=(n, 3))
    log_weights = np.full((1, n), -np.log(n))
    Sigma = np.diag([0.5, 0.3, 0.2])[None].copy()
    kf = []
    for i in range(n):
        P = np.zeros((6, 6))
        P[3:, 3:] = Sigma[0]
        kf.append((particles[0, i].copy(), P))
    for _ in range(25):
        a = rng.normal(size=(1, 3))
        keys = cloud_keys(rng.uniform(size=1))
        particles, log_weights, Sigma, _, _ = _advance(particles, log_weights, Sigma, keys, a=a)
        for i in range(n):
            kf[i] = kalman_on_track(*kf[i], a[0], particles[0, i, :3])
            np.testing.assert_allclose(particles[0, i, 3:], kf[i][0][3:], rtol=1e-9, atol=1e-11)
            np.testing.assert_allclose(Sigma[0], kf[i][1][3:, 3:], rtol=1e-9, atol=1e-14)


def test_a_drawn_cloud_carries_the_conditional_mean_and_the_schur_complement() -> None:
    rng = np.random.default_rng(8)
    M = rng.normal(size=(6, 6))
    P0 = M @ M.T + 0.1 * np.eye(6)
    x0 = rng.normal(size=6)
    n = 4000
    particles = np.zeros((1, n, 6))
    keys = cloud_keys(np.array([0.25]))
    Sigma0 = P0[3:, 3:] - P0[3:, :3] @ np.linalg.solve(P0[:3, :3], P0[:3, 3:])
    out, _, out_S, x, P = _advance(
        particles, np.full((1, n), -np.log(n)), np.zeros((1, 3, 3)), keys, a=np.zeros((1, 3)),
        drawn=np.ones(1, dtype=bool), draw=(x0[None], P0[None]),
    )  # fmt: skip
    # The predicted Σ' is the Kalman step of the drawn Σ: the same as conditioning Σ0.
    L, K, expected = np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3))
    marginal_gain(Sigma0, T, Q, L, K, expected)
    np.testing.assert_allclose(out_S[0], expected, rtol=1e-9, atol=1e-12 * np.trace(expected))
    # The predicted mean and covariance are the Gaussian's prediction, to sampling error.
    spread = np.sqrt(np.diag(A @ P0 @ A.T + Q) / n)
    assert np.all(np.abs(x[0] - A @ x0) < 5 * spread)
    np.testing.assert_allclose(P[0], A @ P0 @ A.T + Q, rtol=0.15, atol=0.15 * np.trace(P0) / 6)


def test_a_nan_run_leaves_the_other_runs_bits_alone() -> None:
    rng = np.random.default_rng(2)
    n = 50
    particles = rng.normal(size=(3, n, 6))
    log_weights = rng.normal(size=(3, n))
    log_weights -= np.log(np.exp(log_weights).sum(axis=1, keepdims=True))
    Sigma = np.broadcast_to(0.1 * np.eye(3), (3, 3, 3)).copy()
    keys = cloud_keys(rng.uniform(size=3))
    a = rng.normal(size=(3, 3))
    batch = _advance(particles, log_weights, Sigma, keys, a=a, threshold=0.9)
    particles[1] = np.nan
    Sigma[1] = np.nan
    with_nan = _advance(particles, log_weights, Sigma, keys, a=a, threshold=0.9)
    for got, want in zip(with_nan, batch, strict=True):
        np.testing.assert_array_equal(got[[0, 2]], want[[0, 2]])
    assert np.isnan(with_nan[3][1]).all()
    for b in (0, 2):  # each run alone: the same bits
        alone = _advance(
            particles[b : b + 1].copy(), log_weights[b : b + 1].copy(), Sigma[b : b + 1].copy(),
            keys[b : b + 1].copy(), a=a[b : b + 1].copy(), threshold=0.9,
        )  # fmt: skip
        for got, want in zip(alone, batch, strict=True):
            np.testing.assert_array_equal(got[0], want[b])


def test_the_range_bearing_kernel_keeps_a_shell_cloud_on_its_shell() -> None:
    """Closed form: particles ``[q, m]`` on the sphere |q + offset| = 14 m, at rest, with
    neither process noise nor velocity uncertainty, resampled and moved by the kernel alone:
    in range-bearing coordinates each keeps its range exactly; in Cartesian ones it leaves."""
    rng = np.random.default_rng(3)
    n, radius = 1500, 14.0
    offset = np.array([0.5, -0.2, 0.1, 0.0, 0.0, 0.0])
    direction = np.array([-0.7, -0.7, 0.1]) + 0.15 * rng.standard_normal((n, 3))
    q = radius * direction / np.linalg.norm(direction, axis=1, keepdims=True)
    particles = (np.hstack([q, np.zeros((n, 3))]) - offset)[None]
    log_weights = -np.log(rng.uniform(1.0, 2.0, (1, n)))
    log_weights -= np.log(np.exp(log_weights).sum())
    bandwidth = ParticleFilterParameters(count=n).bandwidth
    ranges = {}
    for range_bearing in (True, False):
        out, out_lw, _, _, _ = _advance(
            particles, log_weights, np.zeros((1, 3, 3)), cloud_keys(np.array([0.4])),
            a=np.zeros((1, 3)), threshold=1.0, bandwidth=bandwidth,
            range_bearing=range_bearing, offset=offset, Q=np.zeros((6, 6)),
        )  # fmt: skip
        np.testing.assert_allclose(out_lw, -np.log(n))  # it resampled
        ranges[range_bearing] = np.linalg.norm(out[0, :, :3] + offset[:3], axis=1)
    np.testing.assert_allclose(ranges[True], radius, rtol=1e-13)
    assert np.std(ranges[False]) > 0.01


def test_given_its_position_track_a_particle_s_velocity_is_known_to_t2_w_over_4k() -> None:
    """Closed form. The target's acceleration drives both position and velocity (``Q = B W Bᵀ``,
    rank 3), so ``v' = 2 (q' − q − t²/2 a) / t − v + t a`` whatever the noise: given the
    position track a particle's velocity follows from its first one, and each step's
    displacement measures that with covariance ``t² W / 4``. Hence
    ``Σ_k = (Σ₀⁻¹ + 4k/t² W⁻¹)⁻¹``, and ``m'`` is that recurrence exactly when ``Σ = 0``. This is
    why marginalising the velocity leaves the particle filter's Monte Carlo error as it is:
    the cloud's spread of ``m`` carries the velocity's uncertainty, and ``Σ`` almost none."""
    W_c = np.array([[0.004, 0.001, 0.0], [0.001, 0.002, 0.0], [0.0, 0.0, 0.001]])
    _, B_t = double_integrator(T)
    Q_c = B_t @ W_c @ B_t.T
    Sigma0 = np.diag([0.5, 0.3, 0.2])
    Sigma, L, K, Sigma_next = Sigma0.copy(), np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3))
    for k in range(1, 301):
        marginal_gain(Sigma, T, Q_c, L, K, Sigma_next)
        Sigma = Sigma_next.copy()
        expected = np.linalg.inv(np.linalg.inv(Sigma0) + 4 * k / T**2 * np.linalg.inv(W_c))
        np.testing.assert_allclose(Sigma, expected, rtol=1e-9, atol=1e-12 * np.abs(expected).max())
    rng = np.random.default_rng(1)
    q, m, a, q_next = rng.normal(size=(4, 3))
    m_next, Sigma_next = condition_on_track(q, m, np.zeros((3, 3)), q_next, a, T, Q_c)
    np.testing.assert_allclose(m_next, 2 * (q_next - q - T**2 / 2 * a) / T - m + T * a, atol=1e-12)
    np.testing.assert_allclose(Sigma_next, 0.0, atol=1e-15)
