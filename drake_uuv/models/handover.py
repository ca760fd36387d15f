"""When a raw-range filter leaves its linear-KF start: a rule that scales with range and noise.

A raw-range filter (EKF, UKF, particle filter) starts as the paper's linear KF on
``Y = ½(d1² − d2²)``, which is exactly linear in ``q`` and so converges from any prior, and
hands over to the raw ranges. The first rule (:class:`ThresholdHandover`: ``trace(P_qq) ≤
0.5 m²``) is absolute: with σ = 0.5 or 1 m of range noise, or 14 m of standoff, the KF never
reaches it and the "EKF" stays the KF (2.7–4.8× the Cramér–Rao bound). :class:`HandoverRule`
replaces it with two tests on the KF's own estimate and covariance after each linear update:

1. **The prior is forgotten**: ``tr(S_qq) ≤ prior_share · tr(P_qq)``, where ``S = Φ P0 Φᵀ``
   is the part of the KF's covariance that still comes from its prior (``Φ`` the KF's error
   transition since step 0: ``S ← A S Aᵀ`` at a prediction, ``S ← (I − K C) S (I − K C)ᵀ`` at
   an update; :func:`~drake_uuv.models.handover_measures.prior_share_predict`,
   :func:`~drake_uuv.models.handover_measures.prior_share_update`). The scenario's prior
   ``x̂0 = 0``, ``P0 = I`` is three standard deviations from the truth (``|q| ≈ 3 m``), so
   until the data outweigh it the KF's covariance understates its error and no test on that
   covariance can be trusted.
2. **The Gaussian is narrow against the range**: for each sonar,
   ``θᵢ = √tr(P⊥ᵢ) / dᵢ ≤ angle_tolerance``, with ``P⊥ᵢ`` the position covariance across
   the line of sight ``uᵢ`` (``tr P⊥ = tr P_qq − uᵢᵀ P_qq uᵢ``) and ``dᵢ`` the range, both at
   the estimate (:func:`~drake_uuv.models.handover_measures.cross_range_angle`). A range
   filter with a Gaussian posterior is only valid while the angular spread of the target's
   direction is small: beyond it the posterior is a curved shell and, as the baseline turns,
   can split into the two-range circle's mirror images, on which an EKF or UKF locks. In
   terms of the linearisation error: the second-order range term a linearisation drops is
   ``tr(P⊥)/(2d) = θ² d / 2``, so the test bounds it by a fraction of the *range*, not of
   the range noise.

Hand-over happens after the update at which both hold (and at least ``min_linear_steps``
updates were linear), or unconditionally after ``max_linear_steps`` linear updates if set.
A particle filter needs no Gaussian posterior, so it uses test 1 alone
(``angle_tolerance=None``): it draws its particles from the KF's Gaussian once that Gaussian
is an honest description of the KF's error.

Where test 1 holds and test 2 never does (σ = 1 m at 2.8 m: the posterior's angular spread
stays near 0.3 rad), a Gaussian filter would stay the paper's KF for ever. With
``particle_bridge`` it does what the particle filter does instead: at the update where test 1
holds and test 2 fails, it draws particles from the KF's Gaussian and carries the posterior
on them, and takes its Gaussian update back at the first update whose particle posterior
passes test 2 (and the second-order test, for the EKF). Because a Gaussian filter's
covariance can widen again (its steady state at σ = 1 m is wider than the moment it took
over), it returns to particles, drawn from its own Gaussian, when an angle exceeds
``fallback_factor · angle_tolerance``; the gap between the two thresholds keeps it from
switching at every step. A Gaussian filter can also go wrong with a narrow covariance (it
slips onto the mirror solution, or trusts a linearisation that weak excitation leaves
poor): when an innovation is beyond any chance under its own covariance (NIS above
:data:`LOST_NIS`), it redraws particles from that step's prior, widened by NIS/2 so that
the innovation becomes typical, and weighs them by the step's ranges.

The defaults of every threshold below were chosen by measurement, in the plain-numpy loop
of ``benchmarks/estimator_regimes.py`` and in the Drake loop; ``docs/handover.md`` lists
those measurements and the commands that repeat them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum
from typing import NamedTuple, Protocol

import numpy as np
from numba import njit

from drake_uuv.models.handover_measures import (
    _one_run,
    _trace_qq,
    cross_range_angle_runs,
    second_order_range_error_runs,
)

# Re-exported: the measures the tests read are importable from here, as before.
from drake_uuv.models.handover_measures import cross_range_angle as cross_range_angle
from drake_uuv.models.handover_measures import prior_share_predict as prior_share_predict
from drake_uuv.models.handover_measures import prior_share_update as prior_share_update
from drake_uuv.models.handover_measures import second_order_range_error as second_order_range_error


class Phase(IntEnum):
    """Which update a raw-range filter makes at a step (the value is stored as discrete state)."""

    RANGE = 0  # its Gaussian update on the raw ranges (EKF, IEKF, UKF)
    LINEAR = 1  # the paper's KF on Y = ½(z1² − z2²): the start
    PARTICLE = 2  # the posterior carried on particles


# The phases as plain integers, for the arithmetic over runs (an enum member's lookup costs
# more than the comparison it feeds).
_RANGE, _LINEAR, _PARTICLE = int(Phase.RANGE), int(Phase.LINEAR), int(Phase.PARTICLE)


@dataclass(frozen=True)
class PhaseEvidence:
    """What a hand-over policy decides on, after an update the filter applied.

    One run's values, or a batch's with a leading run axis (for ``next_phases``: ``x``
    (B, 6), ``P`` (B, 6, 6), ``nis`` (B), ``linear_updates`` (B), ``prior_share`` (B, 6, 6),
    ``q_s`` (B, 3)). ``x``, ``P``: the step's filtered estimate; ``nis`` its update's NIS;
    ``linear_updates``:
    linear updates applied so far (this one included); ``prior_share``: the prior's share
    ``S`` of the linear KF's covariance
    (:func:`~drake_uuv.models.handover_measures.prior_share_update`); ``q_s``: the world
    baseline; ``noise_std``: the per-sonar ``√(η/f)`` of the range means; ``gaussian``: the
    filter has a Gaussian range update; ``particles``: it can carry particles.
    """

    x: np.ndarray
    P: np.ndarray
    nis: float
    linear_updates: int
    prior_share: np.ndarray
    q_s: np.ndarray
    noise_std: np.ndarray
    gaussian: bool
    particles: bool


class Transition(NamedTuple):
    """A policy's decision: the next step's phase, and for a new particle phase where the
    particles come from: the step's filtered estimate (default), or the step's prior widened
    by NIS/2 and weighed by the step's ranges (``redraw_from_prior``, for a filter that lost
    the target)."""

    phase: Phase
    redraw_from_prior: bool = False


class HandoverPolicy(Protocol):
    """When a raw-range filter changes phase: the one seam of the hand-over.

    ``linear_start``: whether the filter starts in :attr:`Phase.LINEAR`; ``particle_bridge``:
    whether a Gaussian filter carries particles where its Gaussian fails; :meth:`next_phase`
    is asked after every applied update.
    """

    @property
    def linear_start(self) -> bool: ...

    @property
    def particle_bridge(self) -> bool: ...

    def next_phase(self, phase: Phase, evidence: PhaseEvidence) -> Transition: ...

    def next_phases(
        self, phases: np.ndarray, evidence: PhaseEvidence
    ) -> tuple[np.ndarray, np.ndarray]: ...


def _batch_of_one(evidence: PhaseEvidence) -> PhaseEvidence:
    x, P, q_s = _one_run(evidence.x, evidence.P, evidence.q_s)
    return PhaseEvidence(
        x=x, P=P, nis=np.array([float(evidence.nis)]),
        linear_updates=np.array([evidence.linear_updates]),
        prior_share=np.asarray(evidence.prior_share, dtype=float).reshape(1, 6, 6),
        q_s=q_s, noise_std=evidence.noise_std, gaussian=evidence.gaussian,
        particles=evidence.particles,
    )  # fmt: skip


def _one_transition(policy: HandoverPolicy, phase: Phase, evidence: PhaseEvidence) -> Transition:
    phases, redraw = policy.next_phases(np.array([int(phase)]), _batch_of_one(evidence))
    return Transition(Phase(int(phases[0])), bool(redraw[0]))


@dataclass(frozen=True)
class ThresholdHandover:
    """The first raw-range EKF's hand-over: absolute, one way, without particles.

    After the update at which ``trace(P_qq) ≤ position_variance_threshold`` (and at least
    ``min_linear_steps`` linear updates), or unconditionally after ``max_linear_steps`` linear
    updates if that is set, the filter leaves the linear start for its Gaussian update (or
    its particles, for a filter without one) and never returns. ``max_linear_steps = 0``
    disables the linear start. By default there is no forced hand-over: where the linear KF
    cannot converge (a fixed attitude leaves two directions unobservable) a forced hand-over
    linearises a covariance of thousands of m² and the loop blows up.

    The threshold is absolute: with 0.5 or 1 m of range noise, or at 14 m, the KF never
    reaches it and the filter stays the paper's KF; :class:`HandoverRule` scales instead.
    """

    position_variance_threshold: float = 0.5
    min_linear_steps: int = 1
    max_linear_steps: int | None = None

    @property
    def linear_start(self) -> bool:
        """Whether a filter begins with linear-KF updates (``max_linear_steps != 0``)."""
        return self.max_linear_steps is None or self.max_linear_steps > 0

    @property
    def particle_bridge(self) -> bool:
        return False

    def handover_due(self, P: np.ndarray, linear_steps_done: int) -> bool:
        """True if, after ``linear_steps_done`` linear updates ending with covariance ``P``,
        the next update should leave the linear start."""
        if self.max_linear_steps is not None and linear_steps_done >= self.max_linear_steps:
            return True
        if linear_steps_done < self.min_linear_steps:
            return False
        return float(np.trace(P[:3, :3])) <= self.position_variance_threshold

    def handover_due_runs(self, P: np.ndarray, linear_steps_done: np.ndarray) -> np.ndarray:
        """:meth:`handover_due` of each run (``P`` (B, 6, 6), counts (B))."""
        due = (linear_steps_done >= self.min_linear_steps) & (
            _trace_qq(P) <= self.position_variance_threshold
        )
        if self.max_linear_steps is not None:
            due |= linear_steps_done >= self.max_linear_steps
        return due

    def next_phase(self, phase: Phase, evidence: PhaseEvidence) -> Transition:
        return _one_transition(self, phase, evidence)

    def next_phases(
        self, phases: np.ndarray, evidence: PhaseEvidence
    ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`next_phase` of each run: the next phases (B) and whether each redraws its
        particles from its prior (never, here)."""
        due = (phases == _LINEAR) & self.handover_due_runs(evidence.P, evidence.linear_updates)
        target = Phase.RANGE if evidence.gaussian else Phase.PARTICLE
        return np.where(due, int(target), phases), np.zeros(len(phases), dtype=bool)


