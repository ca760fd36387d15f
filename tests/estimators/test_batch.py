"""A batch of runs through one estimator is, bit for bit, each run alone: the paper's KF and
the raw-range filters (EKF, IEKF, UKF) on random batches that mix their phases (linear start
and Gaussian), gated and accepted updates, dropped ranges, late ranges at their ping times, and
a run that failed (NaN)."""

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from drake_uuv.estimators import EstimatorSetting, RangeDifferenceKalmanFilter, RangeFilter
from drake_uuv.models.handover import Phase
from drake_uuv.models.measurement import (
    DROPPED,
    NO_ARRIVAL,
    OUT_OF_BEAM,
    VALID,
    range_measurement,
)
from drake_uuv.models.statistics import chi2_ppf
from drake_uuv.models.timing import PingSchedule
from drake_uuv.scenario import Ekf, Iekf, NavigationErrors, PaperKf, ParticleFilter, Ukf
from drake_uuv.testing import (
    after_update,
    assert_batch_equals_runs,
    fixed_context,
    set_states,
)
from tests.conftest import ETA_UNEQUAL, T, W

F = 3
B_BODY = np.array([-0.6, 1.1, 0.5])
X_TRUE = np.array([-2.0, -2.0, 0.3, 0.1, 0.0, -0.05])
ERRORS = NavigationErrors(
    attitude_noise=np.radians([0.5, 0.5, 2.0]), heading_bias=np.radians(2.0),
    velocity_noise=0.01, velocity_bias=0.005,
)  # fmt: skip
KINDS = {"kf": PaperKf, "ekf": Ekf, "iekf": Iekf, "ukf": Ukf}
# The raw-range filters without particles (the particle clouds are tested on their own).
NO_PARTICLES = dict(particle_bridge=False)
COUNT = 40  # particles of a run's cloud in the tests of late ranges


def setting(errors: bool) -> EstimatorSetting:
    extra = dict(navigation_errors=ERRORS, sound_speed_error=0.004) if errors else {}
    return EstimatorSetting(
        time_step=T, acceleration_covariance=W, noise_variances=ETA_UNEQUAL,
        samples_per_step=F, baseline_B=B_BODY, **extra,
    )  # fmt: skip


def maker(kind: str, errors: bool = False, **fields):
    config = KINDS[kind](gate_probability=0.99, **fields)
    cls = RangeDifferenceKalmanFilter if kind == "kf" else RangeFilter

    def make(batch_size: int):
        return cls(config, setting=setting(errors), batch_size=batch_size)

    return make


def rotation(rng: np.random.Generator) -> np.ndarray:
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    angle = rng.uniform(0.0, 1.0)
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def random_runs(system_make, B: int, seed: int, *, navigated: bool = False, nan_run=None):
    """Random inputs and states of B runs: priors near and far from the truth (accepted and
    gated updates), some sonars dropped, phases mixed for a raw-range filter."""
    rng = np.random.default_rng(seed)
    system = system_make(1)
    samples, status, attitudes = [], [], []
    for _ in range(B):
        R_WB = rotation(rng)
        d = range_measurement(X_TRUE, R_WB @ B_BODY)
        s = d[:, None] + 0.1 * rng.standard_normal((2, F))
        code = rng.choice([VALID, VALID, VALID, DROPPED, OUT_OF_BEAM], size=2)
        s[code != VALID] = np.nan
        samples.append(s.ravel())
        status.append(code.astype(float))
        attitudes.append(R_WB.ravel())
    inputs = dict(range_samples=np.array(samples), sonar_status=np.array(status))
    inputs["R_WB_nav"] = np.array(attitudes)
    if navigated:
        inputs["p_WU_nav"] = rng.normal(size=(B, 3))
        inputs["v_WU_nav"] = rng.normal(size=(B, 3))
    else:
        inputs["u1_W"] = rng.normal(size=(B, 3))
    offsets = rng.choice([0.05, 0.3, 3.0], size=B)  # accepted, some gated
    x = X_TRUE + offsets[:, None] * rng.standard_normal((B, 6))
    M = rng.normal(size=(B, 6, 6))
    P = 0.05 * M @ M.transpose(0, 2, 1) + 0.02 * np.eye(6)
    states = [x, P.reshape(B, 36)]
    if isinstance(system, RangeFilter):
        share = rng.choice([0.001, 0.5], size=B)  # prior forgotten or not
        states.append((share[:, None, None] * P).reshape(B, 36))
        phases = rng.choice([Phase.LINEAR, Phase.RANGE], size=B).astype(float)
        states.append(np.stack([phases, rng.integers(0, 5, size=B)], axis=1).astype(float))
    if nan_run is not None:
        states[0][nan_run] = np.nan
        states[1][nan_run] = np.nan
    return inputs, states


