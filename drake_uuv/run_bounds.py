"""The covariance bounds along a run's true trajectory, from its log.

The Fisher information of a run's ranges (:func:`run_information`, summed over runs for the
Monte Carlo PCRLB), the per-run PCRLB and the paper's KF's Riccati covariance
(:func:`bound_covariances`), and with navigation errors or sonar timing
(:func:`bound_errors_on`) the extended bound of :func:`extended_bound`, its pings read from the
log by :func:`ping_arrivals`. A run's log or a batch log alike (:mod:`drake_uuv.batch_logs`):
a leading run axis in, a leading run axis out. The metrics' RMSEs of these bounds are
:func:`drake_uuv.metrics.bound_metrics`.
"""

import numpy as np
from numba import njit

from drake_uuv.batch_logs import batch_log
from drake_uuv.models.measurement import VALID, range_difference_noise
from drake_uuv.models.navigation_noise import (
    commanded_acceleration_noise,
    heading_bias_floor,
    navigated_velocity_covariance,
    range_attitude_jacobian,
    rotation_vector_covariance,
    sound_speed_floor,
)
from drake_uuv.models.pcrlb import measurement_information, pcrlb_recursion
from drake_uuv.models.pcrlb_timed import pcrlb_timed
from drake_uuv.models.ping_geometry import interpolate_attitude_runs
from drake_uuv.scenario import Scenario

# A ping time short of a tick by less than this fraction of a step (rounding of k t + τ)
# belongs to that tick's step: the sonar's own tolerance for its delays.
_STEP_TOLERANCE = 1e-9


def run_information(
    log: dict[str, np.ndarray], scenario: Scenario, out: np.ndarray | None = None
) -> np.ndarray:
    """Fisher information ``M(k)`` (N×6×6) of the raw ranges, all f samples, on this run's true
    trajectory; a sonar without a return (``sonar_status`` not VALID) contributes nothing.

    Summed over runs it gives the Monte Carlo PCRLB (:func:`~drake_uuv.models.pcrlb.
    pcrlb_over_runs`, see :mod:`drake_uuv.studies.statistics`). This is today's information
    whatever the navigation and the sonar timing: each range that arrives at a tick counts
    there, at the tick's geometry, with the sonar's noise alone (:func:`bound_errors_on`
    says when the per-run bound of :func:`bound_covariances` is the extended one instead).
    """
    available = log["sonar_status"] == VALID if "sonar_status" in log else None
    return measurement_information(  # a batch log: B×N×6×6
        log["p_WU"] - log["p_WT"],
        log["b_W"],
        np.asarray(scenario.sonar.noise_variances, dtype=float),
        scenario.sonar.samples_per_step,
        available,
        out,
    )


@njit(cache=True)
def _baseline_information_kernel(q_s: np.ndarray, weight: np.ndarray, out: np.ndarray) -> None:
    """``w q_s q_sᵀ`` in each step's position block, zero elsewhere: the information of the
    paper's ``Y`` (``C = [q_sᵀ, 0]``, weight ``1/Γ`` where both ranges arrived)."""
    for n in range(q_s.shape[0]):
        out[n] = 0.0
        for i in range(3):
            wq = weight[n] * q_s[n, i]
            for j in range(3):
                out[n, i, j] = wq * q_s[n, j]


