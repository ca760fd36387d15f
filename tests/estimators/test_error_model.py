"""What an estimator's error model does: attitude noise in the ranges' and Y's noise, the
floors of the biases in the published covariance, and ``error_model: ideal`` ignoring it all."""

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pydrake.math import RollPitchYaw, RotationMatrix

from drake_uuv.estimators import EstimatorSetting, RangeDifferenceKalmanFilter, RangeFilter
from drake_uuv.models.filters import range_difference_update
from drake_uuv.models.measurement import range_difference_noise
from drake_uuv.models.motion import double_integrator, process_noise_covariance
from drake_uuv.models.navigation_noise import (
    commanded_acceleration_noise,
    difference_attitude_variance,
    heading_bias_floor,
    range_attitude_covariance,
    rotation_vector_covariance,
)
from drake_uuv.models.timing import PingSchedule
from drake_uuv.scenario import Ekf, NavigationErrors, PaperKf
from drake_uuv.testing import discrete_update, fixed_context
from tests.conftest import ETA_UNEQUAL, T, W

X0 = np.array([-2.0, -2.2, 0.4, 0.1, -0.05, 0.0])
P0 = np.diag([0.3, 0.2, 0.25, 0.1, 0.1, 0.1]) + 0.01
B_BODY = np.array([-1.0, 1.0, 0.0])
R_WB = np.array([[0.8, -0.6, 0.0], [0.6, 0.8, 0.0], [0.0, 0.0, 1.0]])
RANGES = np.array([2.4, 3.3])
ERRORS = NavigationErrors(
    attitude_noise=np.radians([0.5, 0.5, 2.0]), heading_bias=np.radians(2.0),
    velocity_noise=0.01, velocity_bias=0.005,
)  # fmt: skip


def setting(**fields) -> EstimatorSetting:
    values = dict(
        time_step=T, acceleration_covariance=W, noise_variances=ETA_UNEQUAL, baseline_B=B_BODY
    )
    return EstimatorSetting(**{**values, **fields})


def inputs() -> dict:
    return dict(range_samples=RANGES, sonar_status=np.zeros(2), R_WB_nav=R_WB.ravel(),
                u1_W=np.array([0.5, -0.2, 0.1]))  # fmt: skip


def config(kind, **fields):
    return kind(initial_estimate=X0.tolist(), initial_covariance=P0.tolist(), **fields)


def test_the_kf_adds_the_attitude_noise_of_y_to_gamma():
    kf = RangeDifferenceKalmanFilter(config(PaperKf), setting=setting(navigation_errors=ERRORS))
    context = fixed_context(kf, **inputs())
    q_s = R_WB @ B_BODY
    m, gamma = range_difference_noise("derived", ETA_UNEQUAL, RANGES * RANGES)
    gamma += difference_attitude_variance(
        X0, q_s, rotation_vector_covariance(R_WB, ERRORS.attitude_noise)
    )
    x, P, _ = range_difference_update(
        X0, P0, 0.5 * (RANGES[0] ** 2 - RANGES[1] ** 2), m, gamma, q_s
    )
    assert_allclose(kf.GetOutputPort("x_TU_hat").Eval(context), x, rtol=1e-12)
    # The published covariance adds the floors: the heading bias's and the DVL's (none here:
    # the filter predicts with the commanded acceleration, which the DVL does not enter).
    floor = heading_bias_floor(x[None, :3], x[None, 3:], ERRORS.heading_bias)[0]
    published = kf.GetOutputPort("P_TU").Eval(context).reshape(6, 6)
    assert_allclose(published, P + floor, rtol=1e-12)


def test_the_ekf_adds_the_attitude_noise_of_the_ranges_to_r():
    ekf = RangeFilter(
        config(Ekf, handover="threshold", linear_start_max_steps=0),
        setting=setting(navigation_errors=ERRORS, sound_speed_error=0.005),
    )
    context = fixed_context(ekf, **inputs())
    q_s = R_WB @ B_BODY
    R = np.diag(ETA_UNEQUAL) + np.diag((0.005 * RANGES) ** 2)
    R += range_attitude_covariance(X0, q_s, rotation_vector_covariance(R_WB, ERRORS.attitude_noise))
    x, P, nis = Ekf().range_update()(X0, P0, RANGES, q_s, R)  # as configured by default
    assert_allclose(ekf.GetOutputPort("x_TU_hat").Eval(context), x, rtol=1e-12)
    assert ekf.GetOutputPort("nis").Eval(context)[0] == pytest.approx(nis, rel=1e-12)
    floor = heading_bias_floor(x[None, :3], x[None, 3:], ERRORS.heading_bias)[0]
    floor[:3, :3] += 0.005**2 * np.outer(x[:3], x[:3])
    published = ekf.GetOutputPort("P_TU").Eval(context).reshape(6, 6)
    assert_allclose(published, P + floor, rtol=1e-12, atol=1e-15)


