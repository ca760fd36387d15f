"""The compiled particle steps over a batch against the numpy steps of one cloud
(:mod:`drake_uuv.models.particle_filter`) fed the same draws, their draws' statistics, and their
run independence. Tolerances of sampled moments come from the particle count."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from drake_uuv.models import particle_advance, particle_kernels, particle_random
from drake_uuv.models.motion import double_integrator, process_noise_covariance
from drake_uuv.models.particle_filter import (
    TEMPERING_FLOOR,
    ParticleFilterParameters,
    effective_sample_size,
    normalised,
    pf_update,
)
from tests.estimators.cloud_host import reference_step

T = 0.1
A, B = double_integrator(T)
W = np.diag([0.04, 0.03, 0.01])
X0 = np.array([-2.0, -2.0, 0.3, 0.1, 0.0, -0.1])
Q_S = np.array([-0.6, 1.1, 0.5])


def cloud(runs: int, count: int, seed: int = 0, spread: float = 0.5):
    rng = np.random.default_rng(seed)
    particles = X0 + spread * rng.standard_normal((runs, count, 6))
    log_weights = -np.log(rng.uniform(1.0, 2.0, (runs, count)))
    return particles, log_weights


def ranges(runs: int, seed: int = 1):
    rng = np.random.default_rng(seed)
    d = [np.linalg.norm(X0[:3] + 0.5 * Q_S), np.linalg.norm(X0[:3] - 0.5 * Q_S)]
    z = np.asarray(d) + 0.1 * rng.standard_normal((runs, 2))
    return z, np.ones((runs, 2), dtype=bool), np.tile(Q_S, (runs, 1))


def posterior(particles, log_weights, z, used, q_s, R, offset=None, live=None):
    runs, count = log_weights.shape
    offset = np.zeros((runs, 6)) if offset is None else offset
    live = np.ones(runs, dtype=bool) if live is None else live
    out = (np.empty((runs, 6)), np.empty((runs, 6, 6)), np.empty(runs))
    log_post, weights = np.empty((runs, count)), np.empty((runs, count))
    particle_kernels.cloud_posterior(
        particles, log_weights, offset, z, used, q_s, R, live, *out, log_post, weights
    )
    return (*out, log_post, weights)


def advance(particles, log_weights, seeds, parameters, a_W, **options):
    """cloud_advance of every run (no posterior reuse unless ``reweigh``)."""
    runs, count = log_weights.shape
    zeros = np.zeros(runs, dtype=bool)
    draw = options.get("draw")
    drawn = zeros if draw is None else np.ones(runs, dtype=bool)
    draw_x = np.zeros((runs, 6)) if draw is None else np.tile(draw[0], (runs, 1))
    draw_P = np.zeros((runs, 6, 6)) if draw is None else np.tile(draw[1], (runs, 1, 1))
    z, used, q_s = ranges(runs)
    R = np.tile(np.diag([0.01, 0.02]), (runs, 1, 1))
    jitter = options.get("jitter")
    jitter = np.zeros((runs, 6, 6)) if jitter is None else np.tile(jitter, (runs, 1, 1))
    offset = np.tile(options.get("offset", np.zeros(6)), (runs, 1))
    W_factor = options.get("W_factor", np.linalg.cholesky(W))
    out, out_log = np.empty((runs, count, 6)), np.empty((runs, count))
    x, P = np.empty((runs, 6)), np.empty((runs, 6, 6))
    empty = np.empty((runs, count))
    particle_advance.cloud_advance(
        particles, log_weights, zeros, empty, empty, x, P, particle_random.cloud_keys(seeds),
        np.ones(runs, dtype=bool), drawn, draw_x, draw_P, zeros, offset, z, used,
        q_s, R, T, np.tile(a_W, (runs, 1)), W_factor, jitter,
        parameters.resample_threshold, parameters.bandwidth,
        parameters.kernel == "range_bearing", out, out_log, x, P,
    )  # fmt: skip
    return out, out_log, x, P


def _size(log_weights):
    return effective_sample_size(normalised(log_weights))


def test_normals_are_standard_in_moments_and_tails_and_a_function_of_key_and_slot():
    keys = particle_random.cloud_keys(np.array([0.1, 0.2]))
    draws = particle_random.standard_normals(keys, 200_000, 0, 3)
    sample = draws.ravel()
    n = sample.size
    assert abs(sample.mean()) < 5.0 / math.sqrt(n)
    assert abs(sample.var() - 1.0) < 5.0 * math.sqrt(2.0 / n)
    for a in (0.5, 1.0, 2.0, 3.0, 3.7):  # 3.7: beyond the ziggurat's base strip
        p = math.erfc(a / math.sqrt(2.0))
        assert abs(np.mean(np.abs(sample) > a) - p) < 5.0 * math.sqrt(p / n) + 1.0 / n, a
    # Slots and keys are independent streams; a draw is the same however it is asked for.
    assert abs(np.corrcoef(draws[0, :, 0], draws[0, :, 1])[0, 1]) < 5.0 / math.sqrt(200_000)
    assert abs(np.corrcoef(draws[0, :, 0], draws[1, :, 0])[0, 1]) < 5.0 / math.sqrt(200_000)
    assert_array_equal(particle_random.standard_normals(keys[1:], 10, 1, 2)[0], draws[1, :10, 1:3])


def test_keys_are_a_function_of_the_uniform_alone():
    u = np.array([0.0, 0.25, 0.5, 0.999])
    assert_array_equal(particle_random.cloud_keys(u)[1:3], particle_random.cloud_keys(u[1:3]))
    assert len(set(particle_random.cloud_keys(u).tolist())) == 4


def test_a_gaussian_draw_is_the_mean_plus_the_factor_times_the_slots_normals():
    rng = np.random.default_rng(5)
    M = rng.standard_normal((6, 6))
    L = np.linalg.cholesky(M @ M.T + 0.1 * np.eye(6))
    mean = rng.standard_normal(6)
    keys = particle_random.cloud_keys(np.array([0.3]))
    slot = particle_random.KERNEL_SLOT
    normals = particle_random.standard_normals(keys, 4, slot, 6)[0]
    factor = particle_advance.lower_entries(L)
    assert factor == tuple(L[np.tril_indices(6)])
    for particle in range(4):
        drawn = particle_advance.gaussian_draw(keys[0], particle, slot, tuple(mean), factor)
        assert_allclose(drawn, mean + L @ normals[particle], rtol=1e-14, atol=1e-14)


def test_psd_factor_is_cholesky_and_tolerates_singular_and_nan_matrices():
    M = np.random.default_rng(3).standard_normal((6, 6))
    M = M @ M.T + 0.1 * np.eye(6)
    assert_allclose(particle_kernels.psd_factors(M[None])[0], np.linalg.cholesky(M), rtol=1e-12)
    Q = process_noise_covariance(W, T)  # rank 3
    L = particle_kernels.psd_factors(Q[None])[0]
    assert np.all(np.isfinite(L)) and np.allclose(L @ L.T, Q, rtol=1e-9, atol=1e-16)
    bad = M.copy()
    bad[2, 2] = np.nan
    assert np.isnan(particle_kernels.psd_factors(bad[None])[0][2:, 2]).all()


@pytest.mark.parametrize("sonars", [(0, 1), (0,), (1,)])
@pytest.mark.parametrize("correlated", [False, True])
def test_the_posterior_is_pf_update(sonars, correlated):
    particles, log_weights = cloud(3, 500)
    z, used, q_s = ranges(3)
    used[:] = False
    used[:, list(sonars)] = True
    R = np.array([[0.01, 0.004 if correlated else 0.0], [0.004 if correlated else 0.0, 0.02]])
    x, P, nis, log_post, weights = posterior(
        particles, log_weights, z, used, q_s, np.tile(R, (3, 1, 1))
    )
    for run in range(3):
        ref = pf_update(particles[run].T, log_weights[run], z[run], q_s[run], R, sonars)
        assert_allclose(x[run], ref[0], rtol=1e-12, atol=1e-14)
        assert_allclose(P[run], ref[1], rtol=1e-10, atol=1e-15)
        assert nis[run] == pytest.approx(ref[2], rel=1e-10)
        assert_allclose(log_post[run], ref[3], rtol=1e-12, atol=1e-12)
        assert_allclose(weights[run], np.exp(ref[3]), rtol=1e-12)


def test_a_posterior_that_keeps_too_few_particles_is_tempered_as_the_numpy_update():
    """A wide cloud meets precise ranges: Bayes' rule keeps about one particle. The kernel
    tempers it as the numpy update does (:func:`~drake_uuv.models.particle_filter.tempered`,
    tested in closed form on its own): the same log weights, to rounding, keeping the floor's
    worth of particles; a prior already below the floor is left to Bayes' rule in both."""
    floor = TEMPERING_FLOOR
    particles, log_weights = cloud(2, 3000, spread=2.0)
    log_weights[1, :10] += 50.0  # run 1: ten particles hold the prior's weight
    z, used, q_s = ranges(2)
    R = np.diag([1e-4, 1e-4])
    x, P, nis, log_post, weights = posterior(
        particles, log_weights, z, used, q_s, np.tile(R, (2, 1, 1))
    )
    for run in range(2):
        ref = pf_update(particles[run].T, log_weights[run], z[run], q_s[run], R, (0, 1))
        assert_allclose(log_post[run], ref[3], rtol=1e-9, atol=1e-9)
        assert_allclose(x[run], ref[0], rtol=1e-10, atol=1e-12)
        assert nis[run] == pytest.approx(ref[2], rel=1e-10)
    assert floor <= _size(log_post[0]) <= floor * (1.0 + 1e-6)
    assert _size(log_post[1]) < floor