def bound_covariances(log: dict[str, np.ndarray], scenario: Scenario) -> dict[str, np.ndarray]:
    """Two covariance bounds (N×6×6 each) along this run's true trajectory.

    - ``pcrlb``: the posterior Cramér–Rao bound of the raw two-range measurement (all f
      samples), prior ``P(0|−1)`` = ``estimator.initial_covariance``
      (:mod:`drake_uuv.models.pcrlb`). Per run it is the bound *given this trajectory*;
      the proven Monte Carlo bound averages the information over runs instead.
    - ``kf_riccati``: the paper's KF's Riccati covariance with the noise variance ``Γ`` of its
      ``Y`` (first sample of each sonar, the ``derived`` model) on the true ranges: the MSE of
      the paper's KF when its noise model is right, what it would reach on this trajectory.
      It stays today's with navigation errors and sonar timing: ``Y`` at each tick where
      both ranges arrive, on the tick's geometry.

    With navigation errors or sonar timing (:func:`bound_errors_on`), ``pcrlb`` is the
    extended bound of :func:`extended_bound` (floors included), and ``pcrlb_floor`` is the
    floors' part of it.
    """
    e = scenario.estimator
    q = log["p_WU"] - log["p_WT"]
    eta = np.asarray(scenario.sonar.noise_variances, dtype=float).reshape(2, *[1] * (q.ndim - 1))
    P0 = np.asarray(e.initial_covariance, dtype=float)
    W = np.asarray(scenario.target.acceleration_covariance, dtype=float)
    q_s = log["b_W"]
    half = 0.5 * q_s
    squared = np.stack([np.sum((q + half) ** 2, axis=-1), np.sum((q - half) ** 2, axis=-1)])
    # Mean of the squared noisy ranges is d² + η: the noise model then sees the true d².
    _, gamma = range_difference_noise("derived", eta, squared + eta)
    # The KF's Riccati recursion in information form (C = [q_sᵀ, 0], Y needs both ranges),
    # equal to its Joseph form (pcrlb.kf_riccati_covariance) to rounding, run in one batch
    # with the PCRLB: half the time of two recursions. With the errors on, the PCRLB is the
    # extended bound's instead: the Riccati recursion alone.
    errors_on = bound_errors_on(scenario)
    information = np.empty((1 if errors_on else 2, *q_s.shape[:-1], 6, 6))
    if not errors_on:
        run_information(log, scenario, out=information[0])
    both = np.all(log["sonar_status"] == VALID, axis=-1) if "sonar_status" in log else True
    weight = np.broadcast_to(np.where(both, 1.0 / gamma, 0.0), q_s.shape[:-1])
    _baseline_information_kernel(
        np.ascontiguousarray(q_s, dtype=float).reshape(-1, 3),
        np.ascontiguousarray(weight).reshape(-1),
        information[-1].reshape(-1, 6, 6),
    )
    bounds = pcrlb_recursion(information, P0, W, scenario.time_step)
    if not errors_on:
        return {"pcrlb": bounds[0], "kf_riccati": bounds[1]}
    bound, floor = extended_bound(log, scenario)
    return {"pcrlb": bound + floor, "kf_riccati": bounds[-1], "pcrlb_floor": floor}


def bound_errors_on(scenario: Scenario) -> bool:
    """Whether the navigation, the sonars' timing or the sound speed is other than the
    paper's (perfect navigation, both pings at the tick without latency, ε = 0): then the
    per-run bound is :func:`extended_bound`."""
    return bool(
        scenario.navigation.error_figures().any
        or _sonar_timing_on(scenario)
        or scenario.sonar.sound_speed_error != 0.0
    )


def _sonar_timing_on(scenario: Scenario) -> bool:
    sonar = scenario.sonar
    return any(offset != 0.0 for offset in sonar.ping_offsets) or sonar.latency != 0.0