@pytest.mark.parametrize("kind", list(KINDS))
@pytest.mark.parametrize("B", [1, 2, 5])
def test_a_batch_step_is_each_run_alone(kind: str, B: int) -> None:
    make = maker(kind, **({} if kind == "kf" else NO_PARTICLES))
    for seed in range(3):
        inputs, states = random_runs(make, B, seed)
        assert_batch_equals_runs(make, inputs, states, time=2.0)


@pytest.mark.parametrize("kind", list(KINDS))
def test_with_the_error_model_and_navigated_motion_a_batch_is_each_run(kind: str) -> None:
    fields = dict(vehicle_motion="navigation")
    if kind != "kf":
        fields.update(NO_PARTICLES)
    make = maker(kind, errors=True, **fields)
    inputs, states = random_runs(make, 4, 7, navigated=True)
    assert_batch_equals_runs(make, inputs, states, time=2.0)
    make = maker(kind, errors=True, **({} if kind == "kf" else NO_PARTICLES))
    inputs, states = random_runs(make, 4, 8)
    assert_batch_equals_runs(make, inputs, states, time=2.0)


@pytest.mark.parametrize("kind", list(KINDS))
def test_a_failed_run_leaves_the_others_alone(kind: str) -> None:
    """One run's state is NaN: nothing raises, and the other runs' bits are theirs alone."""
    make = maker(kind, **({} if kind == "kf" else NO_PARTICLES))
    inputs, states = random_runs(make, 4, 3, nan_run=2)
    assert_batch_equals_runs(make, inputs, states, time=2.0)
    system = make(4)
    context = fixed_context(system, **{k: v.ravel() for k, v in inputs.items()})
    for group, value in enumerate(states):
        context.SetDiscreteState(group, value.ravel())
    x = system.GetOutputPort("x_TU_hat").Eval(context).reshape(4, 6)
    assert np.isnan(x[2]).all() and np.isfinite(x[[0, 1, 3]]).all()
    after = system.EvalUniquePeriodicDiscreteUpdate(context).get_vector(0).value()
    assert np.isfinite(after.reshape(4, 6)[[0, 1, 3]]).all()


def test_the_batch_mixes_phases_gates_and_drops() -> None:
    """The random batches above hold what they are meant to: runs in the linear start and in
    the Gaussian phase, updated, gated and only predicted, in one batch."""
    make = maker("ekf", **NO_PARTICLES)
    inputs, states = random_runs(make, 12, 1)
    system = make(12)
    context = fixed_context(system, **{k: v.ravel() for k, v in inputs.items()})
    for group, value in enumerate(states):
        context.SetDiscreteState(group, value.ravel())
    status = system.GetOutputPort("measurement_status").Eval(context)
    phases = system.phases(context)
    assert {Phase.LINEAR, Phase.RANGE} <= set(phases.tolist())
    assert {0.0, 4.0} <= set(status.tolist())  # VALID and GATED
    assert set(status.tolist()) & {float(DROPPED), float(OUT_OF_BEAM)}


def test_batch_size_is_checked_and_particles_step_batches_with_late_ranges_too() -> None:
    """A filter that may carry particles steps a batch, with the paper's timing and with late
    ranges (each run's cloud through its own ping window)."""
    with pytest.raises(ValueError, match=r"^batch_size: must be an integer ≥ 1, got 0"):
        maker("kf")(0)
    assert RangeFilter(Ekf(), setting=setting(False), batch_size=2).batch_size == 2
    timed = EstimatorSetting(
        time_step=T, acceleration_covariance=W, noise_variances=ETA_UNEQUAL,
        samples_per_step=F, baseline_B=B_BODY, ping_schedule=SCHEDULE,
    )  # fmt: skip
    assert RangeFilter(Ekf(), setting=timed, batch_size=2).cloud.batch_size == 2


SCHEDULE = PingSchedule(T, (0.1, 0.3), 0.6)  # both ranges two ticks late: D = 2


