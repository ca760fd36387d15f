"""An attitude planner that makes the next sonar measurements most informative.

The paper closes by promising to turn the UUV "based on the target's motion to maximize
observability"; its Algorithms 1 and 2 move the sonar baseline blindly. This module scores a
candidate next attitude ``R(k+1)`` by what the next measurement(s) would tell the filter,
and picks the best one that a rotation budget allows.

The candidates are :mod:`drake_uuv.models.attitude_candidates`'s, the information of a
measurement and the criteria :mod:`drake_uuv.models.information`'s.

The relative position the measurements are scored at
----------------------------------------------------
Both measurement models need a relative position at k+1. The filter's own prediction
``A x̂ + B u1_W`` is out of reach: ``u1_W`` comes from a tracking law that reads this planner's
plan (an algebraic loop). ``position_prediction``:

* ``"hold"`` (default): ``q̂(k|k)``: a tracking law holds the relative position;
* ``"coast"``: ``q̂ + j t ϑ̂``, without the control that cancels ``ϑ̂`` (the paper's law drives
  relative speeds of tens of m/s, so this can be metres off);
* ``"reference"``: the tracking reference at the candidate's attitude,
  ``R(k+j−reference_lag) q*``: ``reference_lag = 0`` for a law that lands on the next
  reference (the LQR law with the plan's feed-forward), 1 for the paper's law, whose
  ``u1(k)`` aims at ``R(k) q*``. With a lag the first measurement does not see the
  candidate, so the horizon scored is at least ``1 + reference_lag``.

The covariance needs no control at all.

Horizon
-------
Over ``horizon = H`` steps the covariance is propagated with the known model
(``P ← A P Aᵀ + Q``, ``Q = B W Bᵀ``) and updated with the measurement each step would give.
A candidate is a motion primitive: its first step's rotation, repeated
(``R(k+j) = Exp(j φ) R(k)``, each step within the budget). The score is the sum of the
criterion over the H posteriors; ``H = 1`` is the greedy choice. For the KF, longer horizons
did not help in the Riccati loop (0.429 m at H = 1, 0.432–0.464 m at H = 2–8 with
A-optimality at 0.39 rad), nor did a greedy rollout as the horizon's base policy.

Persistent excitation
---------------------
The excitation Gramian ``Λ(k) = Σ_{m=k−N+1}^{k} q_s(m) q_s(m)ᵀ`` (paper eq. 10) must stay
positive definite for the KF to be observable. Greedy information seeking does not keep a
floor on it by itself: an unmeasured direction's variance grows until the planner turns
back to it, but within a window it may not. At 0.1 rad per step the smallest eigenvalue over
windows of 24 fell to 0.78 m² (A-optimal) and 0.089 m² (E-optimal) in the Riccati loop, and to
0.10–0.12 m² for every criterion on random estimates. The planner therefore keeps a floor,
``excitation_floor`` (default 1 m², i.e. ``N |b|² / 48``, a sixteenth of the isotropic
``N |b|² / 3``): a candidate is admissible only when the trailing window ending with it, of
``N − pe_lead`` steps, has ``λ_min ≥`` the floor (a window not yet full, at the start, its
share of it). The shorter window meets a shortfall ``pe_lead`` steps before a full one would
suffer it: turning the baseline a quarter-turn takes 16 steps at 0.1 rad. When no candidate
is admissible the planner turns toward the least excited direction, maximising
``x_cᵀ (Λ + εI)⁻¹ x_c``. So the first steps explore: while the window holds a few baselines
close together its Gramian is nearly singular and no candidate meets even its share. With
``pe_lead = 6`` the floor held in every window of 20 runs of 600 steps on random estimates
at every budget from 0.1 to π/2 (smallest 1.11 m²); with ``pe_lead = 2`` it did not
(0.52 m² at 0.1 rad). Below 0.1 rad per step it is not promised.

Reference feasibility
---------------------
The tracking reference ``r = R q*`` turns with the body, so a rotation of angle θ moves it by
up to ``|q*| θ`` and its second difference, the acceleration a tracking law needs to follow
it exactly, is at most ``|q*| (θ(k) + θ(k−1)) / t²``: 8.8 m/s² at 0.39 rad per step for the
paper's ``|q*| = 2.83 m``, ``t = 0.5 s``, above a 7 m/s² limit, so feasibility is not automatic.
With ``max_reference_acceleration`` a candidate is admissible only if
``|R(k+1) q* − 2 R(k) q* + R(k−1) q*| / t² ≤`` that limit (if none is, the one needing the
least is taken); this also bounds the feed-forward ``a_ff`` of the LQR law, built from the
same differences of its plan. The limit takes precedence over the excitation floor.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from drake_uuv.models.attitude_candidates import (
    ball_rotations,
    cap_directions,
    frame_about,
    minimal_rotation_vectors,
    rotate_vectors,
)
from drake_uuv.models.information import (
    BLOCKS,
    CRITERIA,
    MEASUREMENT_MODELS,
    POSITION_PREDICTIONS,
    criterion_values,
    posterior_covariances,
    range_difference_rows,
    range_rows,
    smallest_excitation_eigenvalues,
)
from drake_uuv.models.motion import double_integrator, process_noise_covariance
from drake_uuv.models.so3 import exp_so3


@dataclass(frozen=True)
class PlanStep:
    """One planning step: the chosen rotation and what it was chosen on.

    ``rotation_vector`` is ``Log(R(k+1) R(k)ᵀ)``; ``R_next`` is ``R(k+1)``; ``baseline`` the
    world baseline ``R(k+1) b``; ``P_next`` the planner's ``P(k+1|k+1)`` for that choice;
    ``score`` its criterion; ``excitation`` the smallest eigenvalue of the trailing planning
    window ending with it (NaN without a floor); ``reference_acceleration``
    ``|Δ² (R q*)| / t²`` (NaN without a reference limit or before two attitudes are known).
    """

    rotation_vector: np.ndarray
    R_next: np.ndarray
    baseline: np.ndarray
    P_next: np.ndarray
    score: float
    excitation: float
    reference_acceleration: float


class InformationSeekingPlanner:
    """Chooses the next attitude ``R(k+1)`` that makes the next measurements most informative.

    See the module notes for the model, the criteria, the horizon, the excitation floor and
    the reference limit. :meth:`plan` is a pure function of its arguments: the same inputs
    give the same choice.

    Parameters: ``time_step`` t [s]; ``baseline_B`` b (3) [m]; ``acceleration_covariance`` W
    (3×3) of the target [m²/s⁴]; ``noise_variances`` η (2) [m²]; ``samples_per_step`` f;
    ``measurement_model`` (``range_difference`` for the paper's KF, ``ranges`` for the
    raw-range filters); ``criterion``; ``block``; ``horizon`` H ≥ 1; ``max_angle_per_step``
    [rad]; ``pe_window`` N; ``excitation_floor`` [m²] (0 switches the floor off);
    ``pe_lead`` (the floor is enforced on the trailing ``N − pe_lead`` steps);
    ``desired_relative_position`` q* (3, body frame) and ``max_reference_acceleration``
    [m/s²] (None: no limit); ``position_prediction`` and ``reference_lag`` (0 or 1);
    ``linear_start_position_variance`` [m²], the raw-range filter's hand-over threshold (None:
    it has no linear start; ignored for ``range_difference``);
    ``grid_rings`` of the cap grid and ``ball_rings`` of the ball grid.
    ``max_angle_per_step`` defaults to 0.39 rad, about Algorithm 2's mean rotation per step
    in the paper scenario (0.381 rad over 500 steps).
    """

    def __init__(
        self,
        time_step: float,
        baseline_B: np.ndarray,
        acceleration_covariance: np.ndarray,
        noise_variances: np.ndarray,
        samples_per_step: int = 1,
        measurement_model: str = "range_difference",
        criterion: str = "a_optimal",
        block: str = "position",
        horizon: int = 1,
        max_angle_per_step: float = 0.39,
        pe_window: int = 24,
        excitation_floor: float = 1.0,
        pe_lead: int = 6,
        desired_relative_position: np.ndarray | None = None,
        max_reference_acceleration: float | None = None,
        position_prediction: str = "hold",
        reference_lag: int = 0,
        linear_start_position_variance: float | None = None,
        grid_rings: int = 6,
        ball_rings: int = 4,
    ) -> None:
        b, W, eta = _checked_model(
            time_step, baseline_B, acceleration_covariance, noise_variances, samples_per_step
        )
        _check_search(
            measurement_model=measurement_model,
            criterion=criterion,
            block=block,
            position_prediction=position_prediction,
            horizon=horizon,
            max_angle_per_step=max_angle_per_step,
            pe_window=pe_window,
            excitation_floor=excitation_floor,
            pe_lead=pe_lead,
            reference_lag=reference_lag,
            grid_rings=grid_rings,
            ball_rings=ball_rings,
        )
        _check_reference(
            desired_relative_position=desired_relative_position,
            max_reference_acceleration=max_reference_acceleration,
            position_prediction=position_prediction,
            linear_start_position_variance=linear_start_position_variance,
        )

        self.time_step = float(time_step)
        self.baseline_B = b
        self.baseline_norm = float(np.linalg.norm(b))
        self.noise_variances = eta
        self.samples_per_step = int(samples_per_step)
        self.measurement_model = measurement_model
        self.criterion = criterion
        self.block = block
        self.horizon = int(horizon)
        self.max_angle_per_step = float(max_angle_per_step)
        # Any baseline line is within π/2 of ±u0 (module notes): a larger cap repeats lines.
        self.cap_angle = min(self.max_angle_per_step, 0.5 * math.pi)
        self.pe_window = int(pe_window)
        self.excitation_floor = float(excitation_floor)
        self.pe_lead = int(pe_lead)
        q_star = desired_relative_position
        self.q_star = None if q_star is None else np.asarray(q_star, dtype=float)
        self.max_reference_acceleration = max_reference_acceleration
        self.position_prediction = position_prediction
        self.reference_lag = int(reference_lag)
        self.linear_start_position_variance = (
            None
            if measurement_model != "ranges" or linear_start_position_variance is None
            else float(linear_start_position_variance)
        )
        self.grid_rings = int(grid_rings)
        self.ball_rings = int(ball_rings)
        self._precompute(W)

    def _precompute(self, W: np.ndarray) -> None:
        """What every step uses: the scored horizon, the model's A and Q, the candidates."""
        # With a lagged reference the first measurement does not see the candidate's twist.
        self.scored_horizon = (
            max(self.horizon, 1 + self.reference_lag)
            if self.position_prediction == "reference"
            else self.horizon
        )
        self.A, _ = double_integrator(self.time_step)
        self.Q = process_noise_covariance(W, self.time_step)
        # The candidate grids, computed once: the cap about +z (turned onto the baseline's
        # direction each step: rotation vectors turn as vectors) and the ball.
        z = np.array([0.0, 0.0, 1.0])
        self._cap_rotations_z = minimal_rotation_vectors(
            z, cap_directions(z, self.cap_angle, self.grid_rings)
        )
        self._ball = ball_rotations(self.max_angle_per_step, self.ball_rings)

    @property
    def history_length(self) -> int:
        """How many past baselines (before the current one) :meth:`plan` uses: ``N − 2``."""
        return self.pe_window - 2

    def predict_covariance(self, P: np.ndarray) -> np.ndarray:
        """``A P Aᵀ + Q`` (one or a stack of 6×6)."""
        return np.matmul(np.matmul(self.A, P), self.A.T) + self.Q

    def measurement_rows(
        self, q: np.ndarray, baselines: np.ndarray, linear_start: bool = False
    ) -> tuple[np.ndarray, np.ndarray]:
        """``(H, R)`` of the planned-for measurement model at position ``q`` per baseline.

        ``linear_start``: the raw-range filter's start, the paper's ``Y`` formed from the
        per-sonar sample means (noise variances ``η/f``).
        """
        if self.measurement_model == "range_difference":
            return range_difference_rows(q, baselines, self.noise_variances)
        if linear_start:
            return range_difference_rows(q, baselines, self.noise_variances / self.samples_per_step)
        return range_rows(q, baselines, self.noise_variances, self.samples_per_step)

    def hands_over(self, P: np.ndarray) -> bool:
        """Whether a raw-range filter whose filtered covariance is ``P`` leaves its linear
        start (``trace P_qq ≤ linear_start_position_variance``), as its hand-over policy does."""
        threshold = self.linear_start_position_variance
        return threshold is None or float(np.trace(np.asarray(P)[:3, :3])) <= threshold

    def predicted_positions(
        self, j: int, x_hat: np.ndarray, rotation: np.ndarray, R_WB: np.ndarray
    ) -> np.ndarray:
        """The relative position assumed at step k+j for each candidate (n×3 or 3).

        ``rotation`` (n×3) holds the candidates' per-step rotation vectors, ``R_WB`` is
        ``R(k)``. See :attr:`position_prediction` in the module notes.
        """
        if self.position_prediction == "hold":
            return x_hat[:3]
        if self.position_prediction == "coast":
            return x_hat[:3] + j * self.time_step * x_hat[3:]
        steps = max(j - self.reference_lag, 0)
        return rotate_vectors(steps * rotation, R_WB @ self.q_star)

    def candidate_rotations(self, R_WB: np.ndarray) -> np.ndarray:
        """The candidate rotation vectors ``Log(R(k+1) R(k)ᵀ)`` (n×3, the zero vector first).

        With ``position_prediction="reference"`` the target's assumed position ``R q*`` turns
        with the whole body, so every rotation within the budget is a candidate
        (:func:`ball_rotations`); otherwise only the baseline's direction matters and the
        cheapest rotation to each direction of the cap is the minimal one.
        """
        if self.position_prediction == "reference":
            return self._ball
        return self._cap_rotations_z @ frame_about(R_WB @ self.baseline_B / self.baseline_norm).T

    def horizon_scores(
        self,
        x_hat: np.ndarray,
        P: np.ndarray,
        R_WB: np.ndarray,
        rotation: np.ndarray,
        linear_start: bool = False,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Summed criterion over the horizon, and ``P(k+1|k+1)``, for each candidate.

        ``x_hat``, ``P`` are the filtered ``x̂(k|k)``, ``P(k|k)``; ``R_WB`` is ``R(k)``;
        ``rotation`` (n×3) the candidates' rotation vectors, each repeated every step of the
        horizon (``R(k+j) = Exp(j φ) R(k)``); ``linear_start`` as in :meth:`measurement_rows`,
        for the whole horizon.
        """
        baseline = R_WB @ self.baseline_B
        x_hat = np.asarray(x_hat, dtype=float)
        scores = np.zeros(len(rotation))
        posterior = np.asarray(P, dtype=float)
        first = posterior
        for j in range(1, self.scored_horizon + 1):
            q = self.predicted_positions(j, x_hat, rotation, R_WB)
            H, R = self.measurement_rows(q, rotate_vectors(j * rotation, baseline), linear_start)
            posterior = posterior_covariances(self.predict_covariance(posterior), H, R)
            if j == 1:
                first = posterior
            scores += criterion_values(posterior, self.criterion, self.block)
        return scores, first

    def plan(
        self,
        x_hat: np.ndarray,
        P: np.ndarray,
        R_WB: np.ndarray,
        previous_baselines: np.ndarray,
        R_previous: np.ndarray | None = None,
        linear_start: bool = False,
    ) -> PlanStep:
        """The next attitude from the filtered estimate at step k.

        ``x_hat`` (6) and ``P`` (6×6) are ``x̂(k|k)``, ``P(k|k)``; ``R_WB`` is ``R(k)``;
        ``previous_baselines`` (m×3, oldest first, at most :attr:`history_length` used) are the
        world baselines ``q_s`` of the steps before k; ``R_previous`` is ``R(k−1)`` (None at
        the first step), used only for the reference limit; ``linear_start`` says that the
        raw-range filter's next update is still its linear start's (see :meth:`hands_over`).
        """
        R_WB = np.asarray(R_WB, dtype=float).reshape(3, 3)
        baseline = R_WB @ self.baseline_B
        rotation = self.candidate_rotations(R_WB)
        baselines = rotate_vectors(rotation, baseline)
        scores, posteriors = self.horizon_scores(x_hat, P, R_WB, rotation, linear_start)
        admissible = np.ones(len(rotation), dtype=bool)
        objective = scores

        reference_acceleration = np.full(len(rotation), np.nan)
        if self.max_reference_acceleration is not None and R_previous is not None:
            r_now = R_WB @ self.q_star
            r_previous = np.asarray(R_previous, dtype=float).reshape(3, 3) @ self.q_star
            second_difference = rotate_vectors(rotation, r_now) - 2.0 * r_now + r_previous
            reference_acceleration = np.linalg.norm(second_difference, axis=1) / self.time_step**2
            admissible = reference_acceleration <= self.max_reference_acceleration
            if not admissible.any():  # the least demanding candidate
                admissible = reference_acceleration <= reference_acceleration.min()

        excitation = np.full(len(rotation), np.nan)
        if self.excitation_floor > 0.0:
            history = np.asarray(previous_baselines, dtype=float).reshape(-1, 3)
            window = self.pe_window - self.pe_lead  # steps of the trailing planning window
            recent = history[max(len(history) - (window - 2), 0) :]
            # A window not yet full must hold its share of the floor, so that the first full
            # windows (which include the start) meet it too.
            required = self.excitation_floor * min((len(recent) + 2) / window, 1.0)
            gramian = recent.T @ recent + np.outer(baseline, baseline)
            excitation = smallest_excitation_eigenvalues(gramian, baselines)
            enough = admissible & (excitation >= required)
            if enough.any():
                admissible = enough
            else:
                # Turn toward the least excited direction: the most novel baseline in the
                # Gramian's metric, x_cᵀ (Λ + εI)⁻¹ x_c, defined (unlike λ_min, which is 0 for
                # every candidate while Λ has rank 1) from the first step on.
                epsilon = 1e-3 * self.baseline_norm**2
                weighted = np.linalg.solve(gramian + epsilon * np.eye(3), baselines.T).T
                objective = np.einsum("ij,ij->i", baselines, weighted)

        index = int(np.flatnonzero(admissible)[np.argmax(objective[admissible])])
        R_next = exp_so3(rotation[index]) @ R_WB
        return PlanStep(
            rotation_vector=rotation[index].copy(),
            R_next=R_next,
            baseline=R_next @ self.baseline_B,
            P_next=posteriors[index],
            score=float(scores[index]),
            excitation=float(excitation[index]),
            reference_acceleration=float(reference_acceleration[index]),
        )


def _checked_model(
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


def _check_search(
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


def _check_reference(
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
