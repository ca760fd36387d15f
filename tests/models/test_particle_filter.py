"""The particle filter against the Kalman filter on linear-Gaussian models, and its pieces.

Tolerances come from the particle count: the weighted mean of N particles has a standard
error of about ``√(tr P / N_eff)``, a covariance entry a relative one of about ``√(2/N_eff)``.
"""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from drake_uuv.models.motion import double_integrator
from drake_uuv.models.particle_filter import (
    TEMPERING_FLOOR,
    ParticleFilter,
    ParticleFilterParameters,
    Workspace,
    defensive_draw,
    effective_sample_size,
    initial_particles,
    normalised,
    particle_ranges,
    pf_predict,
    pf_update,
    range_terms,
    reweight,
    shrinkage_kernel,
    systematic_resample,
    tempered,
    weigh,
    weighted_moments,
)
from tests.conftest import W

A, B = double_integrator(0.5)
Q = B @ W @ B.T
X0 = np.array([-2.0, -2.0, 0.3, 0.1, -0.05, 0.0])
_M = np.random.default_rng(3).standard_normal((6, 6))
P0 = _M @ _M.T / 12 + 0.02 * np.eye(6)
H = np.array([[1.0, 0.5, 0.0, 0.0, 0.0, 0.0], [0.0, 0.2, 1.0, 0.0, 0.3, 0.0]])
VARIANCES = np.array([0.05, 0.08])


def kalman_update(x, P, z, variances=VARIANCES):
    S = H @ P @ H.T + np.diag(variances)
    K = P @ H.T @ np.linalg.inv(S)
    nu = z - H @ x
    return x + K @ nu, P - K @ S @ K.T, float(nu @ np.linalg.solve(S, nu))


@pytest.mark.parametrize("widening", [1.0, 2.0, 4.0])
def test_a_defensive_draw_is_a_weighted_sample_of_the_same_gaussian(widening):
    count = 100_000
    particles, log_w = defensive_draw(X0, P0, count, np.random.default_rng(11), widening)
    weights = np.exp(log_w)
    assert weights.sum() == pytest.approx(1.0, rel=1e-12)
    n_eff = effective_sample_size(weights)
    # The weights' second moment for N(0, 1) against N(0, κ) is (√κ / √(2 − 1/κ)) per axis.
    expected = count / (math.sqrt(widening) / math.sqrt(2.0 - 1.0 / widening)) ** 6
    assert n_eff == pytest.approx(expected, rel=0.1)
    x, P = weighted_moments(particles, weights)
    assert np.linalg.norm(x - X0) < 5.0 * math.sqrt(np.trace(P0) / n_eff)
    assert np.linalg.norm(P - P0) < 5.0 * math.sqrt(2.0 / n_eff) * np.linalg.norm(P0)
    # Its draws reach κ times further: the spread of the unweighted cloud.
    assert_allclose(np.cov(particles), widening * P0, atol=5.0 * math.sqrt(2.0 / count) * widening)


def _size(log_weights):
    return effective_sample_size(normalised(log_weights))


def test_a_defensive_draw_without_widening_is_the_plain_draw():
    plain = initial_particles(X0, P0, 500, np.random.default_rng(4))
    particles, log_w = defensive_draw(X0, P0, 500, np.random.default_rng(4), 1.0)
    assert_array_equal(particles, plain)
    assert_allclose(log_w, -math.log(500), rtol=1e-12)


