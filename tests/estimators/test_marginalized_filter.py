"""The marginalised particle filter (``!MarginalizedParticleFilter``): its posterior is the
particle filter's on shared seeds (within the particle filter's own sampled spread at that
count), a batch is each run alone (a NaN run included), and bad options fail in one line."""

import numpy as np
import pytest

from drake_uuv import load_scenario
from drake_uuv.estimators import EstimatorSetting, MarginalizedRangeFilter
from drake_uuv.estimators.marginalized_cloud import LATE_RANGES
from drake_uuv.models.handover import Phase
from drake_uuv.models.marginalized_kernels import marginalized_advance
from drake_uuv.models.measurement import range_measurement
from drake_uuv.models.motion import double_integrator
from drake_uuv.models.particle_advance import cloud_advance
from drake_uuv.models.particle_filter import ParticleFilterParameters
from drake_uuv.models.particle_kernels import cloud_posterior
from drake_uuv.models.particle_random import cloud_keys
from drake_uuv.models.timing import PingSchedule
from drake_uuv.scenario.estimators import MarginalizedParticleFilter
from drake_uuv.scenario.validation import ScenarioError
from drake_uuv.testing import assert_batch_equals_runs
from tests.conftest import ETA_UNEQUAL, T, W
from tests.estimators.test_batch import B_BODY, X_TRUE, F, random_runs, setting

COUNT = 40


def maker(**fields):
    config = MarginalizedParticleFilter(gate_probability=0.99, particle_count=COUNT, **fields)

    def make(batch_size: int):
        return MarginalizedRangeFilter(config, setting=setting(False), batch_size=batch_size)

    return make


def particle_runs(B: int, seed: int, nan_run: int | None = None):
    """Random inputs, discrete states and cloud arrays of B runs whose phases mix the linear
    start, and particles live or not."""
    inputs, states = random_runs(maker(), B, seed, nan_run=nan_run)
    rng = np.random.default_rng(seed + 1)
    phases = rng.choice([Phase.LINEAR, Phase.PARTICLE, Phase.PARTICLE], size=B).astype(float)
    states[3][:, 0] = phases
    particles = X_TRUE + 0.2 * rng.standard_normal((B, COUNT, 6))
    log_weights = rng.normal(size=(B, COUNT))
    M = rng.normal(size=(B, 3, 3))
    Sigma = 0.01 * M @ M.transpose(0, 2, 1) + 0.001 * np.eye(3)
    if nan_run is not None:
        particles[nan_run] = np.nan
        Sigma[nan_run] = np.nan
    live = (phases == Phase.PARTICLE).astype(float)
    states.append(Sigma.reshape(B, 9))
    cloud = maker()(1).cloud.state_index
    arrays = {cloud: {"particles": particles, "log_weights": log_weights, "live": live}}
    inputs["particle_seed"] = rng.uniform(size=(B, 1))
    return inputs, states, arrays


@pytest.mark.parametrize("B", [1, 3, 5])
def test_a_batch_step_is_each_run_alone(B: int) -> None:
    inputs, states, arrays = particle_runs(B, seed=B)
    assert_batch_equals_runs(maker(), inputs, states, arrays=arrays)


def test_a_nan_run_leaves_the_others_alone() -> None:
    inputs, states, arrays = particle_runs(4, seed=11, nan_run=2)
    states[3][:, 0] = float(Phase.PARTICLE)
    (cloud,) = arrays.values()
    cloud["live"][:] = 1.0
    assert_batch_equals_runs(maker(), inputs, states, arrays=arrays)


def _simulate_ranges(steps: int, rng: np.random.Generator):
    """A target's relative track, the world baseline turning, and the per-sonar mean ranges."""
    A, Bu = double_integrator(T)
    x, track = X_TRUE.copy(), []
    R = np.diag(ETA_UNEQUAL / F)
    for k in range(steps):
        angle = 0.3 * k
        c, s = np.cos(angle), np.sin(angle)
        q_s = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ B_BODY
        a = 0.1 * rng.normal(size=3)
        z = range_measurement(x, q_s) + rng.multivariate_normal(np.zeros(2), R)
        track.append((z, q_s, a))
        x = A @ x + Bu @ (a - rng.multivariate_normal(np.zeros(3), W))
    return track, R