def test_without_a_range_or_not_live_the_weights_stand():
    particles, log_weights = cloud(2, 200)
    z, used, q_s = ranges(2)
    used[0] = False
    R = np.tile(np.diag([0.01, 0.02]), (2, 1, 1))
    x, P, nis, log_post, _ = posterior(
        particles, log_weights, z, used, q_s, R, live=np.array([True, False])
    )
    assert np.isnan(nis).all() and np.isnan(x[1]).all() and np.isfinite(x[0]).all()
    assert_array_equal(log_post, log_weights)


@pytest.mark.parametrize(
    ("threshold", "bandwidth_scale"), [(0.0, 1.0), (1.0, 1.0), (1.0, 0.0), (0.5, 2.0)]
)
def test_the_periodic_update_is_the_numpy_steps_with_the_same_draws(threshold, bandwidth_scale):
    count = 400
    parameters = ParticleFilterParameters(
        count=count, resample_threshold=threshold, bandwidth_scale=bandwidth_scale
    )
    particles, log_weights = cloud(3, count)
    seeds = np.array([0.1, 0.5, 0.9])
    a_W = np.array([0.3, -0.2, 0.1])
    out, out_log, x, P = advance(particles, log_weights, seeds, parameters, a_W)
    for run in range(3):
        moved, log_next = reference_step(
            particles[run], log_weights[run], seeds[run], parameters, a_W, model=(A, B, W)
        )
        assert_allclose(out[run], moved, rtol=1e-12, atol=1e-12)
        assert_allclose(out_log[run], log_next, rtol=1e-12)
        weights = np.exp(log_next - log_next.max())
        weights /= weights.sum()
        assert_allclose(x[run], weights @ moved, rtol=1e-12)