@pytest.mark.parametrize("count", [2_000, 20_000, 200_000])
def test_one_update_converges_to_the_kf_with_tolerances_from_the_count(count):
    rng = np.random.default_rng(count)
    z = H @ X0 + np.array([0.3, -0.2])
    particles = initial_particles(X0, P0, count, rng)
    log_w = np.full(count, -math.log(count))
    x, P, nis, log_post = reweight(particles, log_w, z, VARIANCES, H @ particles)
    x_kf, P_kf, nis_kf = kalman_update(X0, P0, z)
    n_eff = effective_sample_size(np.exp(log_post))
    assert n_eff > 0.2 * count  # a mild likelihood: most particles keep weight
    # Sampling error of the prior cloud and of the weights together, 5 standard errors.
    assert np.linalg.norm(x - x_kf) < 5.0 * math.sqrt(np.trace(P_kf) / n_eff)
    assert np.linalg.norm(P - P_kf) < 5.0 * math.sqrt(2.0 / n_eff) * np.linalg.norm(P_kf)
    assert nis == pytest.approx(nis_kf, rel=5.0 * math.sqrt(2.0 / count) + 5.0 / math.sqrt(count))


def test_errors_shrink_with_the_count_at_the_standard_error_rate():
    z = H @ X0 + np.array([0.3, -0.2])
    x_kf, _, _ = kalman_update(X0, P0, z)
    errors = {}
    for count in (1_000, 100_000):
        e = []
        for seed in range(20):
            particles = initial_particles(X0, P0, count, np.random.default_rng(seed))
            log_w = np.full(count, -math.log(count))
            x, *_ = reweight(particles, log_w, z, VARIANCES, H @ particles)
            e.append(np.sum((x - x_kf) ** 2))
        errors[count] = math.sqrt(np.mean(e))
    # 100× the particles: 10× smaller RMS error; 20 runs estimate each RMS within ~±35 %.
    assert 5.0 < errors[1_000] / errors[100_000] < 20.0


def test_the_filter_over_many_steps_tracks_the_kf_on_a_linear_gaussian_model():
    """Predict (resampling, shrinkage kernel, process noise) and update for 30 steps.

    After a resampling the effective sample size starts again near N while the cloud keeps
    the error of the sample it was drawn from, so the bound sums the errors of every step:
    step j's error, of variance ≤ tr P(j)/N_eff(j), reaches step k through the filter's
    contraction, under P(k); hence variance ≤ tr P(k) · Σ_j 1/N_eff(j). The covariance gets 6
    standard errors rather than 5: the kernel re-injects the cloud's estimated covariance at
    every resampling, so its error is heavier-tailed. The likelihood is mild (unit variances),
    so that the effective sample size stays a fair measure of each step's error.
    """
    variances = np.array([1.0, 1.0])
    count = 50_000
    rng = np.random.default_rng(11)
    data = np.random.default_rng(12)
    params = ParticleFilterParameters(count=count)
    particles = initial_particles(X0, P0, count, rng)
    log_w = np.full(count, -math.log(count))
    x_kf, P_kf = X0.copy(), P0.copy()
    truth = X0 + np.linalg.cholesky(P0) @ data.standard_normal(6)
    resampled_any = False
    inverse_ess_sum = 0.0
    for k in range(30):
        a_W = np.array([math.sin(k), 0.5, -0.2])
        z = H @ truth + np.sqrt(variances) * data.standard_normal(2)
        x, P, _, log_w = reweight(particles, log_w, z, variances, H @ particles)
        x_kf, P_kf, _ = kalman_update(x_kf, P_kf, z, variances)
        inverse_ess_sum += 1.0 / effective_sample_size(np.exp(log_w))
        assert np.linalg.norm(x - x_kf) < 5.0 * math.sqrt(np.trace(P_kf) * inverse_ess_sum), k
        assert np.linalg.norm(P - P_kf) < 6.0 * math.sqrt(2.0 * inverse_ess_sum) * np.linalg.norm(
            P_kf
        ), k
        particles, log_w, resampled = pf_predict(particles, log_w, a_W, A, B, W, rng, params)
        resampled_any |= resampled
        x_kf, P_kf = A @ x_kf + B @ a_W, A @ P_kf @ A.T + Q
        truth = A @ truth + B @ (a_W - np.linalg.cholesky(W) @ data.standard_normal(3))
    assert resampled_any


