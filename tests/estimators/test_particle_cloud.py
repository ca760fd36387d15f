"""The particle filter's cloud in a raw-range filter (one run): the filtered estimate is the
numpy reweighting (to rounding) and does not read the random port; the periodic update is the
numpy steps with the draws the port's value keys; the cloud is drawn from the linear KF at the
hand-over; a run is reproducible from the diagram's seed. Batches: test_particle_batch.py."""

import math
from dataclasses import replace

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from pydrake.common import RandomDistribution, RandomGenerator
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import (
    ConstantVectorSource,
    LogVectorOutput,
    RandomSource,
    ZeroOrderHold,
)
from threadpoolctl import threadpool_info, threadpool_limits

from drake_uuv.estimators import RangeFilter
from drake_uuv.estimators.particle_window import _on_one_blas_thread
from drake_uuv.models.handover import Phase
from drake_uuv.models.measurement import DROPPED, VALID
from drake_uuv.models.motion import process_noise_covariance
from drake_uuv.models.navigation_noise import NavigationErrors, commanded_acceleration_noise
from drake_uuv.models.particle_filter import (
    ParticleFilterParameters,
    initial_particles,
    pf_update,
    weighted_moments,
)
from drake_uuv.models.particle_kernels import psd_factors
from drake_uuv.scenario import ParticleFilter
from drake_uuv.testing import after_update
from tests.conftest import X0, T, W
from tests.estimators.cloud_host import reference_step
from tests.estimators.range_filters import (
    A_W,
    COUNT,
    P0,
    Q_S,
    SETTING,
    A,
    B,
    F,
    R,
    context_of,
    filtered,
    inputs,
    make,
    means,
    uniform_log_weights,
)

PARAMS = ParticleFilterParameters(count=COUNT)
MODEL = (A, B, W)


def particle_context(seed_value: float = 0.25, **overrides):
    """A particle filter in its particle phase, holding a seeded cloud about X0 with unequal
    weights (particles N×6)."""
    system = make("pf")
    context = context_of(system, seed_value=seed_value, **overrides)
    particles = initial_particles(X0, P0, COUNT, np.random.default_rng(1)).T
    log_w = -np.log(np.random.default_rng(2).uniform(1.0, 2.0, COUNT))
    system.set_phase(context, Phase.PARTICLE, 3)
    system.cloud.set_particles(context, particles, log_w)
    return system, context, particles, log_w


def test_output_is_the_numpy_update_and_ignores_the_random_port():
    system, context, particles, log_w = particle_context()
    x, P, nis, log_post = pf_update(particles.T, log_w, means(), Q_S, R)
    x_hat, P_hat, status, nis_hat = filtered(system, context)
    # The kernel's sums run in another order than numpy's: equal to rounding.
    assert_allclose(x_hat, x, rtol=1e-12, atol=1e-14)
    assert_allclose(P_hat, P, rtol=1e-10, atol=1e-15)
    assert status == VALID and nis_hat == pytest.approx(nis, rel=1e-10)
    assert_allclose(
        np.reshape(system.cloud.posterior(context)[3], -1), log_post, rtol=1e-12, atol=1e-12
    )
    system.GetInputPort("particle_seed").FixValue(context, [0.75])
    assert_array_equal(filtered(system, context)[0], x_hat)


def test_only_a_cloud_with_late_ranges_reports_arrived_innovations():
    """Without late ranges a tick's innovations are its posterior's NIS and its valid ranges
    (the host counts them); only the window path reports its own."""
    system, context, _, _ = particle_context()
    with pytest.raises(ValueError, match=r"^innovations: only with late ranges"):
        system.cloud.innovations(context)


