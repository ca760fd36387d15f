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

The choice
----------
The best admissible candidate by the score (or, under the floor's fallback, the novelty).
Candidates whose objectives differ by less than 1e-10 (relative) tie, and the first in grid
order is taken: at the first step the novelty is exactly equal around the cap's outer ring,
and rounding would otherwise choose.

A batch of runs
---------------
:meth:`InformationSeekingPlanner.plan_runs` plans B runs at once, each on its own: its own
candidates (the cap turns with its baseline), scores, reference limit, floor and fallback,
whatever the other runs hold; :meth:`~InformationSeekingPlanner.plan` is one run of it. The
work is one numba kernel looping over runs and candidates (scalar code on small buffers): at
one run numpy's cost per call dominated (dozens of calls on n×6×6 stacks per horizon step),
at a thousand its passes over (B, n, 6, 6) temporaries would. The covariance propagation is
written out for the double integrator ``A = [[I, tI], [0, I]]``; the 3×3 eigenvalues (the
excitation, E-optimality of the position block) are in closed form (Smith's), 6×6 ones by
cyclic Jacobi. A run holding NaN or inf neither raises nor changes the other runs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from drake_uuv.models.attitude_candidates import (
    ball_rotations,
    cap_directions,
    minimal_rotation_vectors,
    rotate_vectors,
)
from drake_uuv.models.attitude_plans import exp_so3_kernel, matmul3_kernel
from drake_uuv.models.information import (
    BLOCKS,
    CRITERIA,
    MEASUREMENT_MODELS,
    POSITION_PREDICTIONS,
    range_difference_rows,
    range_rows,
)
from drake_uuv.models.measurement import MIN_RANGE
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

    See the module notes for the model, the criteria, the horizon, the excitation floor and
    the reference limit. :meth:`plan_runs` (B runs) and :meth:`plan` (one) are pure
    functions of their arguments: the same inputs give the same choice, in any batch. The
    numpy methods :meth:`predict_covariance`, :meth:`measurement_rows` and
    :meth:`predicted_positions` state the planned-for model of one run; the planning itself is
    the kernel, which the tests check against them.

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
        return _candidates_kernel(
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
        scores, posteriors = _scores_kernel(
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
        rotation, R_next, baseline, P_next, stats = _plan_kernel(
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


# ------------------------------------------------------------------ the kernel (numba)
# One loop over runs, and in it over candidates: run i's numbers are the same whatever the
# batch. Scalar code on small stack-like buffers, because at one run numpy's cost per call
# (dozens of calls on n×6×6 stacks per horizon step) dominated the planner's step, and at a
# thousand runs its passes over (B, n, 6, 6) temporaries did. ``error_model="numpy"``: a run
# holding NaN or inf gives NaN (and some candidate), never an exception.

# Integer options (``_options``) and float parameters (``_parameters``) by position.
_MEASUREMENT, _CRITERION, _BLOCK, _PREDICTION, _LAG, _SCORED, _WINDOW, _CAP = range(8)
_THRESHOLD_SET = 8
_T, _NORM, _ETA, _ETA_F, _FLOOR, _MAX_REFERENCE, _EPSILON, _THRESHOLD = 0, 1, 2, 4, 6, 7, 8, 9
_RANGE_DIFFERENCE, _RANGES = 0, 1
_D_OPTIMAL, _A_OPTIMAL, _E_OPTIMAL = 0, 1, 2
_HOLD, _COAST, _REFERENCE = 0, 1, 2
_TINY = 1e-12  # attitude_candidates' guard of a zero rotation's axis
_TIE = 1e-10  # relative difference of two objectives below which they tie
_MIN_RANGE = MIN_RANGE


@njit(cache=True, error_model="numpy")
def _rotate(p0, p1, p2, v0, v1, v2):  # pragma: no cover - compiled
    """``Exp(φ) v`` (Rodrigues, as ``attitude_candidates.rotate_vectors``)."""
    angle = math.sqrt(p0 * p0 + p1 * p1 + p2 * p2)
    d = angle if angle > _TINY else _TINY
    a0, a1, a2 = p0 / d, p1 / d, p2 / d
    c, s = math.cos(angle), math.sin(angle)
    dot = a0 * v0 + a1 * v1 + a2 * v2
    k = 1.0 - c
    return (
        v0 * c + (a1 * v2 - a2 * v1) * s + a0 * dot * k,
        v1 * c + (a2 * v0 - a0 * v2) * s + a1 * dot * k,
        v2 * c + (a0 * v1 - a1 * v0) * s + a2 * dot * k,
    )


@njit(cache=True, error_model="numpy")
def _symmetric_eigen_3(a00, a01, a02, a11, a12, a22):  # pragma: no cover - compiled
    """Smallest and largest eigenvalue of a symmetric 3×3 (closed form, Smith 1961)."""
    p1 = a01 * a01 + a02 * a02 + a12 * a12
    q = (a00 + a11 + a22) / 3.0
    b00, b11, b22 = a00 - q, a11 - q, a22 - q
    p = math.sqrt((b00 * b00 + b11 * b11 + b22 * b22 + 2.0 * p1) / 6.0)
    if p == 0.0:
        return q, q
    c00, c11, c22 = b00 / p, b11 / p, b22 / p
    c01, c02, c12 = a01 / p, a02 / p, a12 / p
    r = 0.5 * (c00 * (c11 * c22 - c12 * c12) - c01 * (c01 * c22 - c12 * c02)
               + c02 * (c01 * c12 - c11 * c02))  # fmt: skip
    r = -1.0 if r < -1.0 else (1.0 if r > 1.0 else r)
    phi = math.acos(r) / 3.0
    return q + 2.0 * p * math.cos(phi + 2.0 * math.pi / 3.0), q + 2.0 * p * math.cos(phi)


@njit(cache=True, error_model="numpy")
def _largest_eigenvalue(M, n, work):  # pragma: no cover - compiled
    """Largest eigenvalue of the symmetric leading n×n block of M (cyclic Jacobi)."""
    for i in range(n):
        for j in range(n):
            work[i, j] = M[i, j]
    for _ in range(60):
        off = 0.0
        scale = 0.0
        for i in range(n):
            scale += work[i, i] * work[i, i]
            for j in range(i + 1, n):
                off += work[i, j] * work[i, j]
        if not off > 1e-30 * scale:  # converged (or NaN)
            break
        for p in range(n):
            for q in range(p + 1, n):
                apq = work[p, q]
                if apq == 0.0:
                    continue
                theta = (work[q, q] - work[p, p]) / (2.0 * apq)
                t = (1.0 if theta >= 0.0 else -1.0) / (abs(theta) + math.sqrt(theta * theta + 1.0))
                c = 1.0 / math.sqrt(t * t + 1.0)
                s = t * c
                for k in range(n):
                    akp, akq = work[k, p], work[k, q]
                    work[k, p], work[k, q] = c * akp - s * akq, s * akp + c * akq
                for k in range(n):
                    apk, aqk = work[p, k], work[q, k]
                    work[p, k], work[q, k] = c * apk - s * aqk, s * apk + c * aqk
    largest = work[0, 0]
    for i in range(1, n):
        if work[i, i] > largest or work[i, i] != work[i, i]:
            largest = work[i, i]
    return largest


@njit(cache=True, error_model="numpy")
def _criterion(P, criterion, n, work):  # pragma: no cover - compiled
    """The criterion of the leading n×n block of a covariance (higher is better)."""
    if criterion == _A_OPTIMAL:
        trace = P[0, 0]
        for i in range(1, n):
            trace += P[i, i]
        return -trace
    if criterion == _E_OPTIMAL:
        if n == 3:
            return 1.0 / _symmetric_eigen_3(P[0, 0], P[0, 1], P[0, 2], P[1, 1], P[1, 2], P[2, 2])[1]
        return 1.0 / _largest_eigenvalue(P, n, work)
    # D-optimal: −log|det|, by Gaussian elimination with partial pivoting (as slogdet).
    for i in range(n):
        for j in range(n):
            work[i, j] = P[i, j]
    log_det = 0.0
    for k in range(n):
        pivot = k
        for i in range(k + 1, n):
            if abs(work[i, k]) > abs(work[pivot, k]):
                pivot = i
        if pivot != k:
            for j in range(n):
                work[k, j], work[pivot, j] = work[pivot, j], work[k, j]
        log_det += math.log(abs(work[k, k]))
        for i in range(k + 1, n):
            factor = work[i, k] / work[k, k]
            for j in range(k + 1, n):
                work[i, j] -= factor * work[k, j]
    return -log_det


@njit(cache=True, error_model="numpy")
def _predict(P, t, Q, AP, out):  # pragma: no cover - compiled
    """``A P Aᵀ + Q`` for the double integrator ``A = [[I, tI], [0, I]]``, written out."""
    for i in range(6):
        for k in range(6):
            AP[i, k] = P[i, k] + t * P[i + 3, k] if i < 3 else P[i, k]
    for i in range(6):
        for k in range(6):
            out[i, k] = (AP[i, k] + t * AP[i, k + 3] if k < 3 else AP[i, k]) + Q[i, k]


@njit(cache=True, error_model="numpy")
def _update(prior, rows, r, noise, PHt, gain, out):  # pragma: no cover - compiled
    """``P − P Hᵀ (H P Hᵀ + R)⁻¹ H P``, symmetrised, for ``r`` rows ``H = [rows, 0]`` (the
    measurements see the position only) and ``R = diag(noise)``."""
    for i in range(6):
        for m in range(r):
            PHt[i, m] = (
                prior[i, 0] * rows[m, 0] + prior[i, 1] * rows[m, 1] + prior[i, 2] * rows[m, 2]
            )
    if r == 1:
        S = rows[0, 0] * PHt[0, 0] + rows[0, 1] * PHt[1, 0] + rows[0, 2] * PHt[2, 0] + noise[0]
        for i in range(6):
            gain[i, 0] = PHt[i, 0] / S
    else:
        S00 = rows[0, 0] * PHt[0, 0] + rows[0, 1] * PHt[1, 0] + rows[0, 2] * PHt[2, 0] + noise[0]
        S01 = rows[0, 0] * PHt[0, 1] + rows[0, 1] * PHt[1, 1] + rows[0, 2] * PHt[2, 1]
        S10 = rows[1, 0] * PHt[0, 0] + rows[1, 1] * PHt[1, 0] + rows[1, 2] * PHt[2, 0]
        S11 = rows[1, 0] * PHt[0, 1] + rows[1, 1] * PHt[1, 1] + rows[1, 2] * PHt[2, 1] + noise[1]
        det = S00 * S11 - S01 * S10
        for i in range(6):  # gain = (S⁻¹ (P Hᵀ)ᵀ)ᵀ
            gain[i, 0] = (S11 * PHt[i, 0] - S01 * PHt[i, 1]) / det
            gain[i, 1] = (S00 * PHt[i, 1] - S10 * PHt[i, 0]) / det
    for i in range(6):
        for k in range(i, 6):
            a = prior[i, k] - gain[i, 0] * PHt[k, 0]
            b = prior[k, i] - gain[k, 0] * PHt[i, 0]
            if r == 2:
                a -= gain[i, 1] * PHt[k, 1]
                b -= gain[k, 1] * PHt[i, 1]
            out[i, k] = out[k, i] = 0.5 * (a + b)


@njit(cache=True, error_model="numpy")
def _rows(q, q_s, ranges, eta, rows, noise):  # pragma: no cover - compiled
    """The planned-for measurement at position ``q`` and world baseline ``q_s``: the paper's
    ``Y`` (one row ``q_s``, variance Γ of the derived model at the true ranges) or the two
    ranges (unit lines of sight from each sonar, variances η); returns the row count."""
    h0, h1, h2 = 0.5 * q_s[0], 0.5 * q_s[1], 0.5 * q_s[2]
    if not ranges:
        rows[0, 0], rows[0, 1], rows[0, 2] = q_s[0], q_s[1], q_s[2]
        d0, d1, d2 = q[0] + h0, q[1] + h1, q[2] + h2
        true_0 = (d0 * d0 + d1 * d1 + d2 * d2 + eta[0]) - eta[0]  # as range_difference_noise
        d0, d1, d2 = q[0] - h0, q[1] - h1, q[2] - h2
        true_1 = (d0 * d0 + d1 * d1 + d2 * d2 + eta[1]) - eta[1]
        true_0 = 0.0 if true_0 < 0.0 else true_0
        true_1 = 0.0 if true_1 < 0.0 else true_1
        noise[0] = eta[0] * true_0 + eta[1] * true_1 + 0.5 * (eta[0] ** 2 + eta[1] ** 2)
        return 1
    for m in range(2):
        sign = 1.0 if m == 0 else -1.0
        d0, d1, d2 = q[0] + sign * h0, q[1] + sign * h1, q[2] + sign * h2
        length = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        length = length if length > _MIN_RANGE else _MIN_RANGE
        rows[m, 0], rows[m, 1], rows[m, 2] = d0 / length, d1 / length, d2 / length
        noise[m] = eta[m]
    return 2


@njit(cache=True, error_model="numpy")
def _score_candidates(
    options, parameters, Q, x, P, baseline, r_q, rotation, baselines, first, count, linear,
    scores, firsts, buffers,
):  # pragma: no cover - compiled  # fmt: skip
    """The criterion summed over the scored horizon of candidates ``first`` to
    ``first + count − 1`` of one run (each rotation repeated every step of the horizon;
    ``baselines`` their first steps' world baselines), into ``scores``; with ``firsts`` of
    ``count`` rows, their ``P(k+1|k+1)`` too."""
    t = parameters[_T]
    ranges = options[_MEASUREMENT] == _RANGES and not linear
    first_eta = _ETA if options[_MEASUREMENT] == _RANGE_DIFFERENCE else _ETA_F
    eta = parameters[first_eta : first_eta + 2]
    prediction, lag, block = options[_PREDICTION], options[_LAG], options[_BLOCK]
    first_prior, prior, posterior, AP, work = (
        buffers[0], buffers[1], buffers[2], buffers[3], buffers[4]
    )  # fmt: skip
    PHt, gain = buffers[5, :, :2], buffers[5, :, 2:4]
    rows, noise = buffers[6, :2, :3], buffers[6, 2, :2]
    q, q_s = buffers[6, 3, :3], buffers[6, 4, :3]
    _predict(P, t, Q, AP, first_prior)  # the same prior for every candidate
    keep = firsts.shape[0] == count
    for c in range(first, first + count):
        p0, p1, p2 = rotation[c, 0], rotation[c, 1], rotation[c, 2]
        score = 0.0
        for j in range(1, options[_SCORED] + 1):
            if prediction == _HOLD:
                q[0], q[1], q[2] = x[0], x[1], x[2]
            elif prediction == _COAST:
                jt = j * t
                q[0], q[1], q[2] = x[0] + jt * x[3], x[1] + jt * x[4], x[2] + jt * x[5]
            elif j <= lag:  # the lagging reference has not turned yet: Exp(0) r = r
                q[0], q[1], q[2] = r_q[0], r_q[1], r_q[2]
            else:
                steps = float(j - lag)
                q[0], q[1], q[2] = _rotate(
                    steps * p0, steps * p1, steps * p2, r_q[0], r_q[1], r_q[2]
                )
            if j == 1:
                q_s[0], q_s[1], q_s[2] = baselines[c, 0], baselines[c, 1], baselines[c, 2]
            else:
                q_s[0], q_s[1], q_s[2] = _rotate(
                    j * p0, j * p1, j * p2, baseline[0], baseline[1], baseline[2]
                )
            m = _rows(q, q_s, ranges, eta, rows, noise)
            if j == 1:
                _update(first_prior, rows, m, noise, PHt, gain, posterior)
                if keep:
                    firsts[c - first] = posterior
            else:
                _predict(posterior, t, Q, AP, prior)
                _update(prior, rows, m, noise, PHt, gain, posterior)
            score += _criterion(posterior, options[_CRITERION], block, work)
        scores[c] = score


@njit(cache=True, error_model="numpy")
def _candidate_baselines(rotation, baseline, out):  # pragma: no cover - compiled
    """The world baseline after each candidate's first step, ``Exp(φ_c) R b``."""
    for c in range(rotation.shape[0]):
        out[c, 0], out[c, 1], out[c, 2] = _rotate(
            rotation[c, 0], rotation[c, 1], rotation[c, 2], baseline[0], baseline[1], baseline[2]
        )


@njit(cache=True, error_model="numpy")
def _buffers():  # pragma: no cover - compiled
    return np.empty((7, 6, 6))


@njit(cache=True, error_model="numpy")
def _scores_kernel(
    options, parameters, b, q_star, Q, x_hat, P, R_WB, rotation, linear
):  # pragma: no cover - compiled
    runs, n = x_hat.shape[0], rotation.shape[1]
    scores = np.empty((runs, n))
    firsts = np.empty((runs, n, 6, 6))
    buffers = _buffers()
    baseline, r_q = np.empty(3), np.empty(3)
    baselines = np.empty((n, 3))
    for i in range(runs):
        R = R_WB[i]
        for a in range(3):
            baseline[a] = R[a, 0] * b[0] + R[a, 1] * b[1] + R[a, 2] * b[2]
            r_q[a] = R[a, 0] * q_star[0] + R[a, 1] * q_star[1] + R[a, 2] * q_star[2]
        _candidate_baselines(rotation[i], baseline, baselines)
        _score_candidates(options, parameters, Q, x_hat[i], P[i], baseline, r_q, rotation[i],
                          baselines, 0, n, linear[i] > 0.0, scores[i], firsts[i],
                          buffers)  # fmt: skip
    return scores, firsts


@njit(cache=True, error_model="numpy")
def _cap_rotations(cap_z, baseline, baseline_norm, out):  # pragma: no cover - compiled
    """The cap's rotation vectors about +z turned onto the baseline's direction u0 (rotation
    vectors turn as vectors), by ``attitude_candidates.frame_about``'s frame."""
    u0, u1, u2 = (
        baseline[0] / baseline_norm,
        baseline[1] / baseline_norm,
        baseline[2] / baseline_norm,
    )
    axis, smallest = (1, abs(u1)) if abs(u1) < abs(u0) else (0, abs(u0))
    if abs(u2) < smallest:
        axis = 2
    h0 = 1.0 if axis == 0 else 0.0
    h1 = 1.0 if axis == 1 else 0.0
    h2 = 1.0 if axis == 2 else 0.0
    e0, e1, e2 = u1 * h2 - u2 * h1, u2 * h0 - u0 * h2, u0 * h1 - u1 * h0
    length = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
    e0, e1, e2 = e0 / length, e1 / length, e2 / length
    f0, f1, f2 = u1 * e2 - u2 * e1, u2 * e0 - u0 * e2, u0 * e1 - u1 * e0
    for c in range(cap_z.shape[0]):
        z0, z1, z2 = cap_z[c, 0], cap_z[c, 1], cap_z[c, 2]
        out[c, 0] = z0 * e0 + z1 * f0 + z2 * u0
        out[c, 1] = z0 * e1 + z1 * f1 + z2 * u1
        out[c, 2] = z0 * e2 + z1 * f2 + z2 * u2


@njit(cache=True, error_model="numpy")
def _candidates_kernel(options, parameters, b, candidates, R_WB):  # pragma: no cover - compiled
    runs, n = R_WB.shape[0], candidates.shape[0]
    out = np.empty((runs, n, 3))
    baseline = np.empty(3)
    for i in range(runs):
        R = R_WB[i]
        for a in range(3):
            baseline[a] = R[a, 0] * b[0] + R[a, 1] * b[1] + R[a, 2] * b[2]
        if options[_CAP]:
            _cap_rotations(candidates, baseline, parameters[_NORM], out[i])
        else:
            out[i] = candidates
    return out


@njit(cache=True, error_model="numpy")
def _workspace(n):  # pragma: no cover - compiled
    """Scratch arrays of one run's plan over ``n`` candidates (reused from run to run)."""
    return (
        _buffers(),
        np.empty((1, 6, 6)),  # the chosen candidate's first posterior
        np.empty((5, n)),  # scores, objective, reference acceleration, excitation
        np.empty((2, n), dtype=np.bool_),  # admissible, enough
        np.empty((2, n, 3)),  # the run's own candidate rotations, their baselines
        np.empty((4, 3, 3)),  # baseline and R q* (rows 0, 1 of the first), G, L, the turn
    )


@njit(cache=True, error_model="numpy")
def _plan_run(
    options, parameters, b, q_star, Q, candidates,
    x, P, R, H, filled, Rp, known, linear, workspace,
    out_rotation, out_R, out_baseline, out_P, out_stats,
):  # pragma: no cover - compiled  # fmt: skip
    """One run's plan (:meth:`InformationSeekingPlanner.plan_runs`) into the ``out_`` views."""
    n, kept = candidates.shape[0], H.shape[0]
    t = parameters[_T]
    buffers, firsts, values, flags, vectors, small = workspace
    scores, objective, acceleration, excitation = values[0], values[1], values[2], values[3]
    admissible, enough = flags[0], flags[1]
    own_rotation, baselines = vectors[0], vectors[1]
    baseline, r_q, G, L, turn = small[0, 0], small[0, 1], small[1], small[2], small[3]
    limit = parameters[_MAX_REFERENCE]
    floor = parameters[_FLOOR]
    window = options[_WINDOW]
    for a in range(3):
        baseline[a] = R[a, 0] * b[0] + R[a, 1] * b[1] + R[a, 2] * b[2]
        r_q[a] = R[a, 0] * q_star[0] + R[a, 1] * q_star[1] + R[a, 2] * q_star[2]
    if options[_CAP]:
        _cap_rotations(candidates, baseline, parameters[_NORM], own_rotation)
        rotation = own_rotation
    else:
        rotation = candidates
    _candidate_baselines(rotation, baseline, baselines)
    _score_candidates(options, parameters, Q, x, P, baseline, r_q, rotation, baselines, 0, n,
                      linear, scores, firsts[:0], buffers)  # fmt: skip
    for c in range(n):
        admissible[c] = True
        objective[c] = scores[c]
        acceleration[c] = np.nan
        excitation[c] = np.nan

    # The reference limit (this run's, when it knows R(k−1)).
    if limit < np.inf and known > 0.0:
        s0, s1, s2 = r_q[0], r_q[1], r_q[2]
        v0 = Rp[0, 0] * q_star[0] + Rp[0, 1] * q_star[1] + Rp[0, 2] * q_star[2]
        v1 = Rp[1, 0] * q_star[0] + Rp[1, 1] * q_star[1] + Rp[1, 2] * q_star[2]
        v2 = Rp[2, 0] * q_star[0] + Rp[2, 1] * q_star[1] + Rp[2, 2] * q_star[2]
        any_within = False
        for c in range(n):
            a0, a1, a2 = _rotate(rotation[c, 0], rotation[c, 1], rotation[c, 2], s0, s1, s2)
            d0, d1, d2 = a0 - 2.0 * s0 + v0, a1 - 2.0 * s1 + v1, a2 - 2.0 * s2 + v2
            acceleration[c] = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2) / t**2
            admissible[c] = acceleration[c] <= limit
            any_within = any_within or admissible[c]
        if not any_within:  # the least demanding candidate(s)
            lowest = np.inf
            for c in range(n):
                if acceleration[c] < lowest:
                    lowest = acceleration[c]
            for c in range(n):
                admissible[c] = acceleration[c] <= lowest

    # The excitation floor on the trailing planning window ending with the candidate.
    if floor > 0.0:
        f = filled
        used = int(f) if f >= 0.0 and f <= kept else (kept if f > kept else 0)
        used = min(used, window - 2)
        required = floor * min((used + 2) / window, 1.0)
        for a in range(3):
            for e in range(3):
                total = 0.0
                for row in range(kept - used, kept):
                    total += H[row, a] * H[row, e]
                G[a, e] = total + baseline[a] * baseline[e]
        any_enough = False
        for c in range(n):
            u0, u1, u2 = baselines[c, 0], baselines[c, 1], baselines[c, 2]
            excitation[c] = _symmetric_eigen_3(
                G[0, 0] + u0 * u0, G[0, 1] + u0 * u1, G[0, 2] + u0 * u2,
                G[1, 1] + u1 * u1, G[1, 2] + u1 * u2, G[2, 2] + u2 * u2,
            )[0]  # fmt: skip
            enough[c] = admissible[c] and excitation[c] >= required
            any_enough = any_enough or enough[c]
        if any_enough:
            for c in range(n):
                admissible[c] = enough[c]
        else:
            # Turn toward the least excited direction: x_cᵀ (Λ + εI)⁻¹ x_c = |L⁻¹ x_c|²
            # with Λ + εI = L Lᵀ (Cholesky).
            epsilon = parameters[_EPSILON]
            for a in range(3):
                for e in range(a + 1):
                    total = G[a, e] + (epsilon if a == e else 0.0)
                    for m in range(e):
                        total -= L[a, m] * L[e, m]
                    L[a, e] = math.sqrt(total) if a == e else total / L[e, e]
            for c in range(n):
                y0 = baselines[c, 0] / L[0, 0]
                y1 = (baselines[c, 1] - L[1, 0] * y0) / L[1, 1]
                y2 = (baselines[c, 2] - L[2, 0] * y0 - L[2, 1] * y1) / L[2, 2]
                objective[c] = y0 * y0 + y1 * y1 + y2 * y2

    # The best admissible candidate (NaN counts as best, as argmax). Candidates within
    # rounding of the best are ties, taken in grid order: the first one. (The first step's
    # novelty is exactly equal around a ring, so otherwise rounding would choose.)
    index, best = -1, 0.0
    for c in range(n):
        if admissible[c]:
            value = objective[c]
            if index < 0 or (best == best and (value != value or value > best)):
                index, best = c, value
    if best == best:
        tied = best - _TIE * abs(best)
        for c in range(index):
            if admissible[c] and objective[c] >= tied:
                index = c
                break
    index = max(index, 0)  # none admissible: only a run holding NaN
    p0, p1, p2 = rotation[index, 0], rotation[index, 1], rotation[index, 2]
    out_rotation[0], out_rotation[1], out_rotation[2] = p0, p1, p2
    exp_so3_kernel(p0, p1, p2, turn)
    matmul3_kernel(turn, R, out_R)
    for a in range(3):
        out_baseline[a] = out_R[a, 0] * b[0] + out_R[a, 1] * b[1] + out_R[a, 2] * b[2]
    # The chosen candidate's P(k+1|k+1), scored again (the same arithmetic, the same bits).
    _score_candidates(options, parameters, Q, x, P, baseline, r_q, rotation, baselines, index, 1,
                      linear, values[4, :1], firsts[:1], buffers)  # fmt: skip
    out_P[:, :] = firsts[0]
    out_stats[0], out_stats[1], out_stats[2] = scores[index], excitation[index], acceleration[index]


@njit(cache=True, error_model="numpy")
def _plan_kernel(
    options, parameters, b, q_star, Q, candidates,
    x_hat, P, R_WB, history, filled, R_previous, has_previous, linear, both,
):  # pragma: no cover - compiled  # fmt: skip
    """:meth:`InformationSeekingPlanner.plan_runs` for every run, and with ``both`` the plan
    of step k+1 after it (:meth:`InformationSeekingPlanner.plan_pair_runs`)."""
    runs, n, kept = x_hat.shape[0], candidates.shape[0], history.shape[1]
    stages = 2 if both else 1
    rotation = np.empty((stages, runs, 3))
    R_next = np.empty((stages, runs, 3, 3))
    baseline = np.empty((stages, runs, 3))
    P_next = np.empty((stages, runs, 6, 6))
    stats = np.empty((stages, runs, 3))
    workspace = _workspace(n)
    next_history = np.empty((kept, 3))
    next_x = np.empty(6)
    t = parameters[_T]
    for i in range(runs):
        run_linear = linear[i] > 0.0
        _plan_run(options, parameters, b, q_star, Q, candidates,
                  x_hat[i], P[i], R_WB[i], history[i], filled[i], R_previous[i],
                  has_previous[i], run_linear, workspace,
                  rotation[0, i], R_next[0, i], baseline[0, i], P_next[0, i],
                  stats[0, i])  # fmt: skip
        if not both:
            continue
        # Step k+1 from the planned R(k+1) and P(k+1|k+1), q_s(k) appended to the history.
        R = R_WB[i]
        for row in range(kept - 1):
            next_history[row] = history[i, row + 1]
        for a in range(3):
            next_history[kept - 1, a] = R[a, 0] * b[0] + R[a, 1] * b[1] + R[a, 2] * b[2]
        next_filled = filled[i] + 1.0
        next_filled = kept if next_filled > kept else next_filled
        for a in range(6):
            next_x[a] = x_hat[i, a]
        if options[_PREDICTION] == _COAST:  # x̂(k+1|k) without the control
            for a in range(3):
                next_x[a] = x_hat[i, a] + t * x_hat[i, a + 3]
        # Still the linear start at k+1 unless the planned P(k+1|k+1) hands over.
        Pn = P_next[0, i]
        hands_over = (
            options[_THRESHOLD_SET] == 0 or Pn[0, 0] + Pn[1, 1] + Pn[2, 2] <= parameters[_THRESHOLD]
        )
        _plan_run(options, parameters, b, q_star, Q, candidates,
                  next_x, Pn, R_next[0, i], next_history, next_filled, R, 1.0,
                  run_linear and not hands_over, workspace,
                  rotation[1, i], R_next[1, i], baseline[1, i], P_next[1, i],
                  stats[1, i])  # fmt: skip
    return rotation, R_next, baseline, P_next, stats


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