def test_systematic_resampling_matches_the_searchsorted_formulation():
    rng = np.random.default_rng(5)
    for n in (1, 7, 1000):
        w = rng.exponential(size=n) ** 3
        w /= w.sum()
        for u in (0.0, 0.3, 0.999):
            index = systematic_resample(w, u)
            cdf = np.cumsum(w)
            cdf[-1] = 1.0
            expected = np.searchsorted(cdf, (np.arange(n) + u) / n, side="right")
            assert_array_equal(index, np.minimum(expected, n - 1))
            counts = np.bincount(index, minlength=n)
            assert np.all(np.abs(counts - n * w) < 1.0 + 1e-9)  # floor or ceil of N wᵢ


def test_moments_ess_and_ranges_against_independent_formulas():
    rng = np.random.default_rng(2)
    particles = rng.standard_normal((6, 500))
    w = rng.uniform(size=500)
    w /= w.sum()
    mean, cov = weighted_moments(particles, w)
    assert_allclose(mean, np.average(particles, axis=1, weights=w), atol=1e-14)
    assert_allclose(cov, np.cov(particles, aweights=w, bias=True), atol=1e-14)
    assert effective_sample_size(np.full(8, 1 / 8)) == pytest.approx(8.0)
    assert effective_sample_size(np.array([1.0, 0, 0])) == pytest.approx(1.0)
    q_s = np.array([-0.6, 1.1, 0.5])
    expected = np.stack(
        [
            np.linalg.norm(particles[:3].T + q_s / 2, axis=1),
            np.linalg.norm(particles[:3].T - q_s / 2, axis=1),
        ]
    )
    assert_allclose(particle_ranges(particles, q_s), expected, atol=1e-13)
    out = np.empty((2, 500))
    assert particle_ranges(particles, q_s, out) is out
    assert_array_equal(out, particle_ranges(particles, q_s))


@pytest.mark.parametrize("threshold", [0.0, 1.0])  # never and always resampled
def test_steps_in_a_workspace_give_the_bits_of_fresh_arrays(threshold):
    """The reused work arrays change where the steps write, not what they compute."""
    count = 300
    params = ParticleFilterParameters(count=count, resample_threshold=threshold)
    particles = initial_particles(X0, P0, count, np.random.default_rng(4))
    log_w = np.log(np.random.default_rng(5).uniform(0.5, 1.0, count))
    z, q_s, R = np.array([2.9, 3.0]), np.array([-1.0, 1.0, 0.1]), np.diag([0.01, 0.02])

    def steps(work):
        x, P, nis, log_post = pf_update(particles, log_w, z, q_s, R, work=work)
        weighed = weigh(log_w, *range_terms(particles, z, q_s, R, (1,), work), work)
        given = weigh(
            log_w, *range_terms(particles, z, q_s, R, (1,), work), work, normalised(log_w)
        )
        assert_array_equal(given[1], weighed[1])
        assert given[0] == weighed[0]
        moved, log_next, resampled = pf_predict(
            particles, log_post, np.array([0.1, 0.0, 0.0]), A, B, W,
            np.random.default_rng(6), params, work=work,
        )  # fmt: skip
        assert resampled is (threshold == 1.0)
        return x, P, nis, log_post, *weighed, moved.copy(), log_next

    for fresh, reused in zip(steps(None), steps(Workspace(count)), strict=True):
        assert_array_equal(reused, fresh)


def test_shrinkage_kernel_keeps_mean_and_covariance():
    rng = np.random.default_rng(4)
    count = 200_000
    particles = initial_particles(X0, P0, count, rng)
    mean, cov = weighted_moments(particles, np.full(count, 1 / count))
    moved = shrinkage_kernel(particles, mean, cov, 0.6, rng)
    m2, c2 = weighted_moments(moved, np.full(count, 1 / count))
    assert np.linalg.norm(m2 - mean) < 5.0 * math.sqrt(np.trace(cov) / count)
    assert np.linalg.norm(c2 - cov) < 5.0 * math.sqrt(2.0 / count) * np.linalg.norm(cov)
    assert not np.allclose(moved, particles)  # the particles did move


