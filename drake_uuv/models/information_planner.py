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

Constraints, the choice, a batch of runs
----------------------------------------
A candidate is admissible within a persistent-excitation floor and a reference-acceleration
limit, and the best admissible one by the score is taken (:mod:`drake_uuv.models.
information_choice` states both and why). :meth:`InformationSeekingPlanner.plan_runs` plans B
runs at once, each on its own whatever the others hold (its own candidates, scores, limit,
floor and fallback; a run holding NaN or inf neither raises nor changes the others), and
:meth:`~InformationSeekingPlanner.plan` one: numba kernels looping over runs and candidates,
:mod:`drake_uuv.models.information_scoring`'s, then :mod:`~drake_uuv.models.information_choice`'s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from drake_uuv.models.attitude_candidates import (
    ball_rotations,
    cap_directions,
    minimal_rotation_vectors,
    rotate_vectors,
)
from drake_uuv.models.information import (
    CRITERIA,
    MEASUREMENT_MODELS,
    POSITION_PREDICTIONS,
    range_difference_rows,
    range_rows,
)
from drake_uuv.models.information_choice import candidates_kernel, plan_kernel
from drake_uuv.models.information_planner_checks import (
    check_reference,
    check_search,
    checked_model,
)
from drake_uuv.models.information_scoring import scores_kernel
from drake_uuv.models.motion import double_integrator, process_noise_covariance


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


@dataclass(frozen=True)
class PlanSteps:
    """One planning step of each run of a batch: :class:`PlanStep`'s fields with a leading run
    axis (``rotation_vector`` (B, 3), ``R_next`` (B, 3, 3), ``baseline`` (B, 3), ``P_next``
    (B, 6, 6), ``score``, ``excitation``, ``reference_acceleration`` (B))."""

    rotation_vector: np.ndarray
    R_next: np.ndarray
    baseline: np.ndarray
    P_next: np.ndarray
    score: np.ndarray
    excitation: np.ndarray
    reference_acceleration: np.ndarray

    def run(self, i: int) -> PlanStep:
        """Run ``i``'s step."""
        return PlanStep(
            rotation_vector=self.rotation_vector[i],
            R_next=self.R_next[i],
            baseline=self.baseline[i],
            P_next=self.P_next[i],
            score=float(self.score[i]),
            excitation=float(self.excitation[i]),
            reference_acceleration=float(self.reference_acceleration[i]),
        )