def timed_maker(kind: str, errors: bool = False, **fields):
    config = KINDS[kind](gate_probability=0.99, **fields)
    cls = RangeDifferenceKalmanFilter if kind == "kf" else RangeFilter
    extra = dict(navigation_errors=ERRORS, sound_speed_error=0.004) if errors else {}
    timed = EstimatorSetting(
        time_step=T, acceleration_covariance=W, noise_variances=ETA_UNEQUAL,
        samples_per_step=F, baseline_B=B_BODY, ping_schedule=SCHEDULE, **extra,
    )  # fmt: skip

    def make(batch_size: int):
        return cls(config, setting=timed, batch_size=batch_size)

    return make


def random_timed_runs(make, B: int, seed: int, tick: int, *, navigated: bool = False):
    """Random runs with late ranges: the window's stored ranges (arrived, dropped, not yet
    arrived, at random ping offsets), attitudes and motion, and this tick's arrivals."""
    rng = np.random.default_rng(seed)
    inputs, states = random_runs(make, B, seed, navigated=navigated)
    D = SCHEDULE.window
    slot = 4 + 2 * F
    slots = np.full((B, D, slot), np.nan)
    attitudes = np.empty((B, D, 9))
    for r in range(B):
        for k in range(D):
            R_WB = rotation(rng)
            attitudes[r, k] = R_WB.ravel()
            d = range_measurement(X_TRUE, R_WB @ B_BODY)
            code = rng.choice([VALID, VALID, DROPPED, NO_ARRIVAL], size=2).astype(float)
            slots[r, k, :2] = code
            slots[r, k, 2:4] = rng.choice([0.1, 0.3, 0.3], size=2)
            values = d[:, None] + 0.1 * rng.standard_normal((2, F))
            values[code != VALID] = np.nan
            slots[r, k, 4:] = values.ravel()
    motion = rng.normal(size=(B, D, 6 if navigated else 3))
    # This tick's arrivals: the ranges of step tick − 2, at their ping times (or none).
    arrived = rng.random((B, 2)) < 0.8
    ping = np.where(arrived, (tick - 2) * T + np.array([0.1, 0.3]), np.nan)
    inputs["sonar_status"] = np.where(arrived, inputs["sonar_status"], float(NO_ARRIVAL))
    inputs["ping_time"] = ping
    window = [slots.reshape(B, -1), attitudes.reshape(B, -1), motion.reshape(B, -1)]
    states = states[:2] + window + states[2:]
    return inputs, states


@pytest.mark.parametrize("kind", list(KINDS))
@pytest.mark.parametrize("B", [1, 3])
def test_with_late_ranges_a_batch_step_is_each_run_alone(kind: str, B: int) -> None:
    fields = {} if kind == "kf" else NO_PARTICLES
    make = timed_maker(kind, **fields)
    for seed in range(2):
        inputs, states = random_timed_runs(make, B, seed, tick=6)
        assert_batch_equals_runs(make, inputs, states, time=6 * T)


@pytest.mark.parametrize("kind", ["kf", "ukf"])
def test_with_late_ranges_errors_navigation_and_a_failed_run(kind: str) -> None:
    fields = dict(vehicle_motion="navigation", **({} if kind == "kf" else NO_PARTICLES))
    make = timed_maker(kind, errors=True, **fields)
    inputs, states = random_timed_runs(make, 4, 5, tick=7, navigated=True)
    assert_batch_equals_runs(make, inputs, states, time=7 * T)
    states[0][1] = np.nan  # run 1 failed
    states[1][1] = np.nan
    assert_batch_equals_runs(make, inputs, states, time=7 * T)


def recovery_states(rng: np.random.Generator, B: int, window: int) -> list[np.ndarray]:
    """A Gaussian filter's recovery state for B runs: windows one update short of full (this
    tick's fills them), the even runs' far above their χ² quantile, the odd ones' typical;
    and records of no restart so far."""
    windows = np.full((B, 2 * window), np.nan)
    scale = np.where(np.arange(B) % 2 == 0, 40.0, 1.0)
    windows[:, 1:window] = rng.chisquare(2, size=(B, window - 1)) * scale[:, np.newaxis]
    windows[:, window + 1 :] = 2.0
    return [windows, np.tile([0.0, np.nan, np.nan, np.nan], (B, 1))]