def test_range_update_one_sonar_and_nis():
    rng = np.random.default_rng(9)
    particles = initial_particles(X0, P0, 4000, rng)
    log_w = np.full(4000, -math.log(4000))
    q_s = np.array([-1.0, 1.0, 0.0])
    R = np.diag([0.01, 0.02])
    z = np.array([2.8, np.nan])
    x, P, nis, log_post = pf_update(particles, log_w, z, q_s, R, sonars=(0,))
    h = particle_ranges(particles, q_s)[:1]
    expected = reweight(particles, log_w, z[:1], [0.01], h)
    assert_allclose(x, expected[0])
    assert_allclose(P, expected[1])
    assert nis == expected[2]
    # NIS: innovation against the prior-weighted mean and spread of h, plus the noise.
    w = np.exp(log_w)
    z_hat = h[0] @ w
    S = ((h[0] - z_hat) ** 2) @ w + 0.01
    assert nis == pytest.approx((2.8 - z_hat) ** 2 / S)
    assert math.isclose(np.exp(log_post).sum(), 1.0)


def test_same_generator_same_particles():
    def run(seed):
        rng = np.random.default_rng(seed)
        pf = ParticleFilter(
            initial_particles(X0, P0, 1000, rng), A, B, W, np.diag([0.01, 0.01]), rng
        )
        for k in range(5):
            pf.update(np.array([2.9, 3.0]), np.array([-1.0, 1.0, 0.1 * k]))
            pf.predict(np.array([0.1, 0.0, 0.0]))
        return pf.particles

    assert_array_equal(run(1), run(1))
    assert not np.array_equal(run(1), run(2))


def test_bandwidth_is_the_scaled_gaussian_optimum():
    params = ParticleFilterParameters(count=5000, bandwidth_scale=1.0)
    assert params.bandwidth == pytest.approx((4.0 / (8 * 5000)) ** 0.1)
    assert ParticleFilterParameters(count=5000, bandwidth_scale=0.0).bandwidth == 0.0


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"count": 5}, r"^count: must be in \[10, 1e7\], got 5$"),
        ({"count": 2.5}, r"^count: must be an integer, got 2.5$"),
        ({"resample_threshold": 1.5}, r"^resample_threshold: must be in \[0, 1\], got 1.5$"),
        ({"bandwidth_scale": -1.0}, r"^bandwidth_scale: must be ≥ 0, got -1.0$"),
        ({"kernel": "polar"}, r"^kernel: must be one of cartesian, range_bearing, got 'polar'$"),
    ],
)
def test_bad_parameters_raise(kwargs, message):
    with pytest.raises(ValueError, match=message):
        ParticleFilterParameters(**kwargs)


