"""Error statistics of one run, computed from its log."""

import numpy as np

from drake_uuv.controllers.lqr_tracking_controller import closed_loop_eigenvalues
from drake_uuv.estimators.pcrlb import bound_rmse, measurement_information, pcrlb_recursion
from drake_uuv.scenario import Scenario
from drake_uuv.sensors.dual_sonar import VALID, range_difference_noise


def errors(log: dict[str, np.ndarray], scenario: Scenario) -> dict[str, np.ndarray]:
    """Per-step errors: estimation (position, velocity), tracking, and NEES.

    - ``position``/``velocity`` (N×3): true minus filtered relative position/velocity.
    - ``tracking`` (N×3): ``q − R q*``, the offset from the desired relative position.
    - ``nees`` (N): ``eᵀ P⁻¹ e`` for the 6-D estimation error ``e``.
    """
    q = log["p_uuv"] - log["p_target"]
    velocity = log["v_uuv"] - log["v_target"]
    e = np.concatenate([q - log["q_hat"], velocity - log["v_hat"]], axis=1)
    q_star = np.asarray(scenario.tracking.desired_relative_position)
    return {
        "position": e[:, :3],
        "velocity": e[:, 3:],
        "tracking": q - log["R_WB"] @ q_star,
        "nees": np.einsum("ki,ki->k", e, np.linalg.solve(log["P"], e[:, :, np.newaxis])[:, :, 0]),
        "relative_velocity": velocity,
    }


def run_information(log: dict[str, np.ndarray], scenario: Scenario) -> np.ndarray:
    """Fisher information ``M(k)`` (N×6×6) of the raw ranges, all f samples, on this run's true
    trajectory; a sonar without a return (``sonar_status`` not VALID) contributes nothing.

    Summed over runs it gives the Monte Carlo PCRLB (:func:`~drake_uuv.estimators.pcrlb.
    pcrlb_monte_carlo`, see :mod:`drake_uuv.montecarlo`).
    """
    available = log["sonar_status"] == VALID if "sonar_status" in log else None
    return measurement_information(
        log["p_uuv"] - log["p_target"],
        log["q_s"],
        np.asarray(scenario.sonar.noise_variances, dtype=float),
        scenario.sonar.samples_per_step,
        available,
    )


def bound_covariances(log: dict[str, np.ndarray], scenario: Scenario) -> dict[str, np.ndarray]:
    """Two covariance bounds (N×6×6 each) along this run's true trajectory.

    - ``pcrlb``: the posterior Cramér–Rao bound of the raw two-range measurement (all f
      samples), prior ``P(0|−1)`` = ``estimator.initial_covariance``
      (:mod:`drake_uuv.estimators.pcrlb`). Per run it is the bound *given this trajectory*;
      the proven Monte Carlo bound averages the information over runs instead.
    - ``kf_riccati``: the paper's KF's Riccati covariance with the noise variance ``Γ`` of its
      ``Y`` (first sample of each sonar, the ``derived`` model) on the true ranges: the MSE of
      the paper's KF when its noise model is right, what it would reach on this trajectory.
    """
    e = scenario.estimator
    q = log["p_uuv"] - log["p_target"]
    eta = np.asarray(scenario.sonar.noise_variances, dtype=float)[:, np.newaxis]
    P0 = np.asarray(e.initial_covariance, dtype=float)
    W = np.asarray(scenario.target.acceleration_covariance, dtype=float)
    q_s = log["q_s"]
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
    - ``tracking_spectral_radius``: the largest |eigenvalue| of the tracking law's closed loop
      ``A − B K`` on the relative double integrator (< 1: the error dynamics are stable;
      the paper's law has 1, its undamped velocity mode). The same for every run of a scenario.
    - ``pcrlb_position_rmse``, ``pcrlb_velocity_rmse``: √(mean over the window of the trace
      of the position/velocity block) of the PCRLB along this run's true trajectory, and
      ``kf_riccati_position_rmse``, ``kf_riccati_velocity_rmse`` the same of the paper's KF's
      Riccati covariance (:func:`bound_covariances`): compare with the RMSEs.
    """
    e = errors(log, scenario)
    window = slice(scenario.steady_state_start, None)
    speed = np.linalg.norm(e["relative_velocity"][window], axis=1)
    acceleration = np.linalg.norm(log["a_world"][window], axis=1)
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
        "tracking_spectral_radius": float(np.max(np.abs(closed_loop_eigenvalues(scenario)))),
        **bound_metrics(log, scenario),
    }


def bound_metrics(log: dict[str, np.ndarray], scenario: Scenario) -> dict[str, float]:
    """The steady-state RMSEs of :func:`bound_covariances` (see :func:`run_metrics`)."""
    out: dict[str, float] = {}
    with np.errstate(all="ignore"):
        for name, covs in bound_covariances(log, scenario).items():
            position, velocity = bound_rmse(covs, scenario.steady_state_start)
            out[f"{name}_position_rmse"] = position
            out[f"{name}_velocity_rmse"] = velocity
    return out
