"""The feasible envelope: the plan's tilt, the budget's largest acceleration, the derived
limits for the default vehicle, and the random-walk target's speed against closed forms."""

import math

import numpy as np
import pytest

from drake_uuv.models.statistics import chi2_cdf
from drake_uuv.models.vehicle_envelope import (
    feasible_limits,
    followable_target_scale,
    largest_acceleration,
    plan_max_tilt,
    target_speed_exceedance,
    target_speed_rms,
)
from drake_uuv.models.vehicle_limits import utilisation_budget, vehicle_limits
from drake_uuv.scenario import load_scenario
from drake_uuv.scenario.plants import HoveringAuv


@pytest.fixture(scope="module")
def vehicle():
    config = HoveringAuv()
    return config, config.vehicle_model(), config.allocator()


def _demands(config: HoveringAuv, **values: float) -> dict[str, float]:
    zero = dict(speed=0.0, angular_rate=0.0, rate_step=0.0, tilt=0.0)
    gains = dict(
        attitude_bandwidth=config.attitude_bandwidth,
        attitude_damping_ratio=config.attitude_damping_ratio,
    )
    return {**zero, **values, **gains}


def test_plan_tilt_is_the_elevation_of_zeta_when_b_points_along_its_azimuth() -> None:
    # ζ(0) = |b| [0, 1, h]: the minimal rotation from b = e_y turns about x by atan(h).
    for h in (0.0, 0.25, 0.5):
        tilt = plan_max_tilt(np.array([0.0, 1.0, 0.0]), 1 / 24, h, 1 / 6, steps=1)
        assert tilt == pytest.approx(math.atan(h), abs=1e-12)
    # Horizontal ζ, never antiparallel to b = (−1, 1, 0) before k = 18: a pure yaw.
    assert plan_max_tilt(np.array([-1.0, 1.0, 0.0]), 1 / 24, 0.0, 1 / 6, 18) < 1e-9


def test_papers_plan_turns_the_body_past_the_horizontal(paper) -> None:
    a = paper.attitude
    tilt = plan_max_tilt(np.asarray(paper.sonar.baseline), a.rho, a.h_amplitude, a.h_frequency, 500)
    assert tilt > math.pi / 2


def test_largest_acceleration_alone_is_the_worst_direction_limit(vehicle) -> None:
    config, model, allocator = vehicle
    alone = largest_acceleration(model, allocator, **_demands(config))
    # The budget samples 400 directions, the limits 2000: agreement to the lattice's 0.5 %.
    assert alone == pytest.approx(vehicle_limits(model, allocator).acceleration, rel=5e-3)


def test_largest_acceleration_fills_the_budget_exactly(vehicle) -> None:
    config, model, allocator = vehicle
    demands = _demands(config, speed=0.4, angular_rate=0.3, rate_step=0.6, tilt=1.0)
    a = largest_acceleration(model, allocator, **demands)
    assert 0.0 < a < 3.0
    total = utilisation_budget(model, allocator, acceleration=a, **demands)["total"]
    assert total == pytest.approx(1.0, abs=1e-9)
    assert utilisation_budget(model, allocator, acceleration=a * 1.01, **demands)["total"] > 1.0


def test_largest_acceleration_is_zero_beyond_the_top_speed(vehicle) -> None:
    config, model, allocator = vehicle
    too_fast = 1.1 * vehicle_limits(model, allocator).speed
    assert largest_acceleration(model, allocator, **_demands(config, speed=too_fast)) == 0.0


def test_feasible_limits_of_the_default_vehicle_on_the_paper_plan(vehicle, paper) -> None:
    config, model, allocator = vehicle
    limits = vehicle_limits(model, allocator)
    f = feasible_limits(
        model,
        allocator,
        attitude_bandwidth=config.attitude_bandwidth,
        attitude_damping_ratio=config.attitude_damping_ratio,
        time_step=paper.time_step,
        rho=paper.attitude.rho,
        max_tilt=2.0,
    )
    assert f.speed_budget == pytest.approx(0.5 * limits.speed)
    assert f.sweep_rate == pytest.approx(math.pi / 12)  # ρπ/t with ρ = 1/24, t = 0.5 s
    assert f.angular_rate == 0.3  # π/12 = 0.262 rounded up
    assert f.tilt == pytest.approx(math.pi / 2)  # the worst restoring moment
    assert f.acceleration == math.floor(10 * f.acceleration_exact) / 10 == 0.6
    assert f.budget["total"] <= 1.0
    assert f.budget["rate_step"] == pytest.approx(
        utilisation_budget(model, allocator, acceleration=0.0, **_demands(config, rate_step=0.6))[
            "rate_step"
        ]
    )
    assert f.velocity_weight == pytest.approx(1 / f.speed_budget**2)
    assert f.input_weight == pytest.approx(1 / 0.36)
    assert "tracking.reference_frame=world" in f.overrides()
    assert "attitude.max_angular_rate=0.3" in f.overrides()
    # The overrides load as a scenario.
    scenario = load_scenario("paper", ["plant=!HoveringAuv", *f.overrides()])
    assert scenario.tracking.max_acceleration == 0.6
    assert scenario.tracking.velocity_weight == pytest.approx(f.velocity_weight, rel=1e-3)