def ping_arrivals(
    log: dict[str, np.ndarray], scenario: Scenario
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each step's pings that arrive, from the ranges the log shows arriving at each tick.

    Returns ``(tau, lag, p_TS)``: for sonar i's ping of step k, entry ``[k, i]`` holds its
    offset in the step [s] (NaN when no range of it arrives valid), the ticks from k to its
    arrival, and (``[k, i, :]``) its sonar's position relative to the target at the ping.
    An arrival at tick j counts when its ``sonar_status`` is VALID; its step is the tick its
    ``ping_time`` follows. A log without ``ping_time`` and ``p_TS_W`` (a sonar pinging at
    the tick, without latency) gives ``τ = 0``, lag 0 and ``q ± ½ b_W``. A batch log gives
    each run's (a leading run axis); a run whose pings cannot be read raises.
    """
    tau, lag, p_TS, errors = _read_pings(log, scenario)
    for error in errors.reshape(-1):
        if error is not None:
            raise ValueError(error)
    return tau, lag, p_TS


def _read_pings(
    log: dict[str, np.ndarray], scenario: Scenario
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`ping_arrivals` of a run's log or a batch log, and each run's error (an object
    array of the leading axes: None, or the message of why its pings cannot be read; such a
    run's pings are all absent). All runs at once: the arrivals' indices over the runs."""
    lead, steps, t = log["p_WU"].shape[:-2], log["p_WU"].shape[-2], scenario.time_step
    shape = (*lead, steps, 2)
    valid = log["sonar_status"] == VALID if "sonar_status" in log else np.ones(shape, bool)
    errors = np.full(lead, None, dtype=object)
    if "ping_time" not in log or "p_TS_W" not in log:
        sonar = scenario.sonar
        if _sonar_timing_on(scenario):
            raise ValueError(
                "log: has no 'ping_time' and 'p_TS_W', which the bound needs with sonar "
                f"ping_offsets {sonar.ping_offsets} and latency {sonar.latency}"
            )
        half = 0.5 * log["b_W"]
        q = log["p_WU"] - log["p_WT"]
        return (
            np.where(valid, 0.0, np.nan),
            np.zeros(shape, int),
            np.stack([q + half, q - half], -2),
            errors,
        )
    runs = int(np.prod(lead, dtype=int))
    valid = valid.reshape(runs, steps, 2)
    tau = np.full((runs, steps, 2), np.nan)
    lag = np.zeros((runs, steps, 2), int)
    p_TS = np.zeros((runs, steps, 2, 3))
    run, ticks, sonars = np.nonzero(valid)
    ping_time = log["ping_time"].reshape(runs, steps, 2)[run, ticks, sonars]
    with np.errstate(invalid="ignore"):
        step = np.floor(ping_time / t + _STEP_TOLERANCE)
        late = ~((step >= 0) & (step <= ticks))  # NaN too
    step = np.where(late, 0, step).astype(int)
    key = (run * steps + step) * 2 + sonars
    order = np.argsort(key, kind="stable")
    twice = np.zeros(len(key), bool)
    twice[order[1:]] = key[order[1:]] == key[order[:-1]]
    flat = errors.reshape(-1)
    for r in np.unique(run[twice]):  # rare: a run's log is wrong
        flat[r] = "log: a sonar's ping of one step arrives twice"
    for r in np.unique(run[late]):
        flat[r] = f"log: ping_time {ping_time[run == r]} must be at or before the arrival ticks"
    read = np.array([error is None for error in flat], bool)[run]
    run, ticks, sonars, step, ping_time = (a[read] for a in (run, ticks, sonars, step, ping_time))
    tau[run, step, sonars] = np.maximum(ping_time - step * t, 0.0)
    lag[run, step, sonars] = ticks - step
    p_TS[run, step, sonars] = log["p_TS_W"].reshape(runs, steps, 2, 3)[run, ticks, sonars]
    return tau.reshape(shape), lag.reshape(shape), p_TS.reshape(*shape, 3), errors


#: The signals of a run's true state and baseline: a run with a non-finite one has failed.
_STATE = ("p_WU", "v_WU", "p_WT", "v_WT", "R_WB", "b_W")


def extended_bound(log: dict[str, np.ndarray], scenario: Scenario) -> tuple[np.ndarray, np.ndarray]:
    """The per-run PCRLB with navigation errors and sonar timing, and its error floors
    (N×6×6 each; the bound proper excludes the floors, the metrics add them).

    On this run's true trajectory (:mod:`drake_uuv.models.pcrlb_timed`,
    :mod:`drake_uuv.models.navigation_noise` for the models and their derivations):

    - each range at its ping time, counted from the tick it arrives (:func:`ping_arrivals`);
    - the range noise ``η/f`` plus, with ``!InertialNavigation``, the attitude noise's
      ``J Σ_θ Jᵀ`` (``Σ_θ`` at the step's true attitude, ``J`` at each ping's geometry);
    - with ``estimator.vehicle_motion: commanded``, ``W + [a]× Σ_θ [a]×ᵀ`` per step (``a``:
      the log's ``u1_W``); with ``navigation``, the navigated velocity's error
      ``Σ_ev = (σ_v² + σ_b²) I + [v]× Σ_θ [v]×ᵀ`` (the DVL's noise and bias, and the attitude
      noise turning the true velocity ``v``) as a position process noise ``t² Σ_ev`` per step,
      and ``Σ_ev`` added to the velocity block at each tick;
    - floors: the heading bias's ``σ_ψ² g gᵀ`` and the sound speed's ``ε² q qᵀ``.

    The bound is the estimator's whatever it believes (``estimator.error_model`` does not
    enter): it is what the data allow.

    A batch log (B×N×…) gives each run's (B×N×6×6 each), the same bits as the run alone, all
    runs in one pass. A failed run (a non-finite true state or baseline) is NaN where its
    recursion meets the failure, and all NaN if its pings cannot be read; a sound run whose
    pings cannot be read raises.
    """
    single = log["p_WU"].ndim == 2
    runs = batch_log(log) if single else log
    t = scenario.time_step
    nav = scenario.navigation.error_figures()
    motion = scenario.estimator.vehicle_motion
    tau, lag, p_TS, errors = _read_pings(runs, scenario)
    failed = np.array([error is not None for error in errors], bool)
    if failed.any():
        sound = np.ones(len(failed), bool)
        for name in _STATE:
            sound &= np.isfinite(runs[name]).reshape(len(failed), -1).all(axis=1)
        if (failed & sound).any():
            raise ValueError(errors[np.flatnonzero(failed & sound)[0]])
    R_WB = runs["R_WB"]
    with np.errstate(invalid="ignore", over="ignore"):  # a failed run's NaN and inf
        Sigma = rotation_vector_covariance(R_WB, nav.attitude_noise)
        W = np.asarray(scenario.target.acceleration_covariance, dtype=float)
        if motion == "commanded":
            W = W + commanded_acceleration_noise(runs["u1_W"], Sigma)
        velocity = np.zeros(R_WB.shape)
        if motion == "navigation":  # the navigated velocity's error Σ_ev, on the true motion
            velocity += navigated_velocity_covariance(
                runs["v_WU"], Sigma, nav.velocity_noise, nav.velocity_bias
            )
        bound = pcrlb_timed(
            tau,
            lag,
            p_TS,
            _range_noise(tau, p_TS, R_WB, Sigma, scenario),
            np.asarray(scenario.estimator.initial_covariance, dtype=float),
            W,
            t,
            position_noise=t * t * velocity,
        )
        bound[..., 3:, 3:] += velocity
        q = (runs["p_WU"] - runs["p_WT"]).reshape(-1, 3)
        floor = heading_bias_floor(
            q, (runs["v_WU"] - runs["v_WT"]).reshape(-1, 3), nav.heading_bias
        )
        floor += sound_speed_floor(q, scenario.sonar.sound_speed_error)
    floor = floor.reshape(bound.shape)
    bound[failed] = np.nan
    floor[failed] = np.nan
    return (bound[0], floor[0]) if single else (bound, floor)


def _range_noise(
    tau: np.ndarray, p_TS: np.ndarray, R_WB: np.ndarray, Sigma: np.ndarray, scenario: Scenario
) -> np.ndarray:
    """The covariance (B×N×2×2) of each step's two range errors: ``diag(η/f) + J Σ_θ Jᵀ``,
    the baseline at each ping from the attitude's geodesic between the step's ticks (every
    ping of every run at once: :func:`~drake_uuv.models.ping_geometry.
    interpolate_attitude_runs`)."""
    sonar = scenario.sonar
    noise = np.zeros(tau.shape + (2,))
    noise[..., [0, 1], [0, 1]] = (
        np.asarray(sonar.noise_variances, dtype=float) / sonar.samples_per_step
    )
    if not np.any(scenario.navigation.error_figures().attitude_noise):
        return noise
    run, step, sonar_index = np.nonzero(np.isfinite(tau))
    following = np.minimum(step + 1, tau.shape[1] - 1)  # a ping at τ > 0 has a next tick
    R = interpolate_attitude_runs(
        R_WB[run, step], R_WB[run, following], tau[run, step, sonar_index] / scenario.time_step
    )
    q_s = np.zeros(p_TS.shape)
    q_s[run, step, sonar_index] = R @ np.asarray(sonar.baseline, dtype=float)
    J = range_attitude_jacobian(p_TS, q_s)
    return noise + J @ Sigma @ np.swapaxes(J, -1, -2)
