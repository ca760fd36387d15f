"""The UKF and particle-filter LeafSystems, and the new hand-over in every raw-range system.

Each system alone with ``FixValue``d inputs against the plain-numpy steps of
``drake_uuv/models``; the particle filter's reproducibility from the random port, alone and in
a small diagram run under the Simulator.
"""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from pydrake.common import RandomDistribution, RandomGenerator
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import (
    AddRandomInputs,
    ConstantVectorSource,
    LogVectorOutput,
    RandomSource,
    ZeroOrderHold,
)

from drake_uuv.estimators.linear_start import LINEAR_PHASE, PARTICLE_PHASE, RANGE_PHASE
from drake_uuv.estimators.particle_filter import ParticleRangeEstimator
from drake_uuv.estimators.raw_range_filter import RawRangeEstimator
from drake_uuv.estimators.unscented_filter import UnscentedRangeEstimator
from drake_uuv.models.filters import HandoverPolicy, predict, range_difference_update
from drake_uuv.models.handover import (
    LOST_NIS,
    HandoverRule,
    cross_range_angle,
    prior_share_predict,
    prior_share_update,
)
from drake_uuv.models.measurement import (
    DROPPED,
    VALID,
    range_difference_noise,
    range_measurement,
)
from drake_uuv.models.motion import double_integrator, process_noise_covariance
from drake_uuv.models.particle_filter import (
    ParticleFilterParameters,
    initial_particles,
    pf_predict,
    pf_update,
    weighted_moments,
)
from drake_uuv.models.unscented import SigmaPointParameters, ukf_range_update
from drake_uuv.testing import discrete_update, fixed_context
from tests.conftest import ETA_UNEQUAL, X0, T, W

F = 3
P0 = np.diag([0.3, 0.2, 0.25, 0.1, 0.1, 0.1]) + 0.01
Q_S = np.array([-0.6, 1.1, 0.5])
A_W = np.array([1.0, -3.0, 0.5])
X_TRUE = np.array([-2.0, -2.0, 0.3, 0.0, 0.0, 0.0])
A, B = double_integrator(T)
R = np.diag(ETA_UNEQUAL / F)
RANGE_ONLY = HandoverRule(max_linear_steps=0)
# The Gaussian filters' rules without and with the particle bridge.
NO_BRIDGE = HandoverRule(second_order_tolerance=1.0)
BRIDGE = HandoverRule(particle_bridge=True)
COUNT = 400
PARAMS = ParticleFilterParameters(count=COUNT)