def test_update_is_the_reference_step_seeded_by_the_port():
    """The periodic update is :func:`reference_step` (the numpy steps) with the kernel's own
    draws for the port's value: equal to rounding. (Before the batch, the draws came from a
    numpy generator seeded by the port; the numbers changed with the counter-based draws.)"""
    system, context, particles, log_w = particle_context(seed_value=0.25)
    *_, log_post = pf_update(particles.T, log_w, means(), Q_S, R)
    moved, log_next = reference_step(particles, log_post, 0.25, PARAMS, A_W, model=MODEL)
    after = after_update(system, context)
    assert_allclose(system.cloud.particles(after)[0], moved, rtol=1e-12, atol=1e-12)
    assert_allclose(system.cloud.log_weights(after)[0], log_next, rtol=1e-12, atol=1e-12)
    x, P = weighted_moments(moved.T, np.exp(log_next))
    assert_allclose(system.prior(after).x[0], x, rtol=1e-12)
    assert_allclose(system.prior(after).P[0], P, rtol=1e-10)
    # Same draw, same cloud; another draw, another cloud.
    again = system.cloud.particles(after_update(system, context))
    assert_array_equal(again, system.cloud.particles(after))
    system.GetInputPort("particle_seed").FixValue(context, [0.26])
    assert not np.array_equal(system.cloud.particles(after_update(system, context)), again)


def test_without_a_measurement_the_predicted_weights_stand():
    system, context, particles, log_w = particle_context(
        sonar_status=[DROPPED, DROPPED], range_samples=np.full(2 * F, np.nan)
    )
    moved, log_next = reference_step(particles, log_w, 0.25, PARAMS, A_W, model=MODEL)
    after = after_update(system, context)
    assert_allclose(system.cloud.particles(after)[0], moved, rtol=1e-12, atol=1e-12)
    assert_array_equal(system.cloud.log_weights(after)[0], log_w)  # no resampling: carried


def test_the_cloud_is_drawn_from_the_kf_at_the_hand_over():
    system = make("pf")
    context = context_of(system)
    system.start.set_prior_share(context, 0.01 * P0)
    x, P, *_ = filtered(system, context)
    drawn, log_next = reference_step(
        None, None, 0.5, PARAMS, A_W, model=MODEL, draw=(x, P)
    )  # fmt: skip
    after = after_update(system, context)
    assert system.phase(after) is Phase.PARTICLE and system.linear_updates(after) == 1
    assert_allclose(system.cloud.particles(after)[0], drawn, rtol=1e-12, atol=1e-12)
    assert_array_equal(system.cloud.log_weights(after)[0], log_next)
    assert system.cloud.live(after).tolist() == [True]


def test_navigation_particles_are_the_targets_negated_plus_the_vehicle():
    """With the vehicle's state from its navigation the cloud is stored as the target's
    particles negated; read back, it is relative states again, and it moves by the target's
    model alone (no commanded acceleration)."""
    config = ParticleFilter(
        initial_estimate=X0.tolist(), initial_covariance=P0.tolist(), particle_count=COUNT,
        vehicle_motion="navigation",
    )  # fmt: skip
    system = RangeFilter(config, setting=SETTING)
    X = np.array([4.0, -1.0, 0.5, 0.3, 0.1, -0.2])
    values = inputs(system, p_WU_nav=X[:3], v_WU_nav=X[3:])
    del values["u1_W"]
    context = system.CreateDefaultContext()
    for name, value in values.items():
        system.GetInputPort(name).FixValue(context, np.asarray(value, dtype=float))
    particles = initial_particles(X0, P0, COUNT, np.random.default_rng(1)).T
    system.cloud.set_particles(context, particles, uniform_log_weights())
    system.set_phase(context, Phase.PARTICLE, 3)
    assert_allclose(system.cloud.particles(context)[0], particles, rtol=1e-14, atol=1e-14)
    *_, log_post = pf_update(particles.T, uniform_log_weights(), means(), Q_S, R)
    target, _ = reference_step(particles - X, log_post, 0.5, PARAMS, np.zeros(3), model=MODEL)
    after = after_update(system, context)
    X_next = X + 0.1
    system.GetInputPort("p_WU_nav").FixValue(after, X_next[:3])
    system.GetInputPort("v_WU_nav").FixValue(after, X_next[3:])
    assert_allclose(system.cloud.particles(after)[0], target + X_next, rtol=1e-12, atol=1e-12)


