"""The information-seeking planner's argument checks (one-line errors naming the argument).

:class:`~drake_uuv.models.information_planner.InformationSeekingPlanner` checks its model
(:func:`checked_model`), its search (:func:`check_search`) and the tracking reference and
linear start it plans for (:func:`check_reference`) before it keeps them.
"""

import math

import numpy as np

from drake_uuv.models.information import BLOCKS, CRITERIA, MEASUREMENT_MODELS, POSITION_PREDICTIONS


def checked_model(
    time_step: float,
    baseline_B: np.ndarray,
    acceleration_covariance: np.ndarray,
    noise_variances: np.ndarray,
    samples_per_step: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(b, W, η)`` as float arrays, after checking the planner's model arguments."""
    if not (math.isfinite(time_step) and time_step > 0.0):
        raise ValueError(f"time_step: must be > 0, got {time_step!r}")
    b = np.asarray(baseline_B, dtype=float)
    if b.shape != (3,) or not np.all(np.isfinite(b)) or np.linalg.norm(b) < 1e-9:
        raise ValueError(f"baseline_B: must be a finite non-zero 3-vector, got {baseline_B!r}")
    W = np.asarray(acceleration_covariance, dtype=float)
    if W.shape != (3, 3) or not np.all(np.isfinite(W)):
        raise ValueError(
            f"acceleration_covariance: must be a finite 3×3 matrix, got {W.tolist()!r}"
        )
    eta = np.asarray(noise_variances, dtype=float)
    if eta.shape != (2,) or not np.all(eta > 0.0) or not np.all(np.isfinite(eta)):
        raise ValueError(f"noise_variances: must be two numbers > 0, got {noise_variances!r}")
    if int(samples_per_step) != samples_per_step or samples_per_step < 1:
        raise ValueError(f"samples_per_step: must be an integer ≥ 1, got {samples_per_step!r}")
    return b, W, eta


def check_search(
    *,
    measurement_model: str,
    criterion: str,
    block: str,
    position_prediction: str,
    horizon: int,
    max_angle_per_step: float,
    pe_window: int,
    excitation_floor: float,
    pe_lead: int,
    reference_lag: int,
    grid_rings: int,
    ball_rings: int,
) -> None:
    """Checks the arguments that shape the planner's search (choices, budget, floor, grids)."""
    for name, value, options in (
        ("measurement_model", measurement_model, MEASUREMENT_MODELS),
        ("criterion", criterion, CRITERIA),
        ("block", block, BLOCKS),
        ("position_prediction", position_prediction, POSITION_PREDICTIONS),
    ):
        if value not in options:
            raise ValueError(f"{name}: must be one of {', '.join(options)}, got {value!r}")
    if int(horizon) != horizon or horizon < 1:
        raise ValueError(f"horizon: must be an integer ≥ 1, got {horizon!r}")
    if not (math.isfinite(max_angle_per_step) and 0.0 < max_angle_per_step <= math.pi):
        raise ValueError(f"max_angle_per_step: must be in (0, π], got {max_angle_per_step!r}")
    if int(pe_window) != pe_window or pe_window < 3:
        raise ValueError(f"pe_window: must be an integer ≥ 3, got {pe_window!r}")
    if not (math.isfinite(excitation_floor) and excitation_floor >= 0.0):
        raise ValueError(f"excitation_floor: must be ≥ 0, got {excitation_floor!r}")
    if int(pe_lead) != pe_lead or not 0 <= pe_lead <= pe_window - 3:
        raise ValueError(f"pe_lead: must be an integer in [0, pe_window − 3], got {pe_lead!r}")
    if reference_lag not in (0, 1):
        raise ValueError(f"reference_lag: must be 0 or 1, got {reference_lag!r}")
    for name, value in (("grid_rings", grid_rings), ("ball_rings", ball_rings)):
        if int(value) != value or value < 1:
            raise ValueError(f"{name}: must be an integer ≥ 1, got {value!r}")


def check_reference(
    *,
    desired_relative_position: np.ndarray | None,
    max_reference_acceleration: float | None,
    position_prediction: str,
    linear_start_position_variance: float | None,
) -> None:
    """Checks the arguments about the tracking reference and the estimator's linear start."""
    if max_reference_acceleration is not None:
        if not (math.isfinite(max_reference_acceleration) and max_reference_acceleration > 0):
            raise ValueError(
                f"max_reference_acceleration: must be > 0 or None, got "
                f"{max_reference_acceleration!r}"
            )
        if desired_relative_position is None:
            raise ValueError(
                "desired_relative_position: needed with max_reference_acceleration, got None"
            )
    if desired_relative_position is not None:
        q_star = np.asarray(desired_relative_position, dtype=float)
        if q_star.shape != (3,) or not np.all(np.isfinite(q_star)):
            raise ValueError(
                "desired_relative_position: must be a finite 3-vector, got "
                f"{desired_relative_position!r}"
            )
    if position_prediction == "reference" and desired_relative_position is None:
        raise ValueError(
            "desired_relative_position: needed with position_prediction='reference', got None"
        )
    if linear_start_position_variance is not None and not (
        math.isfinite(linear_start_position_variance) and linear_start_position_variance > 0
    ):
        raise ValueError(
            "linear_start_position_variance: must be > 0 or None, got "
            f"{linear_start_position_variance!r}"
        )