def samples(seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    d = range_measurement(X_TRUE, Q_S)
    return (d[:, None] + np.sqrt(ETA_UNEQUAL)[:, None] * rng.standard_normal((2, F))).ravel()


def inputs(**overrides) -> dict[str, np.ndarray]:
    values = dict(range_samples=samples(), b_W=Q_S, u1_W=A_W, sonar_status=np.zeros(2))
    values.update(overrides)
    return values


def filtered(system, context):
    return (
        system.GetOutputPort("x_TU_hat").Eval(context),
        system.GetOutputPort("P_TU").Eval(context).reshape(6, 6),
        int(system.GetOutputPort("measurement_status").Eval(context)[0]),
        float(system.GetOutputPort("nis").Eval(context)[0]),
    )


def ukf(handover=RANGE_ONLY, **kwargs):
    return UnscentedRangeEstimator(T, W, X0, P0, ETA_UNEQUAL, F, handover=handover, **kwargs)


def pf(handover=None, parameters=PARAMS, **kwargs):
    return ParticleRangeEstimator(
        T, W, X0, P0, ETA_UNEQUAL, F, handover=handover, parameters=parameters, **kwargs
    )


def ekf(handover=None, **kwargs):
    return RawRangeEstimator(T, W, X0, P0, ETA_UNEQUAL, F, handover=handover, **kwargs)


def pf_context(seed_value: float = 0.25, **overrides):
    """A particle filter in its range phase, holding a seeded cloud about X0."""
    system = pf()
    context = fixed_context(system, particle_seed=[seed_value], **inputs(**overrides))
    particles = initial_particles(X0, P0, COUNT, np.random.default_rng(1))
    log_w = -np.log(np.random.default_rng(2).uniform(1.0, 2.0, COUNT))  # unequal weights
    context.SetDiscreteState(system.start_state_index, [PARTICLE_PHASE, 3.0])
    context.SetDiscreteState(system.particles_index, particles.ravel())
    context.SetDiscreteState(system.log_weights_index, log_w)
    return system, context, particles, log_w


# ---------------------------------------------------------------------------------- ports


def bridged_ekf():
    return ekf(particle_parameters=PARAMS)


@pytest.mark.parametrize("make", [ukf, pf, bridged_ekf])
def test_ports_match_the_raw_range_estimator(make):
    system = make()
    reference = ekf(handover=NO_BRIDGE)
    names = [reference.get_input_port(i).get_name() for i in range(reference.num_input_ports())]
    extra = ["particle_seed"] if system.particle_parameters is not None else []
    assert [system.get_input_port(i).get_name() for i in range(system.num_input_ports())] == [
        *names,
        *extra,
    ]
    for i in range(reference.num_output_ports()):
        port = reference.get_output_port(i)
        assert system.GetOutputPort(port.get_name()).size() == port.size()
    x_hat = system.GetOutputPort("x_TU_hat").get_index()
    for name in ("range_samples", "b_W", "sonar_status"):
        assert system.HasDirectFeedthrough(system.GetInputPort(name).get_index(), x_hat)
    for name in ["u1_W", *extra]:
        assert not system.HasDirectFeedthrough(system.GetInputPort(name).get_index(), x_hat)
    builder = DiagramBuilder()
    builder.AddSystem(system)
    assert AddRandomInputs(T, builder) == len(extra)  # exactly the seed port is random


# ------------------------------------------------------------------------------------ UKF


def test_ukf_step_is_the_numpy_update_then_the_prediction():
    system = ukf()
    context = fixed_context(system, **inputs())
    z = samples().reshape(2, F).mean(axis=1)
    x, P, nis = ukf_range_update(X0, P0, z, Q_S, R)
    x_hat, P_hat, status, nis_hat = filtered(system, context)
    assert_allclose(x_hat, x, rtol=1e-13, atol=1e-15)
    assert_allclose(P_hat, P, rtol=1e-13, atol=1e-15)
    assert (status, nis_hat) == (VALID, pytest.approx(nis, rel=1e-12))
    x_next, P_next = predict(x, P, A_W, A, B, process_noise_covariance(W, T))
    assert_allclose(discrete_update(system, context, 0), x_next, rtol=1e-13)
    assert_allclose(discrete_update(system, context, 1).reshape(6, 6), P_next, rtol=1e-12)
    assert_allclose(discrete_update(system, context, system.start_state_index), [RANGE_PHASE, 0])


def test_ukf_uses_its_sigma_point_parameters():
    params = SigmaPointParameters(alpha=0.5, beta=0.0, kappa=0.0)
    system = ukf(sigma_points=params)
    context = fixed_context(system, **inputs())
    z = samples().reshape(2, F).mean(axis=1)
    assert_allclose(
        filtered(system, context)[0], ukf_range_update(X0, P0, z, Q_S, R, (0, 1), params)[0]
    )


@pytest.mark.parametrize("missing", [0, 1])
def test_ukf_with_one_sonar_updates_with_its_range(missing):
    status = np.zeros(2)
    status[missing] = DROPPED
    measured = samples().reshape(2, F)
    measured[missing] = np.nan
    system = ukf()
    context = fixed_context(system, **inputs(range_samples=measured.ravel(), sonar_status=status))
    z = measured.mean(axis=1)
    x, P, nis = ukf_range_update(X0, P0, z, Q_S, R, sonars=(1 - missing,))
    x_hat, P_hat, code, nis_hat = filtered(system, context)
    assert_allclose(x_hat, x, rtol=1e-13, atol=1e-15)
    assert (code, nis_hat) == (VALID, pytest.approx(nis, rel=1e-12))


# ------------------------------------------------------------------ linear start, hand-over


@pytest.mark.parametrize("make", [ekf, ukf, pf])
def test_linear_phase_is_the_papers_kf_and_the_prior_share_follows_it(make):
    system = make(handover=HandoverRule())
    context = fixed_context(system, **inputs(), **_seed(system))
    assert system.in_linear_phase(context)
    z = samples().reshape(2, F).mean(axis=1)
    m, gamma = range_difference_noise("derived", ETA_UNEQUAL / F, z * z)
    Y = 0.5 * (z[0] ** 2 - z[1] ** 2)
    x, P, nis = range_difference_update(X0, P0, Y, m, gamma, Q_S)
    x_hat, P_hat, status, nis_hat = filtered(system, context)
    assert_allclose(x_hat, x, rtol=1e-13, atol=1e-15)
    assert_allclose(P_hat, P, rtol=1e-13, atol=1e-15)
    assert (status, nis_hat) == (VALID, pytest.approx(nis, rel=1e-12))
    # The prior's share is all of P0 at the start: after one update it is still above 10 %.
    assert_allclose(discrete_update(system, context, system.start_state_index), [LINEAR_PHASE, 1])
    S = prior_share_predict(prior_share_update(P0, P, Q_S, gamma), A)
    assert_allclose(
        discrete_update(system, context, system.prior_share_index).reshape(6, 6), S, rtol=1e-12
    )


@pytest.mark.parametrize(("make", "after"), [(ekf, RANGE_PHASE), (ukf, RANGE_PHASE),
                                             (pf, PARTICLE_PHASE)])  # fmt: skip
@pytest.mark.parametrize("forgotten", [True, False])
def test_hand_over_when_the_prior_is_forgotten_and_the_angle_is_small(make, after, forgotten):
    system = make(handover=HandoverRule())
    context = fixed_context(system, **inputs(), **_seed(system))
    context.SetDiscreteState(system.prior_share_index, ((0.01 if forgotten else 0.5) * P0).ravel())
    # tr P_qq ≈ 0.6 m² at 2.9 m: θ ≈ 0.2 rad < 0.25, so only the share decides.
    phase = after if forgotten else LINEAR_PHASE
    assert_allclose(discrete_update(system, context, system.start_state_index), [phase, 1])


def wide_linear_context(system):
    """A linear-phase context whose prior is forgotten but whose KF is wide: θ ≈ 0.6 rad."""
    context = fixed_context(system, **inputs(), **_seed(system))
    context.SetDiscreteState(1, (P0 * 8.0).ravel())
    context.SetDiscreteState(system.prior_share_index, (1e-3 * P0).ravel())
    return context


@pytest.mark.parametrize("make", [ekf, ukf])
def test_a_wide_angle_keeps_a_gaussian_filter_linear_but_not_the_particle_filter(make):
    for system, expected in ((make(handover=HandoverRule()), LINEAR_PHASE), (pf(), PARTICLE_PHASE)):
        context = wide_linear_context(system)
        assert discrete_update(system, context, system.start_state_index)[0] == expected


@pytest.mark.parametrize("make", [ekf, ukf, pf])
def test_a_step_without_both_ranges_only_predicts_in_the_linear_phase(make):
    system = make(handover=HandoverRule())
    status = np.array([VALID, DROPPED])
    measured = samples().reshape(2, F)
    measured[1] = np.nan
    context = fixed_context(
        system, **inputs(range_samples=measured.ravel(), sonar_status=status), **_seed(system)
    )
    x_hat, P_hat, code, nis = filtered(system, context)
    assert_allclose(x_hat, X0)
    assert code == DROPPED and math.isnan(nis)
    assert_allclose(discrete_update(system, context, system.start_state_index), [LINEAR_PHASE, 0])
    S = discrete_update(system, context, system.prior_share_index).reshape(6, 6)
    assert_allclose(S, A @ P0 @ A.T, rtol=1e-13)


def test_the_ekf_accepts_both_hand_overs():
    # The rule by default, with the second-order test the EKF needs.
    assert ekf().handover == HandoverRule(second_order_tolerance=1.0, particle_bridge=True)
    assert isinstance(ekf(handover=HandoverPolicy()).handover, HandoverPolicy)
    system = ekf(handover=HandoverRule())
    context = fixed_context(system, **inputs())
    context.SetDiscreteState(system.prior_share_index, (0.01 * P0).ravel())
    assert_allclose(discrete_update(system, context, system.start_state_index), [RANGE_PHASE, 1])


def _seed(system) -> dict:
    return {"particle_seed": [0.5]} if system.HasInputPort("particle_seed") else {}


# -------------------------------------------------------------------------- particle filter


def test_particle_filter_output_is_the_numpy_update_and_ignores_the_random_port():
    system, context, particles, log_w = pf_context()
    z = samples().reshape(2, F).mean(axis=1)
    x, P, nis, _ = pf_update(particles, log_w, z, Q_S, R)
    x_hat, P_hat, status, nis_hat = filtered(system, context)
    assert_array_equal(x_hat, x)
    assert_array_equal(P_hat, P)
    assert (status, nis_hat) == (VALID, nis)
    system.GetInputPort("particle_seed").FixValue(context, [0.75])
    assert_array_equal(filtered(system, context)[0], x)


def test_particle_filter_update_is_the_numpy_prediction_seeded_by_the_port():
    system, context, particles, log_w = pf_context(seed_value=0.25)
    z = samples().reshape(2, F).mean(axis=1)
    *_, log_post = pf_update(particles, log_w, z, Q_S, R)
    rng = np.random.default_rng(int(0.25 * 2.0**53))
    moved, log_next, _ = pf_predict(particles, log_post, A_W, A, B, W, rng, PARAMS)
    assert_array_equal(discrete_update(system, context, system.particles_index), moved.ravel())
    assert_array_equal(discrete_update(system, context, system.log_weights_index), log_next)
    x, P = weighted_moments(moved, np.exp(log_next))
    assert_allclose(discrete_update(system, context, 0), x, rtol=1e-14)
    assert_allclose(discrete_update(system, context, 1).reshape(6, 6), P, rtol=1e-12)
    # Same draw, same cloud; another draw, another cloud.
    again = discrete_update(system, context, system.particles_index)
    assert_array_equal(again, moved.ravel())
    system.GetInputPort("particle_seed").FixValue(context, [0.26])
    assert not np.array_equal(discrete_update(system, context, system.particles_index), again)


def test_particle_filter_without_a_measurement_keeps_the_predicted_weights():
    status = np.array([DROPPED, DROPPED])
    system, context, particles, log_w = pf_context(
        sonar_status=status, range_samples=np.full(2 * F, np.nan)
    )
    rng = np.random.default_rng(int(0.25 * 2.0**53))
    moved, log_next, _ = pf_predict(particles, log_w, A_W, A, B, W, rng, PARAMS)
    assert_array_equal(discrete_update(system, context, system.particles_index), moved.ravel())
    assert_array_equal(discrete_update(system, context, system.log_weights_index), log_next)


def test_particle_filter_draws_its_cloud_from_the_kf_at_the_hand_over():
    system = pf()
    context = fixed_context(system, particle_seed=[0.5], **inputs())
    context.SetDiscreteState(system.prior_share_index, (0.01 * P0).ravel())
    x, P, *_ = filtered(system, context)
    rng = np.random.default_rng(int(0.5 * 2.0**53))
    drawn = initial_particles(x, P, COUNT, rng)
    moved, log_next, _ = pf_predict(
        drawn, np.full(COUNT, -math.log(COUNT)), A_W, A, B, W, rng, PARAMS
    )
    assert_allclose(discrete_update(system, context, system.start_state_index), [PARTICLE_PHASE, 1])
    assert_array_equal(discrete_update(system, context, system.particles_index), moved.ravel())
    assert_array_equal(discrete_update(system, context, system.log_weights_index), log_next)


# ------------------------------------------------------------------------ particle bridge


def bridged(make, **kwargs):
    """``make``'s filter with the particle bridge (and, for the EKF, its second-order test)."""
    second_order = 1.0 if make is ekf else None
    rule = HandoverRule(particle_bridge=True, second_order_tolerance=second_order)
    return make(handover=rule, particle_parameters=PARAMS, **kwargs)


def drawn_and_predicted(x, P, seed_value=0.5):
    """The cloud a bridge draws from ``N(x, P)`` with the seed port at ``seed_value``, predicted."""
    rng = np.random.default_rng(int(seed_value * 2.0**53))
    drawn = initial_particles(x, P, COUNT, rng)
    return pf_predict(drawn, np.full(COUNT, -math.log(COUNT)), A_W, A, B, W, rng, PARAMS)


@pytest.mark.parametrize("make", [ekf, ukf])
def test_a_bridged_gaussian_filter_draws_particles_where_its_gaussian_fails(make):
    # Prior forgotten, KF wide (θ ≈ 0.6 rad): without the bridge the filter stays linear
    # (above), with it the particles are drawn from the KF's Gaussian of this step.
    system = bridged(make)
    context = wide_linear_context(system)
    x, P, status, _ = filtered(system, context)
    assert status == VALID
    moved, log_next, _ = drawn_and_predicted(x, P)
    assert_allclose(discrete_update(system, context, system.start_state_index), [PARTICLE_PHASE, 1])
    assert_array_equal(discrete_update(system, context, system.particles_index), moved.ravel())
    assert_array_equal(discrete_update(system, context, system.log_weights_index), log_next)
    mean, cov = weighted_moments(moved, np.exp(log_next))
    assert_allclose(discrete_update(system, context, 0), mean, rtol=1e-14)
    assert_allclose(discrete_update(system, context, 1).reshape(6, 6), cov, rtol=1e-12)


def particle_phase_context(system, spread: float):
    """A bridged filter in its particle phase, its cloud about X_TRUE with covariance
    ``spread²·I`` (position) and 0.01·I (velocity)."""
    context = fixed_context(system, particle_seed=[0.5], **inputs())
    cov = np.diag([spread**2] * 3 + [0.01] * 3)
    particles = initial_particles(X_TRUE, cov, COUNT, np.random.default_rng(1))
    context.SetDiscreteState(system.start_state_index, [PARTICLE_PHASE, 7.0])
    context.SetDiscreteState(system.particles_index, particles.ravel())
    context.SetDiscreteState(system.log_weights_index, np.full(COUNT, -math.log(COUNT)))
    return context, particles


@pytest.mark.parametrize("make", [ekf, ukf])
@pytest.mark.parametrize(("spread", "after"), [(0.2, RANGE_PHASE), (1.5, PARTICLE_PHASE)])
def test_a_bridged_filter_takes_its_gaussian_back_when_the_particles_are_narrow(
    make, spread, after
):
    # The particle step is the particle filter's; the Gaussian test on the particles'
    # posterior decides: 0.2 m at 2.9 m is ≈ 0.1 rad, 1.5 m far above 0.25 rad.
    system = bridged(make)
    context, particles = particle_phase_context(system, spread)
    z = samples().reshape(2, F).mean(axis=1)
    x, P, nis, _ = pf_update(particles, np.full(COUNT, -math.log(COUNT)), z, Q_S, R)
    x_hat, P_hat, status, nis_hat = filtered(system, context)
    assert_array_equal(x_hat, x)
    assert_array_equal(P_hat, P)
    assert (status, nis_hat) == (VALID, nis)
    assert_allclose(discrete_update(system, context, system.start_state_index), [after, 7])
    if after == RANGE_PHASE:  # the Gaussian filter predicts from the particles' posterior
        x_next, P_next = predict(x, P, A_W, A, B, process_noise_covariance(W, T))
        assert_allclose(discrete_update(system, context, 0), x_next, rtol=1e-13)
        assert_allclose(discrete_update(system, context, 1).reshape(6, 6), P_next, rtol=1e-12)


@pytest.mark.parametrize(("scale", "after"), [(1.0, RANGE_PHASE), (12.0, PARTICLE_PHASE)])
def test_a_bridged_ukf_falls_back_to_particles_when_its_gaussian_widens(scale, after):
    # In its range phase the UKF updates as without the bridge; a posterior wider than
    # 1.2 × 0.25 rad across the line of sight sends it back to particles drawn from it.
    system = bridged(ukf)
    context = fixed_context(system, particle_seed=[0.5], **inputs())
    context.SetDiscreteState(system.start_state_index, [RANGE_PHASE, 9.0])
    context.SetDiscreteState(1, (scale * P0).ravel())
    z = samples().reshape(2, F).mean(axis=1)
    x, P, _ = ukf_range_update(X0, scale * P0, z, Q_S, R)
    x_hat, P_hat, *_ = filtered(system, context)
    assert_allclose(x_hat, x, rtol=1e-13, atol=1e-15)
    assert_allclose(P_hat, P, rtol=1e-13, atol=1e-15)
    angle = float(np.max(cross_range_angle(x, P, Q_S)))
    assert (angle > 0.3) is (after == PARTICLE_PHASE)
    assert_allclose(discrete_update(system, context, system.start_state_index), [after, 9])
    if after == PARTICLE_PHASE:
        moved, log_next, _ = drawn_and_predicted(x, P)
        particles = discrete_update(system, context, system.particles_index)
        assert_array_equal(particles, moved.ravel())


def test_a_lost_bridged_filter_redraws_from_its_widened_prior():
    # A prior 1.5 m off the truth with a 0.1 m spread: the ranges contradict it (NIS far
    # above 2 ln 10⁶), so the particles are drawn from N(x⁻, P⁻ · NIS/2) and weighed by them.
    system = bridged(ukf)
    x_prior = X0 + np.array([1.5, -1.0, 0.0, 0.0, 0.0, 0.0])
    P_prior = 0.01 * np.eye(6)
    context = fixed_context(system, particle_seed=[0.5], **inputs())
    context.SetDiscreteState(system.start_state_index, [RANGE_PHASE, 9.0])
    context.SetDiscreteState(0, x_prior)
    context.SetDiscreteState(1, P_prior.ravel())
    z = samples().reshape(2, F).mean(axis=1)
    x, P, nis = ukf_range_update(x_prior, P_prior, z, Q_S, R)
    assert nis > LOST_NIS and np.max(cross_range_angle(x, P, Q_S)) < 0.3  # not too wide
    assert_allclose(discrete_update(system, context, system.start_state_index), [PARTICLE_PHASE, 9])
    rng = np.random.default_rng(int(0.5 * 2.0**53))
    drawn = initial_particles(x_prior, P_prior * (nis / 2.0), COUNT, rng)
    *_, weighed = pf_update(drawn, np.full(COUNT, -math.log(COUNT)), z, Q_S, R)
    moved, log_next, _ = pf_predict(drawn, weighed, A_W, A, B, W, rng, PARAMS)
    assert_allclose(discrete_update(system, context, system.particles_index), moved.ravel(),
                    rtol=1e-12)  # fmt: skip
    assert_allclose(discrete_update(system, context, system.log_weights_index), log_next,
                    rtol=1e-12)  # fmt: skip


def build_loop(handover: HandoverRule):
    """The particle filter fed constant ranges and its seed from a seeded uniform source."""
    builder = DiagramBuilder()
    system = builder.AddSystem(
        ParticleRangeEstimator(T, W, X0, P0, ETA_UNEQUAL, F, handover=handover, parameters=PARAMS)
    )
    for name, value in inputs(u1_W=np.zeros(3)).items():
        source = builder.AddSystem(ConstantVectorSource(np.asarray(value, dtype=float)))
        builder.Connect(source.get_output_port(), system.GetInputPort(name))
    uniform = builder.AddSystem(RandomSource(RandomDistribution.kUniform, 1, T))
    hold = builder.AddSystem(ZeroOrderHold(T, 1))
    builder.Connect(uniform.get_output_port(), hold.get_input_port())
    builder.Connect(hold.get_output_port(), system.GetInputPort("particle_seed"))
    logger = LogVectorOutput(system.GetOutputPort("x_TU_hat"), builder, T)
    return builder.Build(), logger


def run_loop(seed: int, steps: int = 12) -> np.ndarray:
    diagram, logger = build_loop(HandoverRule(angle_tolerance=None, max_linear_steps=2))
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    diagram.SetRandomContext(context, RandomGenerator(seed))
    simulator.AdvanceTo(steps * T)
    return logger.FindLog(context).data().T


def test_particle_filter_runs_are_reproducible_from_the_diagram_seed():
    first, again, other = run_loop(3), run_loop(3), run_loop(4)
    assert_array_equal(first, again)
    # Steps 0 and 1 are the linear start; the particles drawn at step 1 depend on the seed.
    assert_array_equal(first[:2], other[:2])
    assert not np.any(np.all(first[2:] == other[2:], axis=1))


# --------------------------------------------------------------------------- bad arguments


@pytest.mark.parametrize(
    ("make", "kwargs", "message"),
    [
        (
            pf,
            {"handover": HandoverRule(max_linear_steps=0)},
            r"^handover: the particle filter draws",
        ),
        (pf, {"parameters": 5000}, r"^parameters: must be ParticleFilterParameters, got 5000$"),
        (
            ukf,
            {"sigma_points": (1, 2, 0)},
            r"^sigma_points: must be SigmaPointParameters, got \(1, 2, 0\)$",
        ),
        (
            ukf,
            {"sigma_points": SigmaPointParameters(kappa=-6.0)},
            r"^kappa: n \+ kappa must be > 0",
        ),
    ],
)
def test_bad_arguments_raise(make, kwargs, message):
    with pytest.raises(ValueError, match=message):
        make(**kwargs)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (
            {"noise_variances": [0.01, -1.0]},
            r"^noise_variances: must be two numbers > 0, got \[0.01, -1.0\]$",
        ),
        ({"samples_per_step": 0}, r"^samples_per_step: must be an integer ≥ 1, got 0$"),
        ({"samples_per_step": 1.5}, r"^samples_per_step: must be an integer ≥ 1, got 1.5$"),
        ({"noise_model": "exact"}, r"^estimator.noise_model: must be derived or paper_printed"),
    ],
)
def test_bad_noise_arguments_raise(args, message):
    values = {"noise_variances": ETA_UNEQUAL, "samples_per_step": F, "noise_model": "derived"}
    values.update(args)
    with pytest.raises(ValueError, match=message):
        UnscentedRangeEstimator(
            T,
            W,
            X0,
            P0,
            values["noise_variances"],
            values["samples_per_step"],
            values["noise_model"],
        )


@pytest.mark.parametrize(("tolerance", "phase"), [(10.0, RANGE_PHASE), (0.1, LINEAR_PHASE)])
def test_the_second_order_test_uses_the_noise_of_the_means(tolerance, phase):
    # After one update tr P⊥/(2d) ≈ 0.055 m; the means' noise is √(η/f) = 0.058, 0.082 m.
    system = ekf(handover=HandoverRule(second_order_tolerance=tolerance))
    context = fixed_context(system, **inputs())
    context.SetDiscreteState(system.prior_share_index, (0.01 * P0).ravel())
    assert_allclose(discrete_update(system, context, system.start_state_index), [phase, 1])
