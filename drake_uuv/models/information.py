"""The information of the next sonar measurement for a candidate attitude, and its criteria.

What a planner assumes of the systems it plans for (:class:`EstimatorPlanningModel`,
:class:`TrackingPlanningModel`), the measurement rows of each model, the posterior
covariance they give and the criteria that score it; the planner on them is
:mod:`drake_uuv.models.information_planner`.

The information of one measurement
----------------------------------
* ``range_difference`` (the paper's KF, ``Y = ½(d1² − d2²) = q_sᵀ q + v̄``): one row
  ``C = [q_sᵀ, 0]`` with the noise variance ``Γ = η1 d1² + η2 d2² + ½(η1² + η2²)`` of the
  sonar's derived noise model (``range_difference_noise``), at the ranges the candidate
  baseline would have. With ``η1 = η2``, ``d1² + d2² = 2|q|² + ½|q_s|²`` does not depend on
  the direction, and the information is ``q_s q_sᵀ / Γ``.
* ``ranges`` (the raw-range EKF and IEKF): the two rows ``range_jacobian`` (unit lines of
  sight from each sonar) with ``R = diag(η/f)``. A baseline along the line of sight makes
  the two rows parallel (range only); one across it adds the bearing along the baseline.
  These filters start as the paper's KF on the sample means until ``trace P_qq`` falls to
  their hand-over threshold; the planner mirrors that from ``P_TU`` alone
  (``InformationSeekingPlanner.hands_over``) and plans for ``Y`` (variances ``η/f``)
  until then: planning for ranges during the start slowed it (it never ends when the KF's
  own covariance stays above the threshold, as at 0.1 rad per step).

Criteria (higher is better), on a block of the posterior covariance ``P⁺``
---------------------------------------------------------------------------
* ``d_optimal``: ``log det`` of the block's posterior information ``(P⁺_block)⁻¹``;
* ``a_optimal`` (default): ``−trace P⁺_block``;
* ``e_optimal``: the smallest eigenvalue of the block's information, ``1/λ_max(P⁺_block)``.

``block="position"`` (default) acts on ``P⁺_qq``: a measurement informs the position
directly (``C`` and the range Jacobians have no velocity columns) and the velocity through
positions over time, which the horizon's propagation sees; the team's measure is the
position RMSE, whose square a consistent filter predicts as ``trace P_qq``, so A-optimality
on this block is that measure itself; and the block has one unit (m²), which A and E need
(``block="full"`` mixes m² and m²/s²; only D is unit-free there). In the numpy Riccati loop
(paper scenario, KF, target held at ``R q*``, 500 steps, ``√mean trace P_qq`` over k ≥ 200)
A and D reach 0.56–0.58 m at 0.2 rad per step and 0.429 m at 0.39 (Algorithm 2: 0.589 m);
E-optimal, which chases the worst direction only, 1.10 m and 0.67 m.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from drake_uuv.models.measurement import MIN_RANGE, range_difference_noise


class PlannedMeasurement(StrEnum):
    """The measurement a planner scores: the paper's ``Y`` or the two raw ranges."""

    RANGE_DIFFERENCE = "range_difference"  # the paper's KF
    RANGES = "ranges"  # the raw-range filters (after their linear start)


@dataclass(frozen=True)
class EstimatorPlanningModel:
    """What a planner assumes of the estimator it plans for.

    ``measurement``: what the estimator updates with; ``linear_start_position_variance``
    [m²]: ``trace P_qq`` below which a raw-range filter is taken to have left its linear
    start (None: no linear start, or the paper's KF).
    """

    measurement: PlannedMeasurement = PlannedMeasurement.RANGE_DIFFERENCE
    linear_start_position_variance: float | None = None


@dataclass(frozen=True)
class TrackingPlanningModel:
    """What a planner assumes of the tracking law it plans for.

    ``desired_relative_position_B``: q* (3) [m] when it is fixed in the body frame, so that
    the reference ``R q*`` turns with the attitude the planner chooses (None: q* fixed in
    the world or the heading, which the attitude does not turn); ``reference_lag``: 0 for a
    law whose ``u1(k)`` lands on the next reference ``R(k+1) q*`` (the plan fed forward), 1
    for one that aims at ``R(k) q*``.
    """

    desired_relative_position_B: tuple[float, float, float] | None = None
    reference_lag: int = 1


MEASUREMENT_MODELS = tuple(m.value for m in PlannedMeasurement)
CRITERIA = ("d_optimal", "a_optimal", "e_optimal")
BLOCKS = ("position", "full")
POSITION_PREDICTIONS = ("hold", "coast", "reference")