def random_cloud_runs(
    make, B: int, seed: int, tick: int, *, errors: bool = False, nan_run=None,
    diverging: bool = False,
):  # fmt: skip
    """Random runs with late ranges (:func:`random_timed_runs`) whose phases mix the particle
    phase (a live cloud at the window's anchor with its window's accelerations, and with
    navigation errors their noise) with the linear start and, for a filter with a Gaussian
    update, the Gaussian phase; and each run's uniform of the step. The recovery windows are
    empty, or with ``diverging`` about to fire in the even runs."""
    rng = np.random.default_rng(100 + seed)
    inputs, states = random_timed_runs(make, B, seed, tick, navigated=errors)
    system = make(1)
    D = SCHEDULE.window
    choices = [Phase.LINEAR, Phase.PARTICLE, Phase.PARTICLE]
    if system.policy.particle_bridge:
        choices.append(Phase.RANGE)
    phases = rng.choice(choices, size=B).astype(float)
    phases[0] = float(Phase.PARTICLE)  # each batch holds a cloud
    states[-1][:, 0] = phases
    particles = X_TRUE + 0.3 * rng.standard_normal((B, COUNT, 6))
    log_weights = -0.5 * rng.random((B, COUNT)) ** 2
    live = (phases == Phase.PARTICLE).astype(float)
    accelerations = 0.1 * rng.standard_normal((B, D * 3 * COUNT))
    cloud = {
        "particles": particles, "log_weights": log_weights, "live": live,
        "accelerations": accelerations,
    }  # fmt: skip
    if errors:
        cloud["jitter"] = 0.01 * rng.standard_normal((B, D * 6 * COUNT))
    if nan_run is not None:
        particles[nan_run] = np.nan
    test = system.divergence
    if test is not None:
        recovery = recovery_states(rng, B, test.window)
        if not diverging:
            recovery[0][:] = np.nan
        states += recovery
    assert len(states) == system.num_discrete_state_groups()
    inputs["particle_seed"] = rng.random((B, 1))
    return inputs, states, {system.cloud.state_index: cloud}


@pytest.mark.parametrize("kind", ["pf", "ekf"])
@pytest.mark.parametrize("B", [1, 2, 5])
def test_with_late_ranges_a_batch_of_clouds_is_each_run_alone(kind: str, B: int) -> None:
    """Each run's cloud stepped through its own window (filtered estimate and periodic
    update: moved on, resampled, drawn anew for a run entering the particles) is the run
    alone, bit for bit, with runs of every phase in the batch; before the window is full
    (tick 1) and after (tick 6)."""
    make = cloud_maker(kind)
    for seed in (0, 2):
        for tick in (1, 6):
            inputs, states, arrays = random_cloud_runs(make, B, seed, tick, diverging=True)
            assert_batch_equals_runs(make, inputs, states, time=tick * T, arrays=arrays)


def test_with_late_ranges_errors_and_navigation_a_batch_of_clouds_is_each_run_alone() -> None:
    make = cloud_maker("pf", errors=True, vehicle_motion="navigation")
    inputs, states, arrays = random_cloud_runs(make, 4, 3, 6, errors=True)
    assert_batch_equals_runs(make, inputs, states, time=6 * T, arrays=arrays)


def test_with_late_ranges_a_failed_cloud_leaves_the_others_alone() -> None:
    """Run 1's particles are NaN: nothing raises, its estimate is NaN, and the other runs'
    bits are theirs alone."""
    make = cloud_maker("pf")
    inputs, states, arrays = random_cloud_runs(make, 4, 4, 6, nan_run=1)
    # Every run on particles, live (the phase group precedes the recovery's two).
    states[-3 if make(1).divergence is not None else -1][:, 0] = float(Phase.PARTICLE)
    (cloud,) = arrays.values()
    cloud["live"][:] = 1.0
    assert_batch_equals_runs(make, inputs, states, time=6 * T, arrays=arrays)
    system = make(4)
    context = fixed_context(system, **{k: v.ravel() for k, v in inputs.items()})
    set_states(context, states, arrays)
    x = system.GetOutputPort("x_TU_hat").Eval(context).reshape(4, 6)
    assert np.isnan(x[1]).all() and np.isfinite(x[[0, 2, 3]]).all()
    after_update(system, context)