def test_with_navigation_errors_each_particle_draws_their_process_noise():
    """The Gaussian filters add ``Q_nav`` (the navigation's process noise at this tick) to
    their Q: the cloud's prediction is the reference step plus a draw of ``N(0, Q_nav)`` per
    particle, from the particle's own slots."""
    errors = NavigationErrors(attitude_noise=np.radians([1.0, 1.0, 3.0]))
    config = ParticleFilter(
        initial_estimate=X0.tolist(), initial_covariance=P0.tolist(), particle_count=COUNT,
    )  # fmt: skip
    system = RangeFilter(config, setting=replace(SETTING, navigation_errors=errors))
    context = context_of(system, sonar_status=[DROPPED, DROPPED],
                         range_samples=np.full(2 * F, np.nan))  # fmt: skip
    particles = initial_particles(X0, P0, COUNT, np.random.default_rng(1)).T
    system.set_phase(context, Phase.PARTICLE, 3)
    system.cloud.set_particles(context, particles, uniform_log_weights())
    Q_nav = process_noise_covariance(commanded_acceleration_noise(A_W, np.radians(
        np.diag([1.0, 1.0, 3.0])) ** 2), T)  # fmt: skip
    root = psd_factors(Q_nav[np.newaxis])[0]
    assert_allclose(root @ root.T, Q_nav, rtol=1e-9, atol=1e-15)  # a factor of rank 3
    moved, log_next = reference_step(
        particles, uniform_log_weights(), 0.5, PARAMS, A_W, model=MODEL, jitter=root
    )
    after = after_update(system, context)
    assert_allclose(system.cloud.particles(after)[0], moved, rtol=1e-12, atol=1e-12)
    assert_array_equal(system.cloud.log_weights(after)[0], log_next)


def build_loop():
    """The particle filter fed constant ranges and its seed from a seeded uniform source."""
    builder = DiagramBuilder()
    config = ParticleFilter(
        initial_estimate=X0.tolist(), initial_covariance=P0.tolist(), particle_count=COUNT,
        linear_start_max_steps=2,
    )  # fmt: skip
    system = builder.AddSystem(RangeFilter(config, setting=SETTING))
    for name, value in inputs(system, u1_W=np.zeros(3)).items():
        if name == "particle_seed":
            continue
        source = builder.AddSystem(ConstantVectorSource(np.asarray(value, dtype=float)))
        builder.Connect(source.get_output_port(), system.GetInputPort(name))
    uniform = builder.AddSystem(RandomSource(RandomDistribution.kUniform, 1, T))
    hold = builder.AddSystem(ZeroOrderHold(T, 1))
    builder.Connect(uniform.get_output_port(), hold.get_input_port())
    builder.Connect(hold.get_output_port(), system.GetInputPort("particle_seed"))
    logger = LogVectorOutput(system.GetOutputPort("x_TU_hat"), builder, T)
    return builder.Build(), logger


def run_loop(seed: int, steps: int = 12) -> np.ndarray:
    diagram, logger = build_loop()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    diagram.SetRandomContext(context, RandomGenerator(seed))
    simulator.AdvanceTo(steps * T)
    return logger.FindLog(context).data().T


def test_runs_are_reproducible_from_the_diagram_seed():
    first, again, other = run_loop(3), run_loop(3), run_loop(4)
    assert_array_equal(first, again)
    # Steps 0 and 1 are the linear start; the particles drawn at step 1 depend on the seed.
    assert_array_equal(first[:2], other[:2])
    assert not np.any(np.all(first[2:] == other[2:], axis=1))
    assert math.isfinite(float(first[-1, 0]))


def test_the_cloud_s_steps_run_with_blas_on_one_thread_and_restore_its_count():
    def blas_threads() -> list[int]:
        return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]

    @_on_one_blas_thread
    def step(fail: bool) -> list[int]:
        inside = blas_threads()
        if fail:
            raise RuntimeError("a step that fails")
        return inside

    with threadpool_limits(limits=2, user_api="blas"):
        assert step(False) == [1] * len(blas_threads())
        assert blas_threads() and set(blas_threads()) == {2}
        with pytest.raises(RuntimeError, match="a step that fails"):
            step(True)
        assert set(blas_threads()) == {2}
