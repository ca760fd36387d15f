"""Error statistics of one run, computed from its log."""

import numpy as np

from drake_uuv.models.attitude_candidates import rotation_angles
from drake_uuv.models.information import excitation_eigenvalues
from drake_uuv.models.measurement import VALID, range_difference_noise
from drake_uuv.models.navigation_noise import (
    commanded_acceleration_noise,
    heading_bias_floor,
    navigated_velocity_covariance,
    range_attitude_jacobian,
    rotation_vector_covariance,
    sound_speed_floor,
)
from drake_uuv.models.pcrlb import bound_rmse, measurement_information, pcrlb_recursion
from drake_uuv.models.pcrlb_timed import pcrlb_timed
from drake_uuv.models.ping_geometry import interpolate_attitude
from drake_uuv.models.tracking_laws import desired_relative_positions
from drake_uuv.scenario import Scenario

#: The log's signals that a run's metrics and warnings (:func:`run_metrics`,
#: :func:`drake_uuv.diagnostics.run_warnings`) and a study's per-run arrays (errors, information)
#: read whatever the scenario: the truth, the estimate, the filter's input, the sonar's baseline
#: and returns, and a vehicle's or a filter's own signals (:func:`metric_signals`).
METRIC_SIGNALS = frozenset(
    {
        "p_WU", "v_WU", "R_WB", "p_WT", "v_WT", "x_TU_hat", "P_TU", "u1_W", "b_W",
        "sonar_status", "R_WB_command", "w_WB", "w_WB_command", "saturation_ticks",
        "estimator_phase",
    }
)  # fmt: skip


def metric_signals(scenario: Scenario) -> frozenset[str]:
    """The signals a run of ``scenario`` must log for its metrics and warnings: a run that logs
    only these (``ClosedLoopSimulation(..., log="metrics")``) has the same metrics.
    :data:`METRIC_SIGNALS`, and each ping's time and geometry where the bound is the
    extended one (:func:`bound_errors_on`)."""
    if bound_errors_on(scenario):
        return METRIC_SIGNALS | {"ping_time", "p_TS_W"}
    return METRIC_SIGNALS


# A ping time short of a tick by less than this fraction of a step (rounding of k t + τ)
# belongs to that tick's step: the sonar's own tolerance for its delays.
_STEP_TOLERANCE = 1e-9


def errors(log: dict[str, np.ndarray], scenario: Scenario) -> dict[str, np.ndarray]:
    """Per-step errors: estimation (position, velocity), tracking, and NEES.

    - ``position``/``velocity`` (N×3): true minus filtered relative position/velocity.
    - ``tracking`` (N×3): ``q − R q*``, the offset from the desired relative position.
    - ``nees`` (N): ``eᵀ P⁻¹ e`` for the 6-D estimation error ``e``.
    """
    q = log["p_WU"] - log["p_WT"]
    velocity = log["v_WU"] - log["v_WT"]
    e = np.concatenate([q, velocity], axis=1) - log["x_TU_hat"]
    tracking = scenario.tracking
    return {
        "position": e[:, :3],
        "velocity": e[:, 3:],
        "tracking": q
        - desired_relative_positions(
            log["R_WB"], tracking.desired_relative_position, tracking.reference_frame
        ),
        "nees": _nees(e, log["P_TU"]),
        "relative_velocity": velocity,
    }


def _nees(e: np.ndarray, P: np.ndarray) -> np.ndarray:
    """``eᵀ P⁻¹ e`` per step; ``inf`` where ``P`` is not finite and numerically positive
    definite (its smallest eigenvalue above ``6 ε`` times its largest): a covariance that lost
    definiteness, or so ill-conditioned that ``P⁻¹`` is rounding, claims no consistent error
    (without this a diverged filter's NEES could come out negative)."""
    nees = np.full(len(e), np.inf)
    ok = np.isfinite(P).all(axis=(1, 2))
    values = np.linalg.eigvalsh(P[ok])
    ok[ok] = values[:, 0] > 6 * np.finfo(float).eps * values[:, -1]
    nees[ok] = np.einsum("ki,ki->k", e[ok], np.linalg.solve(P[ok], e[ok, :, np.newaxis])[:, :, 0])
    return nees