def test_the_batch_of_clouds_mixes_draws_moves_and_hand_backs() -> None:
    """The EKF's random batch above (seed 2, tick 6) holds what it is meant to: runs that
    stay on their particles, a run that hands back to the Gaussian, a run that enters the
    particles (its cloud drawn at the new anchor), a linear start and a gated update. (Run 3
    hands back too when its cloud's update is Bayes' rule; the tempered update keeps it wider,
    on its particles.)"""
    make = cloud_maker("ekf")
    inputs, states, arrays = random_cloud_runs(make, 5, 2, 6)
    system = make(5)
    context = fixed_context(system, **{k: v.ravel() for k, v in inputs.items()})
    context.SetTime(6 * T)
    set_states(context, states, arrays)
    after = after_update(system, context)
    L, R, P = Phase.LINEAR, Phase.RANGE, Phase.PARTICLE
    assert system.phases(context).tolist() == [P, L, P, P, L]
    assert system.phases(after).tolist() == [R, L, P, P, P]
    assert system.cloud.live(after).tolist() == [False, False, True, True, True]
    assert system.GetOutputPort("measurement_status").Eval(context).tolist() == [
        VALID, 4.0, VALID, VALID, VALID,
    ]  # fmt: skip


def cloud_maker(kind: str, errors: bool = False, **fields):
    """A filter that carries particles with late ranges: the particle filter, or the EKF with
    its particle bridge."""
    config = {"pf": ParticleFilter, "ekf": Ekf}[kind]
    config = config(gate_probability=0.99, particle_count=COUNT, **fields)
    extra = dict(navigation_errors=ERRORS, sound_speed_error=0.004) if errors else {}
    timed = EstimatorSetting(
        time_step=T, acceleration_covariance=W, noise_variances=ETA_UNEQUAL,
        samples_per_step=F, baseline_B=B_BODY, ping_schedule=SCHEDULE, **extra,
    )  # fmt: skip

    def make(batch_size: int):
        return RangeFilter(config, setting=timed, batch_size=batch_size)

    return make


def test_with_late_ranges_a_diverged_run_restarts_from_its_widened_anchor() -> None:
    """The recovery with late ranges: each Gaussian run adds every range that arrived at this
    tick (applied or gated) to its window; the even runs' windows, far above their χ²
    quantile, fire. A restarting run goes back to its linear start, its record says why (the
    window's sum above the quantile of its summed dimensions), and the anchor it writes is
    the window's oldest step moved on with the covariance widened by the window's mean NIS
    per dimension plus the initial covariance; the other runs write theirs unwidened."""
    window = 3
    make = timed_maker("ekf", recovery_window=window, **NO_PARTICLES)
    B = 6
    inputs, states = random_timed_runs(make, B, 7, tick=6)
    states[-1][:, 0] = float(Phase.RANGE)
    states += recovery_states(np.random.default_rng(8), B, window)
    system = make(B)
    context = fixed_context(system, **{k: v.ravel() for k, v in inputs.items()})
    context.SetTime(6 * T)
    for group, value in enumerate(states):
        context.SetDiscreteState(group, value.ravel())
    # This tick's new ranges: those that arrived valid (random_timed_runs' arrivals).
    arrived = (inputs["sonar_status"] == VALID).sum(axis=1)
    outcome = system.anchor_advance(context)
    after = system.EvalUniquePeriodicDiscreteUpdate(context)
    record = after.get_vector(8).value().reshape(B, 4)
    restarted = record[:, 0] == 1.0
    even = np.arange(B) % 2 == 0
    assert restarted.tolist() == (even & (arrived > 0)).tolist()
    assert restarted.any()
    phase = after.get_vector(6).value().reshape(B, 2)[:, 0]
    assert (phase[restarted] == float(Phase.LINEAR)).all()
    assert (phase[~restarted] != float(Phase.LINEAR)).all()
    # Why: the window's sum, the χ² quantile of its dimensions (2 per earlier update, and
    # this tick's arrivals).
    dims = 2.0 * (window - 1) + arrived
    assert_allclose(record[restarted, 3], dims[restarted])
    quantiles = [chi2_ppf(1 - system.divergence.probability, d) for d in dims[restarted]]
    assert_allclose(record[restarted, 2], quantiles, rtol=1e-12)
    assert (record[restarted, 1] > record[restarted, 2]).all()
    # The anchor: moved on, widened where the run restarts.
    P_next = after.get_vector(1).value().reshape(B, 6, 6)
    x_next = after.get_vector(0).value().reshape(B, 6)
    scale = record[:, 1] / record[:, 3]
    P0 = system.initial_estimate.P
    widened = outcome.P * scale[:, None, None] + P0
    assert_allclose(P_next[restarted], widened[restarted], rtol=1e-14)
    assert_array_equal(P_next[~restarted], outcome.P[~restarted])
    assert_array_equal(x_next, outcome.x)
