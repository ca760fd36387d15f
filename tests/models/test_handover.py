"""The hand-over rule: closed-form angles, the prior's share of the KF covariance, the decision."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from drake_uuv.models.filters import predict, range_difference_update
from drake_uuv.models.handover import (
    LOST_NIS,
    HandoverRule,
    Phase,
    PhaseEvidence,
    ThresholdHandover,
    Transition,
    cross_range_angle,
    prior_share_predict,
    prior_share_update,
    second_order_range_error,
)
from drake_uuv.models.motion import double_integrator, process_noise_covariance
from drake_uuv.models.statistics import chi2_ppf

A, B = double_integrator(0.5)
Q = process_noise_covariance(np.diag([0.004, 0.001, 0.001]), 0.5)


def test_cross_range_angle_closed_form():
    d, s = 4.0, 0.5
    x = np.array([d, 0.0, 0.0, 0.3, 0.0, 0.0])
    a, b, c = 0.2, 0.3, 0.5
    P = np.diag([a, b, c, 1.0, 1.0, 1.0])
    q_s = np.array([0.0, 2 * s, 0.0])  # sonars at ±s on the y axis
    d1 = math.hypot(d, s)
    # tr P⊥ = a + b + c − uᵀPu with u = (d, ±s, 0)/d1.
    expected = math.sqrt(a + b + c - (a * d * d + b * s * s) / d1**2) / d1
    assert_allclose(cross_range_angle(x, P, q_s), [expected, expected], rtol=1e-14)
    # A baseline of zero length: both sonars at the origin, u = x̂, tr P⊥ = b + c.
    assert_allclose(cross_range_angle(x, P, np.zeros(3)), math.sqrt(b + c) / d, rtol=1e-14)


def test_cross_range_angle_on_a_sonar_is_infinite():
    q_s = np.array([2.0, 0.0, 0.0])
    x = np.array([-1.0, 0.0, 0.0, 0.0, 0.0, 0.0])  # on sonar 1 (q + ½ q_s = 0)
    angles = cross_range_angle(x, np.eye(6), q_s)
    assert angles[0] == math.inf and math.isfinite(angles[1])


def test_prior_share_after_one_update_is_the_covariance_without_the_noise_term():
    P0 = np.diag([1.0, 2.0, 0.5, 1.0, 1.0, 1.0])
    q_s = np.array([-1.0, 1.0, 0.3])
    Gamma = 0.4
    x1, P1, _ = range_difference_update(np.zeros(6), P0, 1.2, 0.0, Gamma, q_s)
    S1 = prior_share_update(P0, P1, q_s, Gamma)
    # Independently: the KF gain from the prior, K = P0 Cᵀ (C P0 Cᵀ + Γ)⁻¹.
    C = np.concatenate([q_s, np.zeros(3)])
    K = P0 @ C / (C @ P0 @ C + Gamma)
    I_KC = np.eye(6) - np.outer(K, C)
    assert_allclose(S1, I_KC @ P0 @ I_KC.T, atol=1e-14)
    assert_allclose(S1, P1 - Gamma * np.outer(K, K), atol=1e-14)
    assert_allclose(prior_share_predict(S1, A), A @ S1 @ A.T)


def test_prior_share_is_below_the_covariance_and_decays_along_a_kf_run():
    rng = np.random.default_rng(0)
    x, P = np.zeros(6), np.eye(6)
    S = P.copy()
    shares = []
    for k in range(60):
        angle = k * math.pi / 24
        q_s = np.array([math.sin(angle), math.cos(angle), 0.5 * math.cos(k * math.pi / 6)])
        Gamma = 0.01 * 18 + 0.5 * 0.02 * 0.01
        x, P, _ = range_difference_update(x, P, rng.normal(), 0.0, Gamma, q_s)
        S = prior_share_update(S, P, q_s, Gamma)
        assert np.linalg.eigvalsh(P - S).min() > -1e-12  # S ⪯ P: noise terms only add
        shares.append(np.trace(S[:3, :3]) / np.trace(P[:3, :3]))
        x, P = predict(x, P, np.zeros(3), A, B, Q)
        S = prior_share_predict(S, A)
    assert shares[0] > 0.5 and shares[-1] < 0.01


def rule_inputs(share: float, cross: float):
    """An estimate 4 m out on x, ``tr P_qq`` = 1 + 2·cross², prior share ``share``."""
    x = np.array([4.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    P = np.diag([1.0, cross**2, cross**2, 0.1, 0.1, 0.1])
    S = share * P
    return {"x": x, "q_s": np.zeros(3), "prior_covariance": S}, P


@pytest.mark.parametrize(
    ("share", "cross", "angle_tolerance", "due"),
    [
        (0.05, 0.4, 0.25, True),  # θ = √(2·0.16)/4 = 0.141
        (0.05, 0.8, 0.25, False),  # θ = 0.283
        (0.2, 0.4, 0.25, False),  # the prior still weighs
        (0.1, 0.4, 0.25, True),  # at the threshold
        (0.05, 0.8, None, True),  # no angle test (a particle filter)
        (0.2, 0.8, None, False),
    ],
)
def test_handover_decision(share, cross, angle_tolerance, due):
    inputs, P = rule_inputs(share, cross)
    rule = HandoverRule(angle_tolerance=angle_tolerance, prior_share=0.1)
    assert rule.handover_due(P, 5, **inputs) is due


def test_step_limits():
    inputs, P = rule_inputs(0.5, 2.0)  # neither test holds
    rule = HandoverRule(min_linear_steps=3, max_linear_steps=10)
    assert not rule.handover_due(P, 9, **inputs)
    assert rule.handover_due(P, 10, **inputs)
    inputs, P = rule_inputs(0.0, 0.1)  # both hold
    assert not rule.handover_due(P, 2, **inputs)
    assert rule.handover_due(P, 3, **inputs)
    assert rule.linear_start
    assert not HandoverRule(max_linear_steps=0).linear_start


def test_the_angle_test_scales_with_the_range():
    # The same covariance passes 30 m out and fails 3 m out: θ = σ⊥/d.
    P = np.diag([0.01, 1.0, 1.0, 0.1, 0.1, 0.1])
    rule = HandoverRule()
    far = np.array([30.0, 0, 0, 0, 0, 0])
    near = np.array([3.0, 0, 0, 0, 0, 0])
    S = np.zeros((6, 6))
    assert rule.handover_due(P, 5, x=far, q_s=np.array([0, 1.0, 0]), prior_covariance=S)
    assert not rule.handover_due(P, 5, x=near, q_s=np.array([0, 1.0, 0]), prior_covariance=S)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"angle_tolerance": 0.0}, r"^angle_tolerance: must be > 0 or None, got 0.0$"),
        ({"prior_share": float("nan")}, r"^prior_share: must be > 0, got nan$"),
        ({"min_linear_steps": -1}, r"^min_linear_steps: must be ≥ 0, got -1$"),
        ({"max_linear_steps": -2}, r"^max_linear_steps: must be ≥ 0, got -2$"),
        ({"fallback_factor": 0.9}, r"^fallback_factor: must be ≥ 1, got 0.9$"),
        (
            {"particle_bridge": True, "angle_tolerance": None},
            r"^particle_bridge: needs an angle_tolerance to leave the particles, got None$",
        ),
    ],
)
def test_bad_parameters_raise(kwargs, message):
    with pytest.raises(ValueError, match=message):
        HandoverRule(**kwargs)


def test_second_order_error_is_half_the_squared_angle_times_the_range():
    x = np.array([4.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    P = np.diag([1.0, 0.09, 0.16, 0.1, 0.1, 0.1])
    # Baseline zero: u = x̂, tr P⊥ = 0.25, so tr P⊥ / (2d) = 0.25 / 8.
    assert_allclose(second_order_range_error(x, P, np.zeros(3)), [0.03125, 0.03125], rtol=1e-14)


@pytest.mark.parametrize(("noise_std", "due"), [(0.04, True), (0.02, False)])
def test_second_order_test_compares_with_the_range_noise(noise_std, due):
    x = np.array([4.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    P = np.diag([1.0, 0.09, 0.16, 0.1, 0.1, 0.1])  # error 0.03125 m, angle 0.125 rad
    rule = HandoverRule(second_order_tolerance=1.0)
    kwargs = dict(x=x, q_s=np.zeros(3), prior_covariance=np.zeros((6, 6)))
    assert rule.handover_due(P, 5, noise_std=np.full(2, noise_std), **kwargs) is due
    assert HandoverRule().handover_due(P, 5, **kwargs)  # no second-order test by default
    with pytest.raises(ValueError, match=r"^noise_std: needed with second_order_tolerance"):
        rule.handover_due(P, 5, **kwargs)
    with pytest.raises(ValueError, match=r"^second_order_tolerance: must be > 0 or None, got 0.0$"):
        HandoverRule(second_order_tolerance=0.0)


def at_angle(angle: float, d: float = 4.0):
    """``(x, P, q_s)`` with every cross-range angle exactly ``angle`` (zero baseline, the
    cross-range variance on the y axis)."""
    x = np.array([d, 0.0, 0.0, 0.0, 0.0, 0.0])
    P = np.diag([0.5, (angle * d) ** 2, 0.0, 0.1, 0.1, 0.1])
    return x, P, np.zeros(3)


@pytest.mark.parametrize(
    ("angle", "holds", "falls_back"),
    [(0.2, True, False), (0.24, True, False), (0.29, False, False), (0.31, False, True)],
)
def test_the_bridge_hysteresis(angle, holds, falls_back):
    # Tolerance 0.25 rad, factor 1.2: a Gaussian between 0.25 and 0.3 rad is neither taken up
    # from particles nor given up for them.
    x, P, q_s = at_angle(angle)
    rule = HandoverRule(particle_bridge=True)
    assert_allclose(cross_range_angle(x, P, q_s), angle, rtol=1e-14)
    assert rule.gaussian_holds(x, P, q_s) is holds
    assert rule.fallback_due(x, P, q_s) is falls_back
    assert not HandoverRule().fallback_due(x, P, q_s)  # no bridge, no fallback


@pytest.mark.parametrize("share", [0.05, 0.2])
@pytest.mark.parametrize("cross", [0.4, 2.0])
def test_handover_is_the_prior_test_and_the_gaussian_test(share, cross):
    inputs, P = rule_inputs(share, cross)
    rule = HandoverRule()
    both = rule.prior_forgotten(P, 5, inputs["prior_covariance"]) and rule.gaussian_holds(
        inputs["x"], P, inputs["q_s"]
    )
    assert rule.handover_due(P, 5, **inputs) is both
    assert rule.prior_forgotten(P, 5, inputs["prior_covariance"]) is (share <= 0.1)


def test_a_bridged_filter_is_lost_beyond_the_one_in_a_million_nis():
    # χ²(2) has survival exp(−x/2): the 1 − 10⁻⁶ quantile is 2 ln 10⁶, as chi2_ppf says.
    assert_allclose(LOST_NIS, chi2_ppf(1.0 - 1e-6, 2), rtol=1e-9)
    rule = HandoverRule(particle_bridge=True)
    assert rule.lost(LOST_NIS * 1.001) and not rule.lost(LOST_NIS * 0.999)
    assert not rule.lost(math.nan)
    assert not HandoverRule().lost(1e9)  # no bridge: nothing to fall back to


def test_threshold_hand_over() -> None:
    policy = ThresholdHandover(
        position_variance_threshold=0.5, min_linear_steps=2, max_linear_steps=9
    )
    small, large = 0.1 * np.eye(6), np.eye(6)
    assert not policy.handover_due(small, 1)  # below min_linear_steps
    assert policy.handover_due(small, 2)
    assert not policy.handover_due(large, 8)
    assert policy.handover_due(large, 9)  # max_linear_steps reached
    assert policy.linear_start and not ThresholdHandover(max_linear_steps=0).linear_start
    assert not policy.particle_bridge


def _evidence(P: np.ndarray, done: int, *, gaussian: bool = True, particles: bool = True,
              share: float = 0.01, nis: float = 1.0) -> PhaseEvidence:  # fmt: skip
    x = np.array([-2.0, -2.0, 0.3, 0.0, 0.0, 0.0])
    return PhaseEvidence(
        x=x, P=P, nis=nis, linear_updates=done, prior_share=share * P,
        q_s=np.array([-1.0, 1.0, 0.0]), noise_std=np.array([0.1, 0.1]), gaussian=gaussian,
        particles=particles,
    )  # fmt: skip


@pytest.mark.parametrize(
    "gaussian, phase, P_scale, expected",
    [
        (True, Phase.LINEAR, 0.1, Phase.RANGE),  # trace 0.3 ≤ 0.5: hand over
        (False, Phase.LINEAR, 0.1, Phase.PARTICLE),  # no Gaussian update: to particles
        (True, Phase.LINEAR, 1.0, Phase.LINEAR),  # trace 3 > 0.5: stay
        (True, Phase.RANGE, 100.0, Phase.RANGE),  # one way: never back
        (False, Phase.PARTICLE, 0.01, Phase.PARTICLE),
    ],
)
def test_threshold_next_phase(gaussian, phase, P_scale, expected) -> None:
    evidence = _evidence(P_scale * np.eye(6), 5, gaussian=gaussian, particles=not gaussian)
    assert ThresholdHandover().next_phase(phase, evidence) == Transition(expected)


@pytest.mark.parametrize(
    "phase, P_scale, nis, gaussian, expected",
    [
        # Linear: narrow and forgotten → the Gaussian update; a particle filter → particles.
        (Phase.LINEAR, 0.01, 1.0, True, Transition(Phase.RANGE)),
        (Phase.LINEAR, 0.01, 1.0, False, Transition(Phase.PARTICLE)),
        # Linear, forgotten but wide (θ ≈ 0.7 rad): a bridged Gaussian filter → particles.
        (Phase.LINEAR, 2.0, 1.0, True, Transition(Phase.PARTICLE)),
        # Particles: narrow → back to the Gaussian update; wide → stay.
        (Phase.PARTICLE, 0.01, 1.0, True, Transition(Phase.RANGE)),
        (Phase.PARTICLE, 2.0, 1.0, True, Transition(Phase.PARTICLE)),
        # Gaussian: too wide → particles from its own posterior; lost → redrawn from the prior.
        (Phase.RANGE, 2.0, 1.0, True, Transition(Phase.PARTICLE)),
        (Phase.RANGE, 0.01, 1e3, True, Transition(Phase.PARTICLE, redraw_from_prior=True)),
        (Phase.RANGE, 0.01, 1.0, True, Transition(Phase.RANGE)),
    ],
)
def test_rule_next_phase(phase, P_scale, nis, gaussian, expected) -> None:
    rule = HandoverRule(particle_bridge=True)
    evidence = _evidence(P_scale * np.eye(6), 5, gaussian=gaussian, nis=nis)
    assert rule.next_phase(phase, evidence) == expected


def test_without_the_bridge_a_gaussian_filter_never_leaves_its_phase() -> None:
    rule = HandoverRule()
    assert rule.next_phase(Phase.RANGE, _evidence(2.0 * np.eye(6), 5, nis=1e3)) == Transition(
        Phase.RANGE
    )
    wide = _evidence(2.0 * np.eye(6), 5, particles=False)
    assert rule.next_phase(Phase.LINEAR, wide) == Transition(Phase.LINEAR)