def test_a_plan_that_never_tilts_leaves_more_acceleration(vehicle) -> None:
    config, model, allocator = vehicle
    kwargs = dict(
        attitude_bandwidth=config.attitude_bandwidth,
        attitude_damping_ratio=config.attitude_damping_ratio,
        time_step=0.5,
        rho=1 / 24,
    )
    upright = feasible_limits(model, allocator, max_tilt=0.0, **kwargs)
    tilted = feasible_limits(model, allocator, max_tilt=math.pi / 2, **kwargs)
    assert upright.tilt == 0.0 and upright.acceleration_exact > tilted.acceleration_exact


@pytest.mark.parametrize(
    ("keyword", "value", "message"),
    [
        ("time_step", 0.0, r"time_step: must be > 0, got 0.0"),
        ("rho", -1.0, r"rho: must be > 0, got -1.0"),
        ("max_tilt", 4.0, r"max_tilt: must be in \[0, π\], got 4.0"),
    ],
)
def test_feasible_limits_reject_bad_input(vehicle, keyword, value, message) -> None:
    config, model, allocator = vehicle
    kwargs = dict(
        attitude_bandwidth=config.attitude_bandwidth,
        attitude_damping_ratio=config.attitude_damping_ratio,
        time_step=0.5,
        rho=1 / 24,
        max_tilt=1.0,
    )
    with pytest.raises(ValueError, match=message):
        feasible_limits(model, allocator, **{**kwargs, keyword: value})


def test_a_vehicle_too_weak_for_its_plan_is_refused(vehicle) -> None:
    config, _, _ = vehicle
    weak = HoveringAuv(max_thrust=0.2 * config.max_thrust)
    with pytest.raises(ValueError, match=r"max_tilt: the vehicle has no acceleration left"):
        feasible_limits(
            weak.vehicle_model(),
            weak.allocator(),
            attitude_bandwidth=weak.attitude_bandwidth,
            attitude_damping_ratio=weak.attitude_damping_ratio,
            time_step=0.5,
            rho=1 / 24,
            max_tilt=math.pi / 2,
        )


def test_target_speed_rms_of_the_paper_target(paper) -> None:
    target = paper.target
    W = np.asarray(target.acceleration_covariance)
    assert target_speed_rms(target.initial_velocity, W, 0.5, 0) == pytest.approx(
        math.sqrt(0.02**2 + 0.1**2 + 0.1**2)
    )
    # 200 steps add 200 · 0.25 · 0.006 = 0.3 m²/s².
    assert target_speed_rms(target.initial_velocity, W, 0.5, 200) == pytest.approx(
        math.sqrt(0.0204 + 0.3)
    )


def test_target_speed_exceedance_against_the_chi_square_law() -> None:
    # From rest with W = σ² I, |v̄(k)|² / (k t² σ²) is χ²(3): check the last step alone.
    sigma2, t, steps, samples = 0.004, 0.5, 50, 4000
    k = steps - 1
    for speed in (0.2, 0.3, 0.45):
        fraction, runs = target_speed_exceedance(
            np.zeros(3), sigma2 * np.eye(3), t, steps, k, speed, samples, seed=3
        )
        expected = 1.0 - chi2_cdf(speed**2 / (k * t * t * sigma2), 3)
        assert fraction == runs  # one step per run
        assert abs(fraction - expected) < 4 * math.sqrt(expected * (1 - expected) / samples)
    # From rest, step 0 is never faster than 0; every later step is.
    assert target_speed_exceedance(np.zeros(3), np.eye(3), t, 10, 0, 0.0, 50) == (0.9, 1.0)
    assert target_speed_exceedance(np.zeros(3), np.eye(3), t, 10, 0, 1e6, 50) == (0.0, 0.0)


def test_followable_target_scale_sets_the_final_rms_speed(paper) -> None:
    target = paper.target
    W = np.asarray(target.acceleration_covariance)
    scale = followable_target_scale(target.initial_velocity, W, 0.5, 500, 0.38)
    assert 0.0 < scale < 1.0
    assert target_speed_rms(target.initial_velocity, scale * W, 0.5, 499) == pytest.approx(0.38)
    with pytest.raises(ValueError, match=r"speed: must exceed the target's initial speed 0.143"):
        followable_target_scale(target.initial_velocity, W, 0.5, 500, 0.1)
    with pytest.raises(ValueError, match=r"steps: must be ≥ 2, got 1"):
        followable_target_scale(target.initial_velocity, W, 0.5, 1, 0.38)