def test_with_navigated_motion_the_dvl_walks_the_position_and_blurs_the_velocity():
    nav = config(PaperKf, vehicle_motion="navigation")
    kf = RangeDifferenceKalmanFilter(nav, setting=setting(navigation_errors=ERRORS))
    model = kf.error_model
    # Level and heading along x at 1.6 m/s: θ × v is (0, θ_yaw v, −θ_pitch v).
    v = np.array([1.6, 0.0, 0.0])
    sigma_roll, sigma_pitch, sigma_yaw = ERRORS.attitude_noise
    dvl = ERRORS.velocity_noise**2 + ERRORS.velocity_bias**2
    velocity = np.diag([dvl, dvl + (sigma_yaw * 1.6) ** 2, dvl + (sigma_pitch * 1.6) ** 2])
    assert_allclose(
        model.velocity_covariance(v, model.attitude_covariance(np.eye(3))), velocity, rtol=1e-12
    )
    expected = heading_bias_floor(X0[None, :3], X0[None, 3:], ERRORS.heading_bias)[0]
    expected[3:, 3:] += velocity
    assert_allclose(model.floor(X0, velocity), expected, rtol=1e-12)


@pytest.mark.slow
def test_the_navigated_velocity_error_is_the_navigation_s_own():
    """``Σ_ev`` against the inertial navigation's formula, ``R_WB_nav (R_WBᵀ v + δ) − v``,
    sampled: each entry within five standard errors of its sample."""
    rng = np.random.default_rng(4)
    n = 20000
    model = RangeDifferenceKalmanFilter(
        config(PaperKf, vehicle_motion="navigation"), setting=setting(navigation_errors=ERRORS)
    ).error_model
    v = np.array([1.2, -0.9, 0.3])
    # The AHRS noise is on roll, pitch and yaw of the true attitude.
    angles = RollPitchYaw(RotationMatrix(R_WB)).vector()
    errors = np.empty((n, 3))
    for j in range(n):
        noisy = angles + ERRORS.attitude_noise * rng.standard_normal(3)
        R_nav = RotationMatrix(RollPitchYaw(noisy)).matrix()
        dvl = ERRORS.velocity_noise * rng.standard_normal(3) + ERRORS.velocity_bias * (
            rng.standard_normal(3)
        )
        errors[j] = R_nav @ (R_WB.T @ v + dvl) - v
    sample = np.cov(errors.T)
    expected = model.velocity_covariance(v, model.attitude_covariance(R_WB))
    # The standard error of a sample covariance entry: sqrt((Σ_ii Σ_jj + Σ_ij²) / n).
    d = np.sqrt(np.diag(expected))
    standard_error = np.sqrt((np.outer(d, d) ** 2 + expected**2) / n)
    assert np.all(np.abs(sample - expected) < 5 * standard_error + 1e-9)


def test_with_the_paper_s_timing_the_prediction_adds_the_navigation_s_process_noise():
    """``A P Aᵀ + Q`` plus the commanded acceleration's error through the double integrator
    (commanded motion), or plus ``t² Σ_ev`` on the position (navigated motion)."""
    a = inputs()["u1_W"]
    sigma_theta = rotation_vector_covariance(R_WB, ERRORS.attitude_noise)
    A, Q = double_integrator(T)[0], process_noise_covariance(W, T)
    kf = RangeDifferenceKalmanFilter(config(PaperKf), setting=setting(navigation_errors=ERRORS))
    context = fixed_context(kf, **inputs())
    P = kf.filtered(context).P[0]
    extra = process_noise_covariance(commanded_acceleration_noise(a, sigma_theta), T)
    after = discrete_update(kf, context, 1).reshape(6, 6)
    assert_allclose(after, A @ P @ A.T + Q + extra, rtol=1e-12)

    nav = RangeDifferenceKalmanFilter(
        config(PaperKf, vehicle_motion="navigation"), setting=setting(navigation_errors=ERRORS)
    )
    v = np.array([1.2, -0.4, 0.1])
    values = {**inputs(), "p_WU_nav": np.zeros(3), "v_WU_nav": v}
    del values["u1_W"]
    context = fixed_context(nav, **values)
    P = nav.filtered(context).P[0]
    velocity = (ERRORS.velocity_noise**2 + ERRORS.velocity_bias**2) * np.eye(3)
    velocity += commanded_acceleration_noise(v, sigma_theta)
    expected = A @ P @ A.T + Q
    expected[:3, :3] += T * T * velocity
    assert_allclose(discrete_update(nav, context, 1).reshape(6, 6), expected, rtol=1e-12)


def test_the_ideal_model_believes_navigation_and_timing_perfect():
    schedule = PingSchedule(T, (0.0, 0.25), 0.2)
    ideal = RangeDifferenceKalmanFilter(
        config(PaperKf, error_model="ideal"),
        setting=setting(navigation_errors=ERRORS, ping_schedule=schedule, sound_speed_error=0.01),
    )
    plain = RangeDifferenceKalmanFilter(config(PaperKf), setting=setting())
    assert ideal.window is None and not ideal.HasInputPort("ping_time")
    assert not ideal.error_model.active
    a, b = fixed_context(ideal, **inputs()), fixed_context(plain, **inputs())
    for port in ("x_TU_hat", "P_TU", "nis"):
        assert_allclose(ideal.GetOutputPort(port).Eval(a), plain.GetOutputPort(port).Eval(b))
    modelled = RangeDifferenceKalmanFilter(config(PaperKf), setting=setting(ping_schedule=schedule))
    assert modelled.window is not None and modelled.HasInputPort("ping_time")
