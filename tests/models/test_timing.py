"""The ping schedule and the exact Gaussian step between ticks, against independent
formulations."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from drake_uuv.models.measurement import range_measurement
from drake_uuv.models.motion import double_integrator
from drake_uuv.models.timing import (
    PingSchedule,
    augment,
    carried_range,
    sub_step,
    transition,
    update_through,
)
from tests.conftest import T, W


@pytest.mark.parametrize(
    "offsets, latency, delays",
    [
        ((0.0, 0.0), 0.0, (0, 0)),  # the paper's timing
        ((0.0, 0.25), 0.2, (1, 1)),  # 0.2 and 0.45 s: both before the next tick
        ((0.0, 0.3), 0.4, (1, 2)),  # 0.4 and 0.7 s
        ((0.0, 0.25), 0.0, (0, 1)),
        ((0.25, 0.0), 0.25, (1, 1)),  # 0.5 s exactly: the next tick, not the one after
        ((0.1, 0.4), 2.3, (5, 6)),
    ],
)
def test_a_range_arrives_at_the_first_tick_after_its_ping_and_latency(offsets, latency, delays):
    schedule = PingSchedule(T, offsets, latency)
    assert schedule.delays == delays
    assert schedule.window == max(delays)
    assert schedule.immediate is (delays == (0, 0))
    assert schedule.ping_time(7, 1) == pytest.approx(7 * T + offsets[1])


@pytest.mark.parametrize(
    "offsets, latency, message",
    [
        ((0.0, 0.5), 0.0, r"^ping_offsets: must be two numbers in \[0, 0.5\), got \(0.0, 0.5\)"),
        ((-0.1, 0.0), 0.0, r"^ping_offsets: must be two numbers in \[0, 0.5\)"),
        ((0.0, 0.0), 5.5, r"^latency: must be in \[0, 5\], got 5.5"),
    ],
)
def test_bad_schedules_name_the_field(offsets, latency, message):
    with pytest.raises(ValueError, match=message):
        PingSchedule(T, offsets, latency)


def test_the_sub_step_transitions_compose_to_the_step():
    A, B = double_integrator(T)
    G, B_t = transition(T)
    assert_allclose(G, np.hstack([A, -B]))
    assert_allclose(B_t, B)
    Phi1, B1 = sub_step(0.2)
    Phi2, B2 = sub_step(0.3)
    assert_allclose(Phi2 @ Phi1, A, atol=1e-15)
    # A constant acceleration over 0.2 s then 0.3 s is the step's.
    assert_allclose(Phi2 @ B1 + B2, B, atol=1e-15)
    assert_allclose(transition(0.0)[0], np.hstack([np.eye(6), np.zeros((6, 3))]))


def _kf(x, P, H, z, R):
    S = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S)
    return x + K @ (z - H @ x), (np.eye(len(x)) - K @ H) @ P


def test_an_update_of_the_state_at_a_ping_carries_over_to_the_step_exactly():
    """A linear measurement of x(τ) = G z + c: the update of y then conditioned onto z equals
    the Kalman update of z with the row H G (an independent formulation)."""
    rng = np.random.default_rng(0)
    x0 = rng.normal(size=6)
    M = rng.normal(size=(6, 6))
    z, P_z = augment(x0, M @ M.T + np.eye(6), W)
    G, B = transition(0.31)
    c = B @ np.array([1.0, -2.0, 0.5])
    H = rng.normal(size=(2, 6))
    R = np.diag([0.01, 0.02])
    meas = rng.normal(size=2)
    y = G @ z + c
    y_post, P_y_post = _kf(y, G @ P_z @ G.T, H, meas, R)
    z_post, P_post = update_through(z, P_z, G, y, y_post, P_y_post)
    z_ref, P_ref = _kf(z, P_z, H @ G, meas - H @ c, R)
    assert_allclose(z_post, z_ref, rtol=1e-10, atol=1e-12)
    assert_allclose(P_post, P_ref, rtol=1e-10, atol=1e-12)


def test_two_simultaneous_ranges_updated_in_sequence_equal_the_joint_update():
    """Two ranges of one instant, linearised at the instant's prior: taken one after the other
    through the step's augmented state, or together, the posterior is the same."""
    rng = np.random.default_rng(1)
    x0 = np.array([-2.0, -2.1, 0.4, 0.1, 0.0, -0.1])
    z, P_z = augment(x0, 0.3 * np.eye(6), W)
    G, B = transition(0.25)
    c = B @ np.array([0.3, 0.1, 0.0])
    q_s = np.array([-1.0, 1.0, 0.2])
    y = G @ z + c
    P_y = G @ P_z @ G.T
    H = np.zeros((2, 6))
    h = range_measurement(y, q_s)
    for i, sign in enumerate((0.5, -0.5)):
        r = y[:3] + sign * q_s
        H[i, :3] = r / np.linalg.norm(r)
    R = np.diag([0.01, 0.02])
    measured = h + rng.normal(size=2) * 0.1
    # Joint: both rows at once.
    y_joint, P_joint = _kf(y, P_y, H, measured - h + H @ y, R)
    z_joint, P_z_joint = update_through(z, P_z, G, y, y_joint, P_joint)
    # In sequence: the first range, then the second, each carried onto z.
    z_seq, P_seq = z, P_z
    for i in range(2):
        y_i = G @ z_seq + c
        y_post, P_post = _kf(
            y_i,
            G @ P_seq @ G.T,
            H[i : i + 1],
            (measured - h + H @ y)[i : i + 1],
            R[i : i + 1, i : i + 1],
        )
        z_seq, P_seq = update_through(z_seq, P_seq, G, y_i, y_post, P_post)
    assert_allclose(z_seq, z_joint, rtol=1e-10, atol=1e-12)
    assert_allclose(P_seq, P_z_joint, rtol=1e-9, atol=1e-12)


def test_the_carried_range_and_its_variance_are_the_predicted_change():
    z, P_z = augment(np.array([-2.0, -2.0, 0.3, 0.4, -0.2, 0.1]), 0.2 * np.eye(6), W)
    early_tau, late_tau = 0.05, 0.3
    q_early, q_late = np.array([-1.0, 1.0, 0.0]), np.array([-0.9, 1.1, 0.1])
    a = np.array([0.5, 0.0, -0.2])

    def at(tau, q_s):
        G, B = transition(tau)
        return G, B @ a, q_s

    shift, variance = carried_range(z, P_z, 0, at(early_tau, q_early), at(late_tau, q_late))

    def change(zz):
        values = [
            range_measurement(G @ zz + c, q)[0]
            for G, c, q in (at(early_tau, q_early), at(late_tau, q_late))
        ]
        return values[1] - values[0]

    assert shift == pytest.approx(change(z), rel=1e-12)
    eps = 1e-6
    g = np.array([(change(z + eps * e) - change(z - eps * e)) / (2 * eps) for e in np.eye(9)])
    assert variance == pytest.approx(g @ P_z @ g, rel=1e-6)
