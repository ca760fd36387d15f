"""Error statistics of one run, computed from its log."""

import numpy as np

from drake_uuv.controllers.lqr_tracking_controller import closed_loop_eigenvalues
from drake_uuv.scenario import Scenario


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
    }