@pytest.mark.parametrize("resample_threshold", [1.0, 0.0])
def test_the_range_bearing_kernel_is_the_numpy_steps_with_the_same_draws(resample_threshold):
    """Offset stored frame: the kernel's frame and coordinates are the relative position's."""
    count = 400
    parameters = ParticleFilterParameters(
        count=count, resample_threshold=resample_threshold, kernel="range_bearing"
    )
    particles, log_weights = cloud(3, count)
    offset = np.array([0.4, -0.3, 0.2, 0.05, 0.0, -0.05])
    particles -= offset  # stored = relative less the offset
    seeds = np.array([0.1, 0.5, 0.9])
    a_W = np.array([0.3, -0.2, 0.1])
    out, out_log, _, _ = advance(particles, log_weights, seeds, parameters, a_W, offset=offset)
    for run in range(3):
        moved, log_next = reference_step(
            particles[run], log_weights[run], seeds[run], parameters, a_W, model=(A, B, W),
            offset=offset,
        )  # fmt: skip
        assert_allclose(out[run], moved, rtol=1e-11, atol=1e-11)
        assert_allclose(out_log[run], log_next, rtol=1e-12)
    cartesian = ParticleFilterParameters(count=count, resample_threshold=resample_threshold)
    other, _, _, _ = advance(particles, log_weights, seeds, cartesian, a_W, offset=offset)
    # Without resampling the kernels do not act; with it they differ.
    assert np.array_equal(out, other) == (resample_threshold == 0.0)