class InformationSeekingPlanner:
    """Chooses the next attitude ``R(k+1)`` that makes the next measurements most informative.

    See the module notes for the model, the criteria and the horizon, and
    :mod:`~drake_uuv.models.information_choice`'s for the excitation floor and the reference
    limit. :meth:`plan_runs` (B runs) and :meth:`plan` (one) are pure functions of their
    arguments: the same inputs give the same choice, in any batch. The numpy methods
    :meth:`predict_covariance`, :meth:`measurement_rows` and :meth:`predicted_positions` state
    the planned-for model of one run; the planning itself is the kernels', which the tests
    check against them.

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
        b, W, eta = checked_model(
            time_step, baseline_B, acceleration_covariance, noise_variances, samples_per_step
        )
        check_search(
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
        check_reference(
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
        # The kernel's constants (see its option and parameter positions).
        reference = self.position_prediction == "reference"
        self._options = np.array(
            [
                MEASUREMENT_MODELS.index(self.measurement_model),
                CRITERIA.index(self.criterion),
                3 if self.block == "position" else 6,
                POSITION_PREDICTIONS.index(self.position_prediction),
                self.reference_lag,
                self.scored_horizon,
                self.pe_window - self.pe_lead,  # steps of the trailing planning window
                0 if reference else 1,
                0 if self.linear_start_position_variance is None else 1,
            ],
            dtype=np.int64,
        )
        eta_f = self.noise_variances / self.samples_per_step  # the per-sonar means of f samples
        limit = self.max_reference_acceleration
        self._parameters = np.array(
            [
                self.time_step,
                self.baseline_norm,
                *self.noise_variances,
                *eta_f,
                self.excitation_floor,
                math.inf if limit is None or self.q_star is None else float(limit),
                1e-3 * self.baseline_norm**2,  # ε of the least-excited direction's metric
                self.linear_start_position_variance or 0.0,
            ]
        )
        self._q_star = np.zeros(3) if self.q_star is None else self.q_star.copy()
        self._b = self.baseline_B.copy()  # writable, as every kernel argument
        self._candidates = np.ascontiguousarray(self._ball if reference else self._cap_rotations_z)

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
        return bool(self.hands_over_runs(np.asarray(P, dtype=float).reshape(1, 6, 6))[0])

    def hands_over_runs(self, P: np.ndarray) -> np.ndarray:
        """:meth:`hands_over` of each run's ``P`` (``(B, 6, 6)`` → ``(B,)`` bool)."""
        threshold = self.linear_start_position_variance
        if threshold is None:
            return np.ones(len(P), dtype=bool)
        return P[:, 0, 0] + P[:, 1, 1] + P[:, 2, 2] <= threshold

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
        return self.candidate_rotations_runs(np.asarray(R_WB, dtype=float).reshape(1, 3, 3))[0]

    def candidate_rotations_runs(self, R_WB: np.ndarray) -> np.ndarray:
        """:meth:`candidate_rotations` of each run's ``R(k)`` (``(B, 3, 3)`` → ``(B, n, 3)``)."""
        return candidates_kernel(
            self._options, self._parameters, self._b, self._candidates, _matrices(R_WB)
        )

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
        for the whole horizon. The kernel of :meth:`plan_runs`, for one run.
        """
        scores, posteriors = scores_kernel(
            self._options,
            self._parameters,
            self._b,
            self._q_star,
            self.Q,
            _vectors(x_hat, 6),
            _matrices(P, 6),
            _matrices(R_WB),
            np.require(rotation, float, "CW").reshape(1, -1, 3),
            np.array([1.0 if linear_start else 0.0]),
        )
        return scores[0], posteriors[0]

    def plan(
        self,
        x_hat: np.ndarray,
        P: np.ndarray,
        R_WB: np.ndarray,
        previous_baselines: np.ndarray,
        R_previous: np.ndarray | None = None,
        linear_start: bool = False,
    ) -> PlanStep:
        """The next attitude from the filtered estimate at step k (one run of
        :meth:`plan_runs`).

        ``x_hat`` (6) and ``P`` (6×6) are ``x̂(k|k)``, ``P(k|k)``; ``R_WB`` is ``R(k)``;
        ``previous_baselines`` (m×3, oldest first, at most :attr:`history_length` used) are the
        world baselines ``q_s`` of the steps before k; ``R_previous`` is ``R(k−1)`` (None at
        the first step), used only for the reference limit; ``linear_start`` says that the
        raw-range filter's next update is still its linear start's (see :meth:`hands_over`).
        """
        history = np.asarray(previous_baselines, dtype=float).reshape(1, -1, 3)
        known = R_previous is not None
        steps = self.plan_runs(
            x_hat,
            P,
            R_WB,
            history,
            np.array([float(history.shape[1])]),
            np.eye(3) if R_previous is None else R_previous,
            np.array([1.0 if known else 0.0]),
            np.array([1.0 if linear_start else 0.0]),
        )
        return steps.run(0)

    def plan_runs(
        self,
        x_hat: np.ndarray,
        P: np.ndarray,
        R_WB: np.ndarray,
        history: np.ndarray,
        filled: np.ndarray,
        R_previous: np.ndarray,
        has_previous: np.ndarray,
        linear_start: np.ndarray,
    ) -> PlanSteps:
        """The next attitude of each run of a batch, from its filtered estimate at step k.

        Per run (leading axis B; flat row-major vectors are reshaped): ``x_hat`` (6) and ``P``
        (6×6) are ``x̂(k|k)``, ``P(k|k)``; ``R_WB`` is ``R(k)``; ``history`` (m×3, oldest
        first) holds the world baselines ``q_s`` before k, of which the last ``filled`` are
        known; ``R_previous`` is ``R(k−1)``, used (for the reference limit) where
        ``has_previous > 0``; ``linear_start > 0`` where the raw-range filter's next update is
        still its linear start's. Each run is scored, constrained and chosen on its own (its
        own candidates, floor, limit and fallbacks): run i's step is the same, bit for bit,
        whatever the batch.
        """
        return self._plan(
            x_hat, P, R_WB, history, filled, R_previous, has_previous, linear_start, False
        )[0]

    def plan_pair_runs(
        self,
        x_hat: np.ndarray,
        P: np.ndarray,
        R_WB: np.ndarray,
        history: np.ndarray,
        filled: np.ndarray,
        R_previous: np.ndarray,
        has_previous: np.ndarray,
        linear_start: np.ndarray,
    ) -> tuple[PlanSteps, PlanSteps]:
        """:meth:`plan_runs` for step k, and the plan of step k+1 that follows it: the planner
        once more from each run's ``R(k+1)`` and its ``P(k+1|k+1)``, the history with
        ``q_s(k)`` appended, ``R(k)`` as ``R(k−1)``, ``x̂`` held (coasted with
        ``position_prediction="coast"``) and the linear start until ``P(k+1|k+1)`` hands over.
        """
        return self._plan(
            x_hat, P, R_WB, history, filled, R_previous, has_previous, linear_start, True
        )

    def _plan(
        self,
        x_hat: np.ndarray,
        P: np.ndarray,
        R_WB: np.ndarray,
        history: np.ndarray,
        filled: np.ndarray,
        R_previous: np.ndarray,
        has_previous: np.ndarray,
        linear_start: np.ndarray,
        both: bool,
    ) -> tuple[PlanSteps, ...]:
        R_WB = _matrices(R_WB)
        runs = len(R_WB)
        rotation, R_next, baseline, P_next, stats = plan_kernel(
            self._options,
            self._parameters,
            self._b,
            self._q_star,
            self.Q,
            self._candidates,
            _vectors(x_hat, 6),
            _matrices(P, 6),
            R_WB,
            np.require(history, float, "CW").reshape(runs, -1, 3),
            _vectors(filled, 1).reshape(runs),
            _matrices(R_previous),
            _vectors(has_previous, 1).reshape(runs),
            _vectors(linear_start, 1).reshape(runs),
            both,
        )
        return tuple(
            PlanSteps(rotation[s], R_next[s], baseline[s], P_next[s], *stats[s].T)
            for s in range(len(rotation))
        )


# The kernels get C-contiguous, writable float arrays whatever the caller holds (a state's
# read-only view, a list): one compiled signature for every caller.


def _matrices(M: np.ndarray, n: int = 3) -> np.ndarray:
    """One or a batch of n×n matrices as a C-contiguous float ``(B, n, n)`` array."""
    return np.require(M, float, "CW").reshape(-1, n, n)


def _vectors(v: np.ndarray, n: int) -> np.ndarray:
    """One or a batch of n-vectors as a C-contiguous float ``(B, n)`` array."""
    return np.require(v, float, "CW").reshape(-1, n)
