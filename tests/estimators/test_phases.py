"""The phases of a raw-range filter: the hand-over from the linear start, the particle bridge,
its return to the Gaussian update, the fallback and the redraw of a lost filter."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from drake_uuv.models.filters import predict, range_difference_update
from drake_uuv.models.handover import (
    LOST_NIS,
    Phase,
    cross_range_angle,
    prior_share_predict,
    prior_share_update,
)
from drake_uuv.models.measurement import range_difference_noise
from drake_uuv.models.motion import process_noise_covariance
from drake_uuv.models.particle_filter import (
    ParticleFilterParameters,
    initial_particles,
    pf_update,
    weighted_moments,
)
from drake_uuv.scenario import ParticleFilter, Ukf
from drake_uuv.testing import after_update
from tests.conftest import ETA_UNEQUAL, X0, T, W
from tests.estimators.cloud_host import reference_step
from tests.estimators.range_filters import (
    A_W,
    COUNT,
    NO_BRIDGE,
    P0,
    Q_S,
    X_TRUE,
    A,
    B,
    F,
    R,
    context_of,
    filtered,
    make,
    means,
    uniform_log_weights,
)

PARAMS = ParticleFilterParameters(count=COUNT)
# The UKF's update as configured by default.
ukf_range_update = Ukf().range_update()
#: The filters under the rule without the bridge, and with it.
PLAIN = {"ekf": dict(NO_BRIDGE), "ukf": dict(NO_BRIDGE), "pf": {}}


def test_the_prior_share_follows_the_linear_kf() -> None:
    system = make("ekf", **NO_BRIDGE)
    context = context_of(system)
    z = means()
    m, gamma = range_difference_noise("derived", ETA_UNEQUAL / F, z * z)
    _, P, _ = range_difference_update(X0, P0, 0.5 * (z[0] ** 2 - z[1] ** 2), m, gamma, Q_S)
    # The prior's share is all of P0 at the start: after one update it is still above 10 %.
    after = after_update(system, context)
    assert system.phase(after) is Phase.LINEAR
    S = prior_share_predict(prior_share_update(P0, P, Q_S, gamma), A)
    assert_allclose(system.start.prior_share(after)[0], S, rtol=1e-12)


@pytest.mark.parametrize(("kind", "after"), [("ekf", Phase.RANGE), ("ukf", Phase.RANGE),
                                             ("pf", Phase.PARTICLE)])  # fmt: skip
@pytest.mark.parametrize("forgotten", [True, False])
def test_hand_over_when_the_prior_is_forgotten_and_the_angle_is_small(kind, after, forgotten):
    system = make(kind, **PLAIN[kind])
    context = context_of(system)
    system.start.set_prior_share(context, (0.01 if forgotten else 0.5) * P0)
    # tr P_qq ≈ 0.6 m² at 2.9 m: θ ≈ 0.2 rad < 0.25, so only the share decides.
    next_context = after_update(system, context)
    assert system.phase(next_context) is (after if forgotten else Phase.LINEAR)
    assert system.linear_updates(next_context) == 1


def wide_linear_context(system):
    """A linear-phase context whose prior is forgotten but whose KF is wide: θ ≈ 0.6 rad."""
    context = context_of(system)
    system.set_prior(context, X0, P0 * 8.0)
    system.start.set_prior_share(context, 1e-3 * P0)
    return context


@pytest.mark.parametrize("kind", ["ekf", "ukf"])
def test_a_wide_angle_keeps_a_gaussian_filter_linear_but_not_the_particle_filter(kind):
    for system, expected in ((make(kind, **NO_BRIDGE), Phase.LINEAR), (make("pf"), Phase.PARTICLE)):
        context = wide_linear_context(system)
        assert system.phase(after_update(system, context)) is expected


@pytest.mark.parametrize(("tolerance", "phase"), [(10.0, Phase.RANGE), (0.1, Phase.LINEAR)])
def test_the_second_order_test_uses_the_noise_of_the_means(tolerance, phase):
    # After one update tr P⊥/(2d) ≈ 0.055 m; the means' noise is √(η/f) = 0.058, 0.082 m.
    system = make("ekf", handover_second_order=tolerance, **NO_BRIDGE)
    context = context_of(system)
    system.start.set_prior_share(context, 0.01 * P0)
    assert system.phase(after_update(system, context)) is phase


def drawn_and_predicted(x, P, seed_value=0.5, weigh=None):
    """The cloud a bridge draws from ``N(x, P)`` with the seed port at ``seed_value``, predicted
    (the numpy steps with the cloud's draws for that value: equal to rounding)."""
    return reference_step(
        None, None, seed_value, PARAMS, A_W, model=(A, B, W), draw=(x, P), weigh=weigh
    )


@pytest.mark.parametrize("kind", ["ekf", "ukf"])
def test_a_bridged_gaussian_filter_draws_particles_where_its_gaussian_fails(kind):
    # Prior forgotten, KF wide (θ ≈ 0.6 rad): without the bridge the filter stays linear
    # (above), with it the particles are drawn from the KF's Gaussian of this step.
    system = make(kind)
    context = wide_linear_context(system)
    x, P, status, _ = filtered(system, context)
    moved, log_next = drawn_and_predicted(x, P)
    after = after_update(system, context)
    assert system.phase(after) is Phase.PARTICLE and system.linear_updates(after) == 1
    assert_allclose(system.cloud.particles(after)[0], moved, rtol=1e-12, atol=1e-12)
    assert_array_equal(system.cloud.log_weights(after)[0], log_next)
    mean, cov = weighted_moments(moved.T, np.exp(log_next))
    assert_allclose(system.prior(after).x[0], mean, rtol=1e-12)
    assert_allclose(system.prior(after).P[0], cov, rtol=1e-10)


def particle_phase_context(system, spread: float):
    """A filter in its particle phase, its cloud about X_TRUE with covariance ``spread²·I``
    (position) and 0.01·I (velocity)."""
    context = context_of(system)
    cov = np.diag([spread**2] * 3 + [0.01] * 3)
    particles = initial_particles(X_TRUE, cov, COUNT, np.random.default_rng(1))
    system.set_phase(context, Phase.PARTICLE, 7)
    system.cloud.set_particles(context, particles.T, uniform_log_weights())
    return context, particles


@pytest.mark.parametrize("kind", ["ekf", "ukf"])
@pytest.mark.parametrize(("spread", "after"), [(0.2, Phase.RANGE), (1.5, Phase.PARTICLE)])
def test_a_bridged_filter_takes_its_gaussian_back_when_the_particles_are_narrow(
    kind, spread, after
):
    # The particle step is the particle filter's; the Gaussian test on the particles'
    # posterior decides: 0.2 m at 2.9 m is ≈ 0.1 rad, 1.5 m far above 0.25 rad.
    system = make(kind)
    context, particles = particle_phase_context(system, spread)
    x, P, nis, _ = pf_update(particles, uniform_log_weights(), means(), Q_S, R)
    x_hat, P_hat, status, nis_hat = filtered(system, context)
    assert_allclose(x_hat, x, rtol=1e-12, atol=1e-14)  # the kernel's sums: to rounding
    assert_allclose(P_hat, P, rtol=1e-10, atol=1e-15)
    assert nis_hat == pytest.approx(nis, rel=1e-10)
    next_context = after_update(system, context)
    assert system.phase(next_context) is after and system.linear_updates(next_context) == 7
    if after is Phase.RANGE:  # the Gaussian filter predicts from the particles' posterior
        x_next, P_next = predict(x, P, A_W, A, B, process_noise_covariance(W, T))
        assert_allclose(system.prior(next_context).x[0], x_next, rtol=1e-13)
        assert_allclose(system.prior(next_context).P[0], P_next, rtol=1e-12)


@pytest.mark.parametrize(("scale", "after"), [(1.0, Phase.RANGE), (12.0, Phase.PARTICLE)])
def test_a_bridged_ukf_falls_back_to_particles_when_its_gaussian_widens(scale, after):
    # In its range phase the UKF updates as without the bridge; a posterior wider than
    # 1.2 × 0.25 rad across the line of sight sends it back to particles drawn from it.
    system = make("ukf")
    context = context_of(system)
    system.set_phase(context, Phase.RANGE, 9)
    system.set_prior(context, X0, scale * P0)
    x, P, _ = ukf_range_update(X0, scale * P0, means(), Q_S, R)
    x_hat, P_hat, *_ = filtered(system, context)
    assert_allclose(x_hat, x, rtol=1e-13, atol=1e-15)
    assert_allclose(P_hat, P, rtol=1e-13, atol=1e-15)
    angle = float(np.max(cross_range_angle(x, P, Q_S)))
    assert (angle > 0.3) is (after is Phase.PARTICLE)
    next_context = after_update(system, context)
    assert system.phase(next_context) is after and system.linear_updates(next_context) == 9
    if after is Phase.PARTICLE:
        moved, _ = drawn_and_predicted(x, P)
        assert_allclose(system.cloud.particles(next_context)[0], moved, rtol=1e-12, atol=1e-12)


def test_a_lost_bridged_filter_redraws_from_its_widened_prior():
    # A prior 1.5 m off the truth with a 0.1 m spread: the ranges contradict it (NIS far
    # above 2 ln 10⁶), so the particles are drawn from N(x⁻, P⁻ · NIS/2) and weighed by them.
    system = make("ukf")
    x_prior = X0 + np.array([1.5, -1.0, 0.0, 0.0, 0.0, 0.0])
    P_prior = 0.01 * np.eye(6)
    context = context_of(system)
    system.set_phase(context, Phase.RANGE, 9)
    system.set_prior(context, x_prior, P_prior)
    x, P, nis = ukf_range_update(x_prior, P_prior, means(), Q_S, R)
    assert nis > LOST_NIS and np.max(cross_range_angle(x, P, Q_S)) < 0.3  # not too wide
    assert filtered(system, context)[3] == pytest.approx(nis, rel=1e-12)
    nis = filtered(system, context)[3]  # the filter's own, to the bit, widens the draw
    next_context = after_update(system, context)
    assert system.phase(next_context) is Phase.PARTICLE
    moved, log_next = drawn_and_predicted(
        x_prior, P_prior * (nis / 2.0),
        weigh=lambda drawn: pf_update(drawn.T, uniform_log_weights(), means(), Q_S, R)[3],
    )  # fmt: skip
    assert_allclose(system.cloud.particles(next_context)[0], moved, rtol=1e-12, atol=1e-12)
    assert_allclose(system.cloud.log_weights(next_context)[0], log_next, rtol=1e-12, atol=1e-12)


def test_the_threshold_hand_over_never_leaves_the_range_phase():
    system = make("ukf", handover="threshold")
    context = context_of(system)
    system.set_phase(context, Phase.RANGE, 9)
    system.set_prior(context, X0, 12.0 * P0)  # wide: the rule would fall back to particles
    assert system.cloud is None
    assert system.phase(after_update(system, context)) is Phase.RANGE


def test_the_particle_filter_stays_on_particles():
    system = make("pf")
    assert isinstance(system.policy, type(ParticleFilter().handover_policy()))
    context, _ = particle_phase_context(system, 0.2)  # narrow: a Gaussian filter would leave
    assert system.phase(after_update(system, context)) is Phase.PARTICLE
    assert math.isfinite(filtered(system, context)[3])