def _shell(count: int, radius: float, offset: np.ndarray, seed: int = 3):
    """A cloud on the sphere |q| = radius about a direction (relative), at rest, stored less
    ``offset``, with unequal weights (a threshold of 1 resamples it)."""
    rng = np.random.default_rng(seed)
    direction = np.array([-0.7, -0.7, 0.1]) + 0.15 * rng.standard_normal((count, 3))
    q = radius * direction / np.linalg.norm(direction, axis=1, keepdims=True)
    particles = np.hstack([q, np.zeros((count, 3))]) - offset
    return particles[None], -np.log(rng.uniform(1.0, 2.0, (1, count)))


def test_the_range_bearing_kernel_keeps_each_particle_on_its_range_shell():
    """Closed form: particles at one range, at rest, with no process noise, are resampled and
    moved by the kernel only; in range-bearing coordinates each keeps the range exactly (the
    range's variance is 0), in Cartesian ones they leave the shell."""
    count, radius = 2000, 14.0
    offset = np.array([0.5, -0.2, 0.1, 0.0, 0.0, 0.0])
    particles, log_weights = _shell(count, radius, offset)
    no_noise = np.zeros((3, 3))
    ranges = {}
    for kernel in ("range_bearing", "cartesian"):
        parameters = ParticleFilterParameters(count=count, resample_threshold=1.0, kernel=kernel)
        out, out_log, _, _ = advance(
            particles, log_weights, np.array([0.3]), parameters, np.zeros(3), offset=offset,
            W_factor=no_noise,
        )  # fmt: skip
        assert_array_equal(out_log, -math.log(count))  # it resampled
        ranges[kernel] = np.linalg.norm(out[0, :, :3] + offset[:3], axis=1)
    assert_allclose(ranges["range_bearing"], radius, rtol=1e-13)
    assert np.std(ranges["cartesian"]) > 0.01  # h ≈ 0.30 of a cloud ~2 m across
    before = np.linalg.norm(particles[0, :, :3] + offset[:3], axis=1)
    assert_allclose(before, radius, rtol=1e-13)


def test_a_cloud_around_the_vehicle_takes_the_cartesian_kernel():
    """A particle behind the plane normal to the mean direction (bearings would wrap): the
    step is the Cartesian kernel's, bit for bit."""
    count = 300
    particles, log_weights = _shell(count, 3.0, np.zeros(6))
    particles[0, 0, :3] *= -1.0  # one particle on the far side
    result = {}
    for kernel in ("range_bearing", "cartesian"):
        parameters = ParticleFilterParameters(count=count, resample_threshold=1.0, kernel=kernel)
        result[kernel] = advance(particles, log_weights, np.array([0.3]), parameters, np.ones(3))
    for got, want in zip(result["range_bearing"], result["cartesian"], strict=True):
        assert_array_equal(got, want)