def run_information(log: dict[str, np.ndarray], scenario: Scenario) -> np.ndarray:
    """Fisher information ``M(k)`` (N×6×6) of the raw ranges, all f samples, on this run's true
    trajectory; a sonar without a return (``sonar_status`` not VALID) contributes nothing.

    Summed over runs it gives the Monte Carlo PCRLB (:func:`~drake_uuv.models.pcrlb.
    pcrlb_over_runs`, see :mod:`drake_uuv.studies.statistics`). This is today's information
    whatever the navigation and the sonar timing: each range that arrives at a tick counts
    there, at the tick's geometry, with the sonar's noise alone (:func:`bound_errors_on`
    says when the per-run bound of :func:`bound_covariances` is the extended one instead).
    """
    available = log["sonar_status"] == VALID if "sonar_status" in log else None
    return measurement_information(
        log["p_WU"] - log["p_WT"],
        log["b_W"],
        np.asarray(scenario.sonar.noise_variances, dtype=float),
        scenario.sonar.samples_per_step,
        available,
    )


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
    eta = np.asarray(scenario.sonar.noise_variances, dtype=float)[:, np.newaxis]
    P0 = np.asarray(e.initial_covariance, dtype=float)
    W = np.asarray(scenario.target.acceleration_covariance, dtype=float)
    q_s = log["b_W"]
    half = 0.5 * q_s
    squared = np.stack([np.sum((q + half) ** 2, axis=1), np.sum((q - half) ** 2, axis=1)])
    # Mean of the squared noisy ranges is d² + η: the noise model then sees the true d².
    _, gamma = range_difference_noise("derived", eta, squared + eta)
    # The KF's Riccati recursion in information form (C = [q_sᵀ, 0], Y needs both ranges),
    # equal to its Joseph form (pcrlb.kf_riccati_covariance) to rounding, run in one batch
    # with the PCRLB: half the time of two recursions.
    information = np.zeros((2, *q_s.shape[:1], 6, 6))
    information[0] = run_information(log, scenario)
    both = np.all(log["sonar_status"] == VALID, axis=1) if "sonar_status" in log else True
    weight = np.where(both, 1.0 / gamma, 0.0)
    information[1, :, :3, :3] = weight[:, None, None] * q_s[:, :, None] * q_s[:, None, :]
    pcrlb, riccati = pcrlb_recursion(information, P0, W, scenario.time_step)
    if not bound_errors_on(scenario):
        return {"pcrlb": pcrlb, "kf_riccati": riccati}
    bound, floor = extended_bound(log, scenario)
    return {"pcrlb": bound + floor, "kf_riccati": riccati, "pcrlb_floor": floor}


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
    the tick, without latency) gives ``τ = 0``, lag 0 and ``q ± ½ b_W``.
    """
    steps, t = len(log["p_WU"]), scenario.time_step
    valid = log["sonar_status"] == VALID if "sonar_status" in log else np.ones((steps, 2), bool)
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
            np.zeros((steps, 2), int),
            np.stack([q + half, q - half], 1),
        )
    tau = np.full((steps, 2), np.nan)
    lag = np.zeros((steps, 2), int)
    p_TS = np.zeros((steps, 2, 3))
    ticks, sonars = np.nonzero(valid)
    ping_time = log["ping_time"][ticks, sonars]
    step = np.floor(ping_time / t + _STEP_TOLERANCE).astype(int)
    if np.any((step < 0) | (step > ticks)):
        raise ValueError(f"log: ping_time {ping_time} must be at or before the arrival ticks")
    if len(set(zip(step, sonars, strict=True))) < len(step):
        raise ValueError("log: a sonar's ping of one step arrives twice")
    tau[step, sonars] = np.maximum(ping_time - step * t, 0.0)
    lag[step, sonars] = ticks - step
    p_TS[step, sonars] = log["p_TS_W"].reshape(steps, 2, 3)[ticks, sonars]
    return tau, lag, p_TS


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
    """
    t = scenario.time_step
    nav = scenario.navigation.error_figures()
    motion = scenario.estimator.vehicle_motion
    tau, lag, p_TS = ping_arrivals(log, scenario)
    R_WB = log["R_WB"]
    Sigma = rotation_vector_covariance(R_WB, nav.attitude_noise)
    W = np.asarray(scenario.target.acceleration_covariance, dtype=float)
    if motion == "commanded":
        W = W + commanded_acceleration_noise(log["u1_W"], Sigma)
    velocity = np.zeros((len(R_WB), 3, 3))
    if motion == "navigation":  # the navigated velocity's error Σ_ev, on the true motion
        velocity += navigated_velocity_covariance(
            log["v_WU"], Sigma, nav.velocity_noise, nav.velocity_bias
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
    bound[:, 3:, 3:] += velocity
    q, velocity = log["p_WU"] - log["p_WT"], log["v_WU"] - log["v_WT"]
    floor = heading_bias_floor(q, velocity, nav.heading_bias)
    floor += sound_speed_floor(q, scenario.sonar.sound_speed_error)
    return bound, floor


def _range_noise(
    tau: np.ndarray, p_TS: np.ndarray, R_WB: np.ndarray, Sigma: np.ndarray, scenario: Scenario
) -> np.ndarray:
    """The covariance (N×2×2) of each step's two range errors: ``diag(η/f) + J Σ_θ Jᵀ``, the
    baseline at each ping from the attitude's geodesic between the step's ticks."""
    sonar = scenario.sonar
    noise = np.zeros(tau.shape + (2,))
    noise[:, [0, 1], [0, 1]] = (
        np.asarray(sonar.noise_variances, dtype=float) / sonar.samples_per_step
    )
    if not np.any(Sigma):
        return noise
    b = np.asarray(sonar.baseline, dtype=float)
    q_s = np.zeros(p_TS.shape)
    for k, i in zip(*np.nonzero(np.isfinite(tau)), strict=True):
        s = tau[k, i] / scenario.time_step
        R = R_WB[k] if s == 0.0 else interpolate_attitude(R_WB[k], R_WB[k + 1], s)
        q_s[k, i] = R @ b
    J = range_attitude_jacobian(p_TS, q_s)
    return noise + J @ Sigma @ np.swapaxes(J, -1, -2)


def rms_norm(values: np.ndarray) -> float:
    """``√(mean over rows of |row|²)``."""
    return float(np.sqrt(np.mean(np.sum(values * values, axis=-1))))


def run_metrics(log: dict[str, np.ndarray], scenario: Scenario) -> dict[str, float]:
    """Steady-state metrics over k ≥ ``scenario.steady_state_start``.

    - ``position_rmse``, ``velocity_rmse``: RMS of |true − filtered| relative position [m] and
      velocity [m/s]; ``tracking_rmse``: RMS of |q − R q*| [m]; ``nees_mean``: mean NEES (≈ 6
      for a consistent filter); ``final_position_error``: |position error| at the last step.
    - ``relative_speed_mean``/``_peak``: mean and largest |ϑ| = |v − v̄|, the true relative
      speed [m/s]; ``acceleration_mean``/``_peak``: mean and largest |R u1|, the commanded
      (after any limit, i.e. applied) world acceleration [m/s²]. These measure what the
      tracking law asks of the vehicle.
    - ``model_acceleration_rmse``: RMS of |(v(k+1) − v(k))/t − R u1(k)| [m/s²], how far the
      vehicle's motion is from the commanded acceleration that the filter takes as known
      (0 for the paper's kinematic vehicle).
    - How the attitude moved and excited the baseline: :func:`attitude_metrics`.
    - For a vehicle that logs its attitude target and thrusts (``!HoveringAuv``):
      :func:`vehicle_metrics`.
    - ``pcrlb_position_rmse``, ``pcrlb_velocity_rmse``: √(mean over the window of the trace
      of the position/velocity block) of the PCRLB along this run's true trajectory, and
      ``kf_riccati_position_rmse``, ``kf_riccati_velocity_rmse`` the same of the paper's KF's
      Riccati covariance (:func:`bound_covariances`): compare with the RMSEs. With
      navigation errors or sonar timing (:func:`bound_errors_on`) the PCRLB is the extended
      bound (:func:`extended_bound`), and ``pcrlb_floor_position_rmse``,
      ``pcrlb_floor_velocity_rmse`` are its floors' part (√ mean of the floors' traces):
      the error the biases leave whatever the ranges' number and noise.
    """
    e = errors(log, scenario)
    window = slice(scenario.steady_state_start, None)
    speed = np.linalg.norm(e["relative_velocity"][window], axis=1)
    acceleration = np.linalg.norm(log["u1_W"][window], axis=1)
    return {
        "position_rmse": rms_norm(e["position"][window]),
        "velocity_rmse": rms_norm(e["velocity"][window]),
        "tracking_rmse": rms_norm(e["tracking"][window]),
        "nees_mean": float(np.mean(e["nees"][window])),
        "final_position_error": float(np.linalg.norm(e["position"][-1])),
        "relative_speed_mean": float(np.mean(speed)),
        "relative_speed_peak": float(np.max(speed)),
        "acceleration_mean": float(np.mean(acceleration)),
        "acceleration_peak": float(np.max(acceleration)),
        "model_acceleration_rmse": model_acceleration_rmse(log, scenario),
        **attitude_metrics(log, scenario),
        **vehicle_metrics(log, scenario),
        **bound_metrics(log, scenario),
    }


def attitude_metrics(log: dict[str, np.ndarray], scenario: Scenario) -> dict[str, float]:
    """Rotation per step, excitation and reference acceleration over the whole run.

    - ``rotation_mean``, ``rotation_peak`` [rad]: the angle of ``R(k+1) R(k)ᵀ`` over
      k = 0..N−2 (a rotation budget applies from the first step, so no window).
    - ``excitation_min`` [m²]: the smallest eigenvalue of ``Σ q_s q_sᵀ`` over every window
      of ``analysis.pe_window`` steps (paper eq. 10), the minimum over the run.
    - ``reference_acceleration_mean``, ``reference_acceleration_peak`` [m/s²]:
      ``|r(k+1) − 2 r(k) + r(k−1)| / t²`` of the desired relative position ``r = R_WF q*``,
      the acceleration that following it exactly asks of the vehicle.
    """
    R = log["R_WB"]
    angles = rotation_angles(R)
    low, _ = excitation_eigenvalues(log["b_W"], scenario.analysis.pe_window)
    t = scenario.tracking
    reference = desired_relative_positions(R, t.desired_relative_position, t.reference_frame)
    second = reference[2:] - 2.0 * reference[1:-1] + reference[:-2]
    acceleration = np.linalg.norm(second, axis=1) / scenario.time_step**2
    nan = float("nan")
    return {
        "rotation_mean": float(np.mean(angles)) if len(angles) else nan,
        "rotation_peak": float(np.max(angles)) if len(angles) else nan,
        "excitation_min": float(np.min(low)) if len(low) else nan,
        "reference_acceleration_mean": float(np.mean(acceleration)) if len(acceleration) else nan,
        "reference_acceleration_peak": float(np.max(acceleration)) if len(acceleration) else nan,
    }


def model_acceleration_rmse(log: dict[str, np.ndarray], scenario: Scenario) -> float:
    """RMS over the window of |(v(k+1) − v(k))/t − u1_W(k)| [m/s²] (see :func:`run_metrics`)."""
    start = scenario.steady_state_start
    achieved = np.diff(log["v_WU"][start:], axis=0) / scenario.time_step
    return rms_norm(achieved - log["u1_W"][start:-1]) if len(achieved) else 0.0


def vehicle_metrics(log: dict[str, np.ndarray], scenario: Scenario) -> dict[str, float]:
    """What the outer loop's commands cost a vehicle that logs its attitude target
    (``R_WB_command``), achieved rate (``w_WB``) and saturation counts (``saturation_ticks``),
    over the steady-state window; empty for a vehicle that logs none of them.

    - ``attitude_error_mean``/``_peak`` [rad]: |Log(R_cmd R_WBᵀ)| at the outer ticks, the
      attitude reached against the one commanded for that tick.
    - ``angular_rate_mean``/``_peak`` [rad/s]: |ω_WB| reached; ``angular_rate_error_mean``:
      mean |ω_WB − u2| at the ticks.
    - ``thrust_saturated_fraction``: the fraction of the controller's ticks whose wrench the
      thrust allocation scaled down (some thruster at its limit), force or moment.
    """
    if "R_WB_command" not in log:
        return {}
    start = scenario.steady_state_start
    R, R_cmd = log["R_WB"][start:], log["R_WB_command"][start:]
    # The rotation angle of R_cmd Rᵀ from its trace, clipped for rounding.
    cos_angle = 0.5 * (np.einsum("kij,kij->k", R_cmd, R) - 1.0)
    error = np.arccos(np.clip(cos_angle, -1.0, 1.0))
    rate = np.linalg.norm(log["w_WB"][start:], axis=1)
    out = {
        "attitude_error_mean": float(np.mean(error)),
        "attitude_error_peak": float(np.max(error)),
        "angular_rate_mean": float(np.mean(rate)),
        "angular_rate_peak": float(np.max(rate)),
        "angular_rate_error_mean": float(
            np.mean(np.linalg.norm(log["w_WB"][start:] - log["w_WB_command"][start:], axis=1))
        ),
    }
    if "saturation_ticks" in log:
        ticks, _, _, either = log["saturation_ticks"][-1] - log["saturation_ticks"][start]
        out["thrust_saturated_fraction"] = float(either / max(ticks, 1.0))
    return out


def bound_metrics(log: dict[str, np.ndarray], scenario: Scenario) -> dict[str, float]:
    """The steady-state RMSEs of :func:`bound_covariances` (see :func:`run_metrics`):
    ``<name>_position_rmse`` and ``<name>_velocity_rmse`` for each of its covariances."""
    out: dict[str, float] = {}
    with np.errstate(all="ignore"):
        for name, covs in bound_covariances(log, scenario).items():
            position, velocity = bound_rmse(covs, scenario.steady_state_start)
            out[f"{name}_position_rmse"] = position
            out[f"{name}_velocity_rmse"] = velocity
    return out
