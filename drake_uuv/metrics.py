"""Error statistics of one run, computed from its log."""

import numpy as np

from drake_uuv.models.attitude_candidates import rotation_angles
from drake_uuv.models.information import excitation_eigenvalues
from drake_uuv.models.measurement import VALID, range_difference_noise
from drake_uuv.models.pcrlb import bound_rmse, measurement_information, pcrlb_recursion
from drake_uuv.models.tracking_laws import desired_relative_positions
from drake_uuv.scenario import Scenario


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
        "nees": np.einsum(
            "ki,ki->k", e, np.linalg.solve(log["P_TU"], e[:, :, np.newaxis])[:, :, 0]
        ),
        "relative_velocity": velocity,
    }


def run_information(log: dict[str, np.ndarray], scenario: Scenario) -> np.ndarray:
    """Fisher information ``M(k)`` (N×6×6) of the raw ranges, all f samples, on this run's true
    trajectory; a sonar without a return (``sonar_status`` not VALID) contributes nothing.

    Summed over runs it gives the Monte Carlo PCRLB (:func:`~drake_uuv.models.pcrlb.
    pcrlb_monte_carlo`, see :mod:`drake_uuv.studies.statistics`).
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
    return {"pcrlb": pcrlb, "kf_riccati": riccati}


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
      Riccati covariance (:func:`bound_covariances`): compare with the RMSEs.
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
    """The steady-state RMSEs of :func:`bound_covariances` (see :func:`run_metrics`)."""
    out: dict[str, float] = {}
    with np.errstate(all="ignore"):
        for name, covs in bound_covariances(log, scenario).items():
            position, velocity = bound_rmse(covs, scenario.steady_state_start)
            out[f"{name}_position_rmse"] = position
            out[f"{name}_velocity_rmse"] = velocity
    return out