def test_range_bearing_coordinates_in_closed_form_and_back():
    """A particle at the mean direction turned by φ toward the frame's second axis and θ
    toward its third has coordinates [r, r̄ φ, r̄ θ]; the map back is the inverse."""
    from drake_uuv.models.range_bearing import (
        from_range_bearing,
        range_bearing_frame,
        to_range_bearing,
    )

    offset = np.array([1.0, 2.0, -0.5, 0.1, 0.2, 0.3])
    q = np.array([[10.0, 9.0, 11.0], [-5.0, -6.0, -4.0], [1.0, 0.5, 1.5]])  # 3 particles
    particles = np.vstack([q, np.ones((3, 3))]) - offset[:, None]
    weights = np.array([0.5, 0.25, 0.25])
    E, radius = range_bearing_frame(particles, weights, offset)
    assert_allclose(E @ E.T, np.eye(3), atol=1e-15)
    assert_allclose(radius, np.linalg.norm(q @ weights))
    assert_allclose(E[0], q @ weights / radius)
    phi, theta, r = 0.1, -0.05, 12.0
    d = r * np.array([np.cos(theta) * np.cos(phi), np.cos(theta) * np.sin(phi), np.sin(theta)])
    one = np.concatenate([E.T @ d, [0.1, 0.2, 0.3]]) - offset
    local = to_range_bearing(one[:, None], (E, radius), offset)
    assert_allclose(local[:, 0], [r, radius * phi, radius * theta, 0.0, 0.0, 0.0], atol=1e-12)
    back = from_range_bearing(to_range_bearing(particles, (E, radius), offset), (E, radius), offset)
    assert_allclose(back, particles, atol=1e-12)
    behind = particles.copy()
    behind[:3, 1] = -(q @ weights) - offset[:3]  # one particle opposite the mean direction
    assert range_bearing_frame(behind, weights, offset) is None


def test_a_batch_is_its_runs_alone_bit_for_bit():
    parameters = ParticleFilterParameters(count=300, resample_threshold=0.9)
    particles, log_weights = cloud(5, 300)
    seeds = np.linspace(0.05, 0.95, 5)
    a_W = np.array([0.3, -0.2, 0.1])
    batch = advance(particles, log_weights, seeds, parameters, a_W)
    z, used, q_s = ranges(5)
    R = np.tile(np.diag([0.01, 0.02]), (5, 1, 1))
    batch_post = posterior(particles, log_weights, z, used, q_s, R)
    for run in range(5):
        alone = advance(
            particles[run : run + 1], log_weights[run : run + 1], seeds[run : run + 1],
            parameters, a_W,
        )  # fmt: skip
        for got, want in zip(batch, alone, strict=True):
            assert_array_equal(got[run], want[0])
        z1, used1, q1 = z[run : run + 1], used[run : run + 1], q_s[run : run + 1]
        post = posterior(particles[run : run + 1], log_weights[run : run + 1], z1, used1, q1, R[:1])
        for got, want in zip(batch_post, post, strict=True):
            assert_array_equal(got[run], want[0])


def test_a_drawn_cloud_predicts_the_gaussian_s_moments_within_the_count_s_errors():
    """Drawn from N(x, P) and moved without resampling: the predicted cloud's moments are
    ``A x + B a`` and ``A P Aᵀ + B W Bᵀ`` within their standard errors (5 of them)."""
    count = 20_000
    parameters = ParticleFilterParameters(count=count, resample_threshold=0.0)
    M = np.random.default_rng(7).standard_normal((6, 6))
    P0 = M @ M.T / 10.0 + 0.05 * np.eye(6)
    a_W = np.array([0.3, -0.2, 0.1])
    empty = np.empty((2, count, 6)), np.empty((2, count))
    _, _, x, P = advance(*empty, np.array([0.3, 0.6]), parameters, a_W, draw=(X0, P0))
    mean = A @ X0 + B @ a_W
    cov = A @ P0 @ A.T + B @ W @ B.T
    for run in range(2):
        error = np.linalg.solve(np.linalg.cholesky(cov), x[run] - mean)
        assert np.all(np.abs(error) < 5.0 / math.sqrt(count)), error
        scale = np.sqrt(np.outer(np.diag(cov), np.diag(cov)))
        assert np.all(np.abs(P[run] - cov) < 5.0 * math.sqrt(2.0 / count) * scale)
    assert not np.array_equal(x[0], x[1])  # each run its own draws