def _run(marginal: bool, count: int, track, R, x0, P0, seed: int) -> np.ndarray:
    """The filter's posterior mean after the track's ranges (one run, shared seed)."""
    keys_rng = np.random.default_rng(seed)
    parameters = ParticleFilterParameters(count=count)
    A, Bu = double_integrator(T)
    particles, lw = np.zeros((1, count, 6)), np.full((1, count), -np.log(count))
    Sigma = np.zeros((1, 3, 3))
    x, P, nis = np.empty((1, 6)), np.empty((1, 6, 6)), np.empty(1)
    post_lw, post_w = np.empty((1, count)), np.empty((1, count))
    one, no = np.ones(1, dtype=bool), np.zeros(1, dtype=bool)
    for k, (z, q_s, a) in enumerate(track):
        first = k == 0
        if not first:
            cloud_posterior(
                particles, lw, np.zeros((1, 6)), z[None], np.ones((1, 2), dtype=bool), q_s[None],
                R[None], one, x, P, nis, post_lw, post_w,
            )  # fmt: skip
        if k == len(track) - 1:
            return x[0]
        keys = cloud_keys(keys_rng.uniform(size=1))
        out, out_lw = np.empty_like(particles), np.empty_like(lw)
        xp, Pp = np.empty((1, 6)), np.empty((1, 6, 6))
        common = (
            post_lw, post_w, x.copy(), P.copy(), keys, one, one if first else no, x0[None],
            P0[None], no, np.zeros((1, 6)), z[None], np.ones((1, 2), dtype=bool), q_s[None],
            R[None], T, a[None],
        )  # fmt: skip
        tail = (parameters.resample_threshold, parameters.bandwidth, False, out, out_lw)
        if marginal:
            out_S = np.empty((1, 3, 3))
            Q = (Bu @ W @ Bu.T)[None]
            marginalized_advance(particles, lw, Sigma, ~one if first else one, *common, Q, *tail,
                                 out_S, xp, Pp)  # fmt: skip
            Sigma = out_S
        else:
            W_factor, jitter = np.linalg.cholesky(W), np.zeros((1, 6, 6))
            cloud_advance(particles, lw, ~one if first else one, *common, W_factor, jitter, *tail,
                          xp, Pp)  # fmt: skip
        particles, lw = out, out_lw
    raise AssertionError("unreachable")


@pytest.mark.slow
def test_the_posterior_is_the_particle_filter_s_on_shared_seeds() -> None:
    """Both filters, drawn from the same Gaussian, take the same ranges for 30 steps with the
    same seed per run. The tolerance is sampled: the spread of the particle filter's
    posterior mean over seeds at the count (its Monte Carlo error); each seed's difference is
    within 5 such spreads (of both filters), and their mean within 5 standard errors."""
    rng = np.random.default_rng(4)
    track, R = _simulate_ranges(30, rng)
    x0, P0 = X_TRUE + np.array([0.1, -0.1, 0.05, 0.02, 0.0, 0.0]), 0.05 * np.eye(6)
    count, seeds = 2000, range(12)
    pf = np.array([_run(False, count, track, R, x0, P0, s) for s in seeds])
    mpf = np.array([_run(True, count, track, R, x0, P0, s) for s in seeds])
    spread = np.sqrt(pf.var(axis=0, ddof=1) + mpf.var(axis=0, ddof=1))
    difference = mpf - pf
    assert np.all(np.abs(difference) <= 5 * spread), (difference, spread)
    mean_error = np.abs(difference.mean(axis=0))
    assert np.all(mean_error <= 5 * difference.std(axis=0, ddof=1) / np.sqrt(len(seeds)))
    # The marginalised filter's own Monte Carlo error is no larger than the particle filter's.
    assert np.all(mpf.std(axis=0)[3:] <= 1.5 * pf.std(axis=0)[3:])


@pytest.mark.parametrize(
    ("override", "message"),
    [
        ("estimator.particle_count=5", r"^estimator\.particle_count: must be in \[10, 1e7\], got 5$"),
        ("estimator.linear_start_max_steps=0", r"^estimator\.linear_start_max_steps: must not be 0"),
        ("estimator.particle_resample_threshold=2", r"^estimator\.particle_resample_threshold: must be in \[0, 1\]"),
        ("estimator.particle_bandwidth_scale=-1", r"^estimator\.particle_bandwidth_scale: "),
    ],
)  # fmt: skip
def test_bad_options_fail_in_one_line_naming_the_field(override: str, message: str) -> None:
    with pytest.raises(ScenarioError, match=message):
        load_scenario("paper", ["estimator=MarginalizedParticleFilter", override])


@pytest.mark.parametrize("B", [1, 2])
def test_late_ranges_are_refused_in_one_line(B: int) -> None:
    timed = EstimatorSetting(
        time_step=T, acceleration_covariance=W, noise_variances=ETA_UNEQUAL,
        samples_per_step=F, baseline_B=B_BODY, ping_schedule=PingSchedule(T, (0.1, 0.3), 0.6),
    )  # fmt: skip
    with pytest.raises(ValueError, match=r"^sonar\.ping_offsets: the marginalised") as error:
        MarginalizedRangeFilter(MarginalizedParticleFilter(), setting=timed, batch_size=B)
    assert str(error.value) == LATE_RANGES and "\n" not in LATE_RANGES
    # With error_model: ideal the ranges are taken at their tick: it builds.
    MarginalizedRangeFilter(
        MarginalizedParticleFilter(error_model="ideal", particle_count=COUNT),
        setting=timed, batch_size=B,
    )  # fmt: skip


def test_late_ranges_are_refused_when_the_scenario_is_loaded() -> None:
    """Before any system is built: one line naming the field (the command line prints it)."""
    from drake_uuv.scenario import ScenarioError, load_scenario

    with pytest.raises(
        ScenarioError,
        match=r"^sonar.ping_offsets: must be zero, with sonar.latency, for the marginalised "
        r"particle filter with error_model: modelled .*got \[0.0, 0.25\]$",
    ):
        load_scenario("realistic", ["estimator=MarginalizedParticleFilter"])