def range_difference_rows(
    q: np.ndarray, baselines: np.ndarray, noise_variances: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``(H, R)`` of the paper's ``Y`` for each candidate world baseline (n×3).

    ``H`` is n×1×6 with rows ``[q_sᵀ, 0]``; ``R`` is n×1×1 holding ``Γ`` of the derived noise
    model at the true ranges ``|q ± ½ q_s|`` (``range_difference_noise`` estimates
    ``d̄²`` as ``mean(d²) − η``, so it is given ``d̄² + η``).
    """
    q = np.asarray(q, dtype=float)
    eta = np.asarray(noise_variances, dtype=float).reshape(2, 1)
    half = 0.5 * baselines
    squared = np.stack([np.sum((q + half) ** 2, axis=1), np.sum((q - half) ** 2, axis=1)])  # 2×n
    _, gamma = range_difference_noise("derived", eta, squared + eta)
    n = len(baselines)
    H = np.zeros((n, 1, 6))
    H[:, 0, :3] = baselines
    return H, np.asarray(gamma, dtype=float).reshape(n, 1, 1)


def range_rows(
    q: np.ndarray, baselines: np.ndarray, noise_variances: np.ndarray, samples_per_step: int
) -> tuple[np.ndarray, np.ndarray]:
    """``(H, R)`` of the two raw ranges for each candidate world baseline (n×3).

    ``H`` (n×2×6) is ``range_jacobian`` at position ``q`` for each baseline (unit vectors from
    each sonar to the target's negated position, zero velocity columns); ``R`` (n×2×2) is
    ``diag(η/f)``, the covariance of the per-sonar sample means.
    """
    q = np.asarray(q, dtype=float)
    half = 0.5 * baselines
    n = len(baselines)
    H = np.zeros((n, 2, 6))
    for row, r in enumerate((q + half, q - half)):
        H[:, row, :3] = r / np.maximum(np.linalg.norm(r, axis=1), MIN_RANGE)[:, np.newaxis]
    # The per-sonar mean of f samples has variance η/f.
    R = np.broadcast_to(
        np.diag(np.asarray(noise_variances, dtype=float) / samples_per_step), (n, 2, 2)
    )
    return H, R


def posterior_covariances(P: np.ndarray, H: np.ndarray, R: np.ndarray) -> np.ndarray:
    """``P − P Hᵀ (H P Hᵀ + R)⁻¹ H P`` for each candidate (P: 6×6 or n×6×6; H: n×r×6)."""
    PHt = np.matmul(P, np.transpose(H, (0, 2, 1)))  # n×6×r
    S = np.matmul(H, PHt) + R  # n×r×r
    if S.shape[1] == 1:
        gain = PHt / S  # n×6×1
    else:
        gain = np.transpose(np.linalg.solve(S, np.transpose(PHt, (0, 2, 1))), (0, 2, 1))
    posterior = P - np.matmul(gain, np.transpose(PHt, (0, 2, 1)))
    return 0.5 * (posterior + np.transpose(posterior, (0, 2, 1)))


def criterion_values(P: np.ndarray, criterion: str, block: str = "position") -> np.ndarray:
    """The criterion of each posterior covariance (n×6×6), higher is better (see the module)."""
    if block not in BLOCKS:
        raise ValueError(f"block: must be one of {', '.join(BLOCKS)}, got {block!r}")
    covariance = P[:, :3, :3] if block == "position" else P
    if criterion == "d_optimal":
        return -np.linalg.slogdet(covariance)[1]
    if criterion == "a_optimal":
        return -np.trace(covariance, axis1=1, axis2=2)
    if criterion == "e_optimal":
        return 1.0 / np.linalg.eigvalsh(covariance)[:, -1]
    raise ValueError(f"criterion: must be one of {', '.join(CRITERIA)}, got {criterion!r}")


def excitation_eigenvalues(q_s: np.ndarray, window: int) -> tuple[np.ndarray, np.ndarray]:
    """λ_min and λ_max of Λ(k) = Σ_{m=k}^{k+N−1} q_s(m) q_s(m)ᵀ for k = 0..len − N."""
    outer = q_s[:, :, np.newaxis] * q_s[:, np.newaxis, :]
    if window > len(q_s):
        return np.empty(0), np.empty(0)
    cumulative = np.concatenate([np.zeros((1, 3, 3)), np.cumsum(outer, axis=0)])
    sums = cumulative[window:] - cumulative[:-window]
    eigenvalues = np.linalg.eigvalsh(sums)
    return eigenvalues[:, 0], eigenvalues[:, -1]


def smallest_excitation_eigenvalues(gramian: np.ndarray, baselines: np.ndarray) -> np.ndarray:
    """``λ_min(Λ + q_s q_sᵀ)`` for a Gramian ``Λ`` (3×3) and each candidate baseline (n×3)."""
    total = gramian + baselines[:, :, np.newaxis] * baselines[:, np.newaxis, :]
    return np.linalg.eigvalsh(total)[:, 0]
