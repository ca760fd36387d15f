"""Ranges at their own ping times and late ranges: the estimate published at tick k is of the
state at k from exactly the ranges that have arrived by k.

The estimator under test is a throwaway variant whose update is linear in the position (each
sonar's range is taken as ``cᵢᵀ q`` plus noise), so the whole estimator is a linear Gaussian
filter with late measurements; its estimate at every tick is checked against an independent
batch formulation: the joint Gaussian of the start and every step's target acceleration,
conditioned on the ranges arrived by then."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from drake_uuv.estimators import (
    Estimate,
    EstimatorSetting,
    MeasurementUpdate,
    Ranges,
    RelativeStateEstimator,
)
from drake_uuv.models.measurement import NO_ARRIVAL, VALID
from drake_uuv.models.motion import double_integrator
from drake_uuv.models.timing import PingSchedule, sub_step
from drake_uuv.scenario import PaperKf
from tests.conftest import ETA_UNEQUAL, T, W

C = np.array([[0.8, -0.6, 0.0], [0.0, 0.6, 0.8]])  # each sonar's linear "range" direction
X0 = np.array([0.3, -0.2, 0.1, 0.05, 0.0, -0.02])
P0 = np.diag([1.0, 2.0, 0.5, 0.3, 0.2, 0.1]) + 0.05


class LinearProbe(RelativeStateEstimator):
    """A throwaway estimator: sonar i measures ``cᵢᵀ q`` with variance ηᵢ."""

    def measurement_update(self, context, prior: Estimate, ranges: Ranges):
        # The probe steps one run: its batch of one, row 0.
        rows = ranges.run(0).sonars
        if rows.size == 0:
            return None
        H = np.zeros((rows.size, 6))
        H[:, :3] = C[rows]
        R = np.diag(ETA_UNEQUAL[rows])
        x_prior, P_prior = prior.x[0], prior.P[0]
        S = H @ P_prior @ H.T + R
        K = P_prior @ H.T @ np.linalg.inv(S)
        nu = ranges.z[0][rows] - H @ x_prior
        x = x_prior + K @ nu
        I_KH = np.eye(6) - K @ H
        P = I_KH @ P_prior @ I_KH.T + K @ R @ K.T
        nis = np.array([float(nu @ np.linalg.solve(S, nu))])
        return MeasurementUpdate(
            x[np.newaxis], P[np.newaxis], nis, np.array([rows.size]), np.ones(1, dtype=bool)
        )


def _probe(schedule: PingSchedule) -> LinearProbe:
    setting = EstimatorSetting(
        time_step=T, acceleration_covariance=W, noise_variances=ETA_UNEQUAL,
        ping_schedule=schedule,
    )  # fmt: skip
    return LinearProbe(PaperKf(initial_estimate=X0.tolist(), initial_covariance=P0.tolist()),
                       setting=setting)  # fmt: skip


def _batch(steps: int, accelerations, pings, tick):
    """Mean and covariance of x(t_tick) given the pings ``(ping time, sonar, value)`` arrived
    by then: the joint Gaussian of w = [x(0), ū(0), …, ū(steps−1)] conditioned directly."""
    n = 6 + 3 * steps
    mean_w = np.concatenate([X0, np.zeros(3 * steps)])
    cov_w = np.zeros((n, n))
    cov_w[:6, :6] = P0
    for k in range(steps):
        cov_w[6 + 3 * k : 9 + 3 * k, 6 + 3 * k : 9 + 3 * k] = W

    def state_at(time):
        """x(time) = M w + m: the step's constant accelerations, exactly."""
        k = min(math.floor(time / T + 1e-9), steps - 1)
        A, B = double_integrator(T)
        M = np.zeros((6, n))
        M[:, :6] = np.eye(6)
        m = np.zeros(6)
        for step in range(k):
            M = A @ M
            M[:, 6 + 3 * step : 9 + 3 * step] -= B
            m = A @ m + B @ accelerations[step]
        Phi, Btau = sub_step(time - k * T)
        M = Phi @ M
        M[:, 6 + 3 * k : 9 + 3 * k] -= Btau
        return M, Phi @ m + Btau @ accelerations[k]

    rows, values, noise = [], [], []
    for ping_time, sonar, value in pings:
        M, m = state_at(ping_time)
        rows.append(C[sonar] @ M[:3])
        values.append(value - C[sonar] @ m[:3])
        noise.append(ETA_UNEQUAL[sonar])
    M, m = state_at(tick * T)
    if rows:
        H = np.array(rows)
        S = H @ cov_w @ H.T + np.diag(noise)
        K = cov_w @ H.T @ np.linalg.inv(S)
        mean_w = mean_w + K @ (np.array(values) - H @ mean_w)
        cov_w = cov_w - K @ H @ cov_w
    return M @ mean_w + m, M @ cov_w @ M.T


@pytest.mark.parametrize(
    "offsets, latency",
    [
        ((0.0, 0.0), 0.0),
        ((0.0, 0.25), 0.2),
        ((0.0, 0.3), 0.4),
        ((0.1, 0.1), 0.0),
        ((0.2, 0.0), 1.3),
    ],
)
def test_the_estimate_at_each_tick_uses_exactly_the_arrived_ranges(offsets, latency):
    schedule = PingSchedule(T, offsets, latency)
    system = _probe(schedule)
    context = system.CreateDefaultContext()
    rng = np.random.default_rng(11)
    steps = 14
    accelerations = 0.3 * rng.normal(size=(steps, 3))
    values = {(k, i): rng.normal() for k in range(steps) for i in range(2)}
    delays = schedule.delays
    for tick in range(steps):
        samples, status, ping_time = (
            np.full(2, np.nan),
            np.full(2, float(NO_ARRIVAL)),
            np.full(2, np.nan),
        )
        for i in range(2):
            step = tick - delays[i]
            if step >= 0:
                samples[i], status[i] = values[step, i], VALID
                ping_time[i] = schedule.ping_time(step, i)
        for name, value in (("range_samples", samples), ("sonar_status", status),
                            ("R_WB_nav", np.eye(3).ravel()), ("u1_W", accelerations[tick])):  # fmt: skip
            system.GetInputPort(name).FixValue(context, value)
        if system.HasInputPort("ping_time"):
            system.GetInputPort("ping_time").FixValue(context, ping_time)
        context.SetTime(tick * T)
        arrived = [
            (schedule.ping_time(k, i), i, values[k, i])
            for k in range(steps) for i in range(2) if k + delays[i] <= tick
        ]  # fmt: skip
        x, P = _batch(steps, accelerations, arrived, tick)
        assert_allclose(system.GetOutputPort("x_TU_hat").Eval(context), x, rtol=1e-9, atol=1e-10)
        assert_allclose(
            system.GetOutputPort("P_TU").Eval(context).reshape(6, 6), P, rtol=1e-8, atol=1e-11
        )
        news = sum(1 for i in range(2) if tick - delays[i] >= 0)
        code = system.GetOutputPort("measurement_status").Eval(context)[0]
        assert code == (VALID if news else NO_ARRIVAL)
        context.SetDiscreteState(system.EvalUniquePeriodicDiscreteUpdate(context))
