"""How much a run's attitude moved, and how well it excited the sonar baseline."""

import numpy as np

from drake_uuv.analysis.figures import excitation_eigenvalues
from drake_uuv.models.information import rotation_angles
from drake_uuv.scenario import Scenario


def attitude_metrics(log: dict[str, np.ndarray], scenario: Scenario) -> dict[str, float]:
    """Rotation per step, excitation and reference acceleration over the whole run.

    - ``rotation_mean``, ``rotation_peak`` [rad]: the angle of ``R(k+1) R(k)ᵀ`` over
      k = 0..N−2 (the rotation budget applies from the first step, so no window).
    - ``excitation_min`` [m²]: the smallest eigenvalue of ``Σ q_s q_sᵀ`` over every window
      of ``analysis.pe_window`` steps (paper eq. 10), the minimum over the run.
    - ``reference_acceleration_mean``, ``reference_acceleration_peak`` [m/s²]:
      ``|R(k+1) q* − 2 R(k) q* + R(k−1) q*| / t²``, the acceleration that following the
      turning reference ``R q*`` exactly asks of the vehicle.
    """
    R = log["R_WB"]
    angles = rotation_angles(R)
    low, _ = excitation_eigenvalues(log["q_s"], scenario.analysis.pe_window)
    reference = R @ np.asarray(scenario.tracking.desired_relative_position, dtype=float)
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