#: The NIS beyond which a bridged Gaussian filter is lost: the χ²(2) quantile of 1 − 10⁻⁶
#: (−2 ln 10⁻⁶), about one false alarm per two thousand 500-step runs.
LOST_NIS = 2.0 * math.log(1e6)


@dataclass(frozen=True)
class HandoverRule:
    """The hand-over from the linear-KF start to the raw ranges (see the module docstring).

    After ``linear_steps_done`` linear updates ending with estimate ``x``, covariance ``P``
    and baseline ``q_s``, :meth:`handover_due` is true when ``max_linear_steps`` is reached, or
    when :meth:`prior_forgotten` (test 1, after at least ``min_linear_steps``) and
    :meth:`gaussian_holds` (test 2, unless ``angle_tolerance`` is None, and the second-order
    test if set). ``max_linear_steps = 0`` disables the linear start.

    With ``particle_bridge``, a Gaussian filter whose prior is forgotten but whose Gaussian
    test fails carries its posterior on particles until :meth:`gaussian_holds` on the
    particles' mean and covariance, and goes back to particles when :meth:`fallback_due`
    (an angle above ``fallback_factor · angle_tolerance``: the hysteresis keeps it from
    switching at every step).
    """

    angle_tolerance: float | None = 0.25
    prior_share: float = 0.1
    min_linear_steps: int = 1
    max_linear_steps: int | None = None
    # For a filter that drops the second-order term (the EKF): also require
    # tr(P⊥)/(2d) ≤ second_order_tolerance · σ/√f (None: no such test).
    second_order_tolerance: float | None = None
    # Particles between the linear start and the Gaussian filter, and wherever the Gaussian
    # test fails later (needs angle_tolerance).
    particle_bridge: bool = False
    # Back to particles when a cross-range angle exceeds fallback_factor · angle_tolerance.
    fallback_factor: float = 1.2

    def __post_init__(self) -> None:
        if self.angle_tolerance is not None and not (
            math.isfinite(self.angle_tolerance) and self.angle_tolerance > 0.0
        ):
            raise ValueError(f"angle_tolerance: must be > 0 or None, got {self.angle_tolerance!r}")
        if not self.prior_share > 0.0:  # inf: no test 1 (NaN fails here too)
            raise ValueError(f"prior_share: must be > 0, got {self.prior_share!r}")
        if self.second_order_tolerance is not None and not self.second_order_tolerance > 0.0:
            raise ValueError(
                f"second_order_tolerance: must be > 0 or None, got {self.second_order_tolerance!r}"
            )
        if self.min_linear_steps < 0:
            raise ValueError(f"min_linear_steps: must be ≥ 0, got {self.min_linear_steps!r}")
        if self.max_linear_steps is not None and self.max_linear_steps < 0:
            raise ValueError(f"max_linear_steps: must be ≥ 0, got {self.max_linear_steps!r}")
        if not self.fallback_factor >= 1.0:  # inf: never back to particles
            raise ValueError(f"fallback_factor: must be ≥ 1, got {self.fallback_factor!r}")
        if self.particle_bridge and self.angle_tolerance is None:
            raise ValueError(
                "particle_bridge: needs an angle_tolerance to leave the particles, got None"
            )

    @property
    def linear_start(self) -> bool:
        """Whether a filter begins with linear-KF updates (``max_linear_steps != 0``)."""
        return self.max_linear_steps is None or self.max_linear_steps > 0

    def prior_forgotten_runs(
        self, P: np.ndarray, linear_steps_done: np.ndarray, prior_covariance: np.ndarray
    ) -> np.ndarray:
        """:meth:`prior_forgotten` of each run (``P``, ``prior_covariance`` (B, 6, 6), counts
        (B))."""
        forgotten = (linear_steps_done >= self.min_linear_steps) & (
            _trace_qq(prior_covariance) <= self.prior_share * _trace_qq(P)
        )
        if self.max_linear_steps is not None:
            forgotten |= linear_steps_done >= self.max_linear_steps
        return forgotten

    def prior_forgotten(
        self, P: np.ndarray, linear_steps_done: int, prior_covariance: np.ndarray
    ) -> bool:
        """Test 1 (or ``max_linear_steps`` reached): the KF's covariance rests on its data.

        ``prior_covariance`` is the prior's share ``S`` of ``P``."""
        P = np.asarray(P, dtype=float).reshape(1, 6, 6)
        S = np.asarray(prior_covariance, dtype=float).reshape(1, 6, 6)
        return bool(self.prior_forgotten_runs(P, np.array([linear_steps_done]), S)[0])

    def gaussian_holds_runs(
        self,
        x: np.ndarray,
        P: np.ndarray,
        q_s: np.ndarray,
        noise_std: np.ndarray | None = None,
        angles: np.ndarray | None = None,
    ) -> np.ndarray:
        """:meth:`gaussian_holds` of each run (``angles``: their
        :func:`~drake_uuv.models.handover_measures.cross_range_angle_runs`, when known)."""
        holds = np.ones(len(x), dtype=bool)
        if self.angle_tolerance is None and self.second_order_tolerance is None:
            return holds
        if angles is None:
            angles = cross_range_angle_runs(x, P, q_s)
        if self.angle_tolerance is not None:
            holds &= np.all(angles <= self.angle_tolerance, axis=1)
        if self.second_order_tolerance is None:
            return holds
        if noise_std is None:
            raise ValueError("noise_std: needed with second_order_tolerance, got None")
        limit = self.second_order_tolerance * np.asarray(noise_std, dtype=float)
        error = second_order_range_error_runs(x, P, q_s, angles)
        return holds & np.all(error <= limit, axis=1)

    def gaussian_holds(
        self,
        x: np.ndarray,
        P: np.ndarray,
        q_s: np.ndarray,
        noise_std: np.ndarray | None = None,
    ) -> bool:
        """Test 2 and, with ``second_order_tolerance``, the second-order test (``noise_std``
        the per-sonar ``√(η/f)``): a Gaussian describes the posterior ``N(x, P)``."""
        return bool(self.gaussian_holds_runs(*_one_run(x, P, q_s), noise_std)[0])

    def fallback_due_runs(
        self, x: np.ndarray, P: np.ndarray, q_s: np.ndarray, angles: np.ndarray | None = None
    ) -> np.ndarray:
        """:meth:`fallback_due` of each run."""
        if not self.particle_bridge:
            return np.zeros(len(x), dtype=bool)
        if angles is None:
            angles = cross_range_angle_runs(x, P, q_s)
        limit = self.fallback_factor * float(self.angle_tolerance)
        return np.any(angles > limit, axis=1)

    def fallback_due(self, x: np.ndarray, P: np.ndarray, q_s: np.ndarray) -> bool:
        """With ``particle_bridge``: a Gaussian filter's ``N(x, P)`` has become too wide for a
        Gaussian (a cross-range angle above ``fallback_factor · angle_tolerance``)."""
        return bool(self.fallback_due_runs(*_one_run(x, P, q_s))[0])

    def lost(self, nis: float | np.ndarray) -> bool | np.ndarray:
        """With ``particle_bridge``: a Gaussian filter's innovation is beyond any chance under
        its own covariance (NIS above :data:`LOST_NIS`), as when it slips onto the mirror
        solution while its covariance stays narrow (per run for an array of NIS)."""
        return self.particle_bridge & (nis > LOST_NIS)

    def handover_due_runs(
        self,
        P: np.ndarray,
        linear_steps_done: np.ndarray,
        *,
        x: np.ndarray,
        q_s: np.ndarray,
        prior_covariance: np.ndarray,
        noise_std: np.ndarray | None = None,
        angles: np.ndarray | None = None,
    ) -> np.ndarray:
        """:meth:`handover_due` of each run."""
        due = self.prior_forgotten_runs(P, linear_steps_done, prior_covariance)
        due &= self.gaussian_holds_runs(x, P, q_s, noise_std, angles)
        if self.max_linear_steps is not None:
            due |= linear_steps_done >= self.max_linear_steps
        return due

    def handover_due(
        self,
        P: np.ndarray,
        linear_steps_done: int,
        *,
        x: np.ndarray,
        q_s: np.ndarray,
        prior_covariance: np.ndarray,
        noise_std: np.ndarray | None = None,
    ) -> bool:
        """True if the next update should be a range update (``prior_covariance`` is ``S``,
        ``noise_std`` the per-sonar ``√(η/f)``, needed with ``second_order_tolerance``)."""
        x, P, q_s = _one_run(x, P, q_s)
        S = np.asarray(prior_covariance, dtype=float).reshape(1, 6, 6)
        return bool(
            self.handover_due_runs(
                P, np.array([linear_steps_done]), x=x, q_s=q_s, prior_covariance=S,
                noise_std=noise_std,
            )[0]
        )  # fmt: skip

    def next_phase(self, phase: Phase, evidence: PhaseEvidence) -> Transition:
        """Linear: to the Gaussian update when :meth:`handover_due`, else to particles once
        the prior is forgotten (a filter without a Gaussian update, or with the bridge).
        Particles: back to the Gaussian update when :meth:`gaussian_holds` on them. Gaussian
        (with the bridge): to particles when :meth:`fallback_due`, or redrawn from the prior
        when :meth:`lost`."""
        return _one_transition(self, phase, evidence)

    def next_phases(
        self, phases: np.ndarray, evidence: PhaseEvidence
    ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`next_phase` of each run (``evidence`` with a leading run axis): the next
        phases (B) and the runs that redraw their particles from their prior (B). One
        compiled loop over the runs (:func:`_rule_next_phases`), the tests' arithmetic of
        the methods above."""
        e = evidence
        B = len(phases)
        following = np.empty(B, dtype=np.intp)
        redraw = np.empty(B, dtype=np.bool_)
        _rule_next_phases(
            np.asarray(phases, dtype=np.intp), e.x, e.P, np.asarray(e.nis, dtype=float),
            np.asarray(e.linear_updates, dtype=float), e.prior_share, e.q_s,
            np.asarray(e.noise_std, dtype=float).reshape(2),
            math.nan if self.angle_tolerance is None else float(self.angle_tolerance),
            float(self.prior_share), float(self.min_linear_steps),
            -1.0 if self.max_linear_steps is None else float(self.max_linear_steps),
            math.nan if self.second_order_tolerance is None else float(self.second_order_tolerance),
            bool(self.particle_bridge), float(self.fallback_factor), bool(e.gaussian),
            bool(e.particles), following, redraw,
        )  # fmt: skip
        return following, redraw


@njit(cache=True, error_model="numpy")
def _rule_next_phases(
    phases, x, P, nis, done, S, q_s, noise_std, angle_tolerance, share, min_steps, max_steps,
    second_order, bridge, fallback_factor, gaussian, particles, following, redraw,
):  # fmt: skip
    """:meth:`HandoverRule.next_phases` of each run (NaN tolerances: no such test; a negative
    ``max_steps``: none)."""
    angles = np.empty(2)
    for r in range(len(phases)):
        # the cross-range angles and the second-order test at the estimate
        trace = P[r, 0, 0] + P[r, 1, 1] + P[r, 2, 2]
        small = True
        for i in range(2):
            sign = 0.5 if i == 0 else -0.5
            v0 = x[r, 0] + sign * q_s[r, 0]
            v1 = x[r, 1] + sign * q_s[r, 1]
            v2 = x[r, 2] + sign * q_s[r, 2]
            d = np.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
            if d < 1e-9:
                angles[i] = np.inf
            else:
                u0, u1, u2 = v0 / d, v1 / d, v2 / d
                uPu = 0.0
                for a, ua in ((0, u0), (1, u1), (2, u2)):
                    uPu += ua * (P[r, a, 0] * u0 + P[r, a, 1] * u1 + P[r, a, 2] * u2)
                across = trace - uPu
                across = across if (across > 0.0 or across != across) else 0.0
                angles[i] = np.sqrt(across) / d
            if second_order == second_order:
                if not (0.5 * angles[i] * angles[i] * d <= second_order * noise_std[i]):
                    small = False
        holds = small
        if angle_tolerance == angle_tolerance:
            holds = holds and angles[0] <= angle_tolerance and angles[1] <= angle_tolerance
        maxed = max_steps >= 0.0 and done[r] >= max_steps
        forgotten = maxed or (
            done[r] >= min_steps and S[r, 0, 0] + S[r, 1, 1] + S[r, 2, 2] <= share * trace
        )
        redraw[r] = False
        phase = phases[r]
        if phase == 1:  # linear
            if gaussian and (maxed or (forgotten and holds)):
                following[r] = 0
            elif particles and forgotten:
                following[r] = 2
            else:
                following[r] = 1
        elif phase == 2:  # particles
            following[r] = 0 if (gaussian and holds) else 2
        else:
            limit = fallback_factor * angle_tolerance
            fallback = bridge and (angles[0] > limit or angles[1] > limit)
            if fallback:
                following[r] = 2
            elif bridge and nis[r] > LOST_NIS:
                following[r] = 2
                redraw[r] = True
            else:
                following[r] = 0