def test_the_numpy_range_bearing_kernel_keeps_each_particle_s_range():
    """The numpy resampling (the late-range window's) with ``kernel: range_bearing``: a cloud
    on the sphere |q| = 14 m keeps every particle's range exactly and the cloud's moments in
    its range-bearing coordinates within their standard errors; the Cartesian kernel leaves
    the shell."""
    from drake_uuv.models.particle_filter import resample_regularised
    from drake_uuv.models.range_bearing import range_bearing_frame, to_range_bearing

    rng = np.random.default_rng(5)
    count, radius = 20_000, 14.0
    direction = np.array([-0.7, -0.7, 0.1])[:, None] + 0.1 * rng.standard_normal((3, count))
    q = radius * direction / np.linalg.norm(direction, axis=0)
    particles = np.vstack([q, 0.2 * rng.standard_normal((3, count))])
    weights = normalised(-rng.uniform(0.0, 0.01, count))  # resampled at threshold 1
    log_weights = np.log(weights)
    parameters = ParticleFilterParameters(count=count, resample_threshold=1.0)
    moved = {}
    for kernel in ("range_bearing", "cartesian"):
        chosen_parameters = ParticleFilterParameters(count, 1.0, kernel=kernel)
        out, _, chosen = resample_regularised(
            particles, log_weights, np.random.default_rng(6), chosen_parameters
        )
        assert chosen is not None
        moved[kernel] = out
    assert_allclose(np.linalg.norm(moved["range_bearing"][:3], axis=0), radius, rtol=1e-13)
    assert np.std(np.linalg.norm(moved["cartesian"][:3], axis=0)) > 0.01
    frame = range_bearing_frame(particles, weights)
    before = weighted_moments(to_range_bearing(particles, frame), weights)
    after = weighted_moments(
        to_range_bearing(moved["range_bearing"], frame), np.full(count, 1 / count)
    )
    scale = np.sqrt(np.diag(before[1]))
    tolerance = 5.0 * scale / math.sqrt(count)
    assert np.all(np.abs(after[0] - before[0])[1:] <= tolerance[1:])  # range: 0 ± 0
    variance_tolerance = 5.0 * math.sqrt(2.0 / count) * scale**2
    assert np.all(np.abs(np.diag(after[1]) - np.diag(before[1])) <= variance_tolerance + 1e-24)
    assert parameters.kernel == "cartesian"  # the default
    # Stored less an offset (the late ranges' window): the ranges about the offset are kept.
    offset = np.array([3.0, -1.0, 0.5, 0.1, 0.0, 0.0])
    stored = particles - offset[:, None]
    chosen_parameters = ParticleFilterParameters(count, 1.0, kernel="range_bearing")
    out, _, chosen = resample_regularised(
        stored, log_weights, np.random.default_rng(6), chosen_parameters, offset=offset
    )
    assert_allclose(np.linalg.norm(out[:3] + offset[:3, None], axis=0), radius, rtol=1e-13)


def test_tempering_keeps_the_floor_with_the_largest_power_of_the_likelihood():
    """Closed form of :func:`tempered`: a likelihood that leaves about one particle is raised
    to the largest power λ whose posterior keeps ``TEMPERING_FLOOR`` particles' worth (the
    result is the prior plus λ times the log likelihood, normalised; a little more than λ
    keeps fewer); a posterior above the floor, and a prior below it, are left alone."""
    rng = np.random.default_rng(3)
    prior = -np.log(rng.uniform(1.0, 2.0, 4000))
    likelihood = -0.5 * (rng.normal(size=4000) / 0.002) ** 2  # a sharp one
    plain = prior + likelihood
    plain -= np.log(np.sum(np.exp(plain - plain.max()))) + plain.max()
    assert _size(plain) < 0.6 * TEMPERING_FLOOR  # Bayes keeps about a dozen
    out = tempered(prior, plain)
    power, shift = np.polyfit(likelihood, out - prior, 1)
    assert_allclose(out - prior, power * likelihood + shift, atol=1e-8)
    assert 0.0 < power < 1.0
    assert TEMPERING_FLOOR <= _size(out) <= TEMPERING_FLOOR * (1.0 + 1e-6)
    assert _size(prior + 1.001 * power * likelihood) < TEMPERING_FLOOR
    assert np.exp(out).sum() == pytest.approx(1.0, rel=1e-12)
    # Above the floor: Bayes' rule, the same array.
    mild = prior - 0.5 * (rng.normal(size=4000) / 10.0) ** 2
    assert tempered(prior, mild) is mild
    # A prior below the floor: Bayes' rule too (tempering could not restore it).
    narrow = prior.copy()
    narrow[:5] += 60.0
    assert tempered(narrow, plain) is plain
    # A particle of zero prior weight keeps none.
    dead = prior.copy()
    dead[0] = -np.inf
    assert tempered(dead, plain)[0] == -np.inf
