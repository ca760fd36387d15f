"""When a raw-range filter leaves its linear-KF start: a rule that scales with range and noise.

A raw-range filter (EKF, UKF, particle filter) starts as the paper's linear KF on
``Y = ½(d1² − d2²)``, which is exactly linear in ``q`` and so converges from any prior, and
hands over, one way, to the raw ranges. The old rule (``HandoverPolicy``: ``trace(P_qq) ≤
0.5 m²``) is absolute: with σ = 0.5 or 1 m of range noise, or 14 m of standoff, the KF never
reaches it and the "EKF" stays the KF (2.7–4.8× the Cramér–Rao bound). :class:`HandoverRule`
replaces it with two tests on the KF's own estimate and covariance after each linear update:

1. **The prior is forgotten**: ``tr(S_qq) ≤ prior_share · tr(P_qq)``, where ``S = Φ P0 Φᵀ``
   is the part of the KF's covariance that still comes from its prior (``Φ`` the KF's error
   transition since step 0: ``S ← A S Aᵀ`` at a prediction, ``S ← (I − K C) S (I − K C)ᵀ`` at
   an update; :func:`prior_share_predict`, :func:`prior_share_update`). The scenario's prior
   ``x̂0 = 0``, ``P0 = I`` is three standard deviations from the truth (``|q| ≈ 3 m``), so
   until the data outweigh it the KF's covariance understates its error and no test on that
   covariance can be trusted.
2. **The Gaussian is narrow against the range**: for each sonar,
   ``θᵢ = √tr(P⊥ᵢ) / dᵢ ≤ angle_tolerance``, with ``P⊥ᵢ`` the position covariance across
   the line of sight ``uᵢ`` (``tr P⊥ = tr P_qq − uᵢᵀ P_qq uᵢ``) and ``dᵢ`` the range, both at
   the estimate (:func:`cross_range_angle`). A range filter with a Gaussian posterior is
   only valid while the angular spread of the target's direction is small: beyond it the
   posterior is a curved shell and, as the baseline turns, can split into the two-range
   circle's mirror images, on which an EKF or UKF locks. In terms of the linearisation
   error: the second-order range term a linearisation drops is ``tr(P⊥)/(2d) = θ² d / 2``,
   so the test bounds it by a fraction of the *range*, not of the range noise.

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

Measurements (plain numpy closed loop, ``python benchmarks/estimator_regimes.py``, which
prints the commands' table; "paper" is σ = 0.1 m with q* = [−2, −2, 0] in the body frame,
"world" holds q* in the world frame; ratios are position RMSE over k ≥ 200 against the mean
per-run posterior Cramér–Rao bound):

* Test 1 (40 paper runs, test 2 at 0.25): without it (``prior_share = inf``) the EKF hands
  over at step 15 and 1 of 40 runs diverges, as does the particle filter drawn at step 0;
  with 0.3, 0.1, 0.03 the hand-over comes at step 16, 22, 28 and no EKF, UKF or particle
  filter run diverges (1.00–1.01×). The default is 0.1.
* The brief's first idea, the second-order error against the noise,
  ``tr(P⊥)/(2d) ≤ c σ/√f`` (with test 1, without test 2), fails where the noise is large: the
  KF's covariance there (∝ σ² d²) meets a threshold ∝ σ d, and the EKF's *own* steady state
  then slips onto the mirror solution. World, 20 runs: for c = 0.5, 0.75, 1, 1.5 the EKF
  diverged in 3, 6, 6, 6 runs at σ = 0.5 m and 8, 12, 17, 19 at σ = 1 m.
* Test 2 (40 runs per cell, test 1 at 0.1), EKF and UKF alike: with 0.2, 0.25 or 0.3 no run
  diverges in any cell; hand-over at step 22–23 in the paper scenario (1.01×, 1.00×), at
  22 at 2.8 m world (1.06×, 1.05×), at 24 at 14 m (1.13×, 1.17×) and 28 m (1.21×, 1.32×);
  never at σ = 1 m (the KF's 3.51×, whose own 3 of 40 runs end > 10 m off). At σ = 0.5 m
  (paper frame) 2, 14, 38 of 40 runs hand over (2.57×, 2.34×, 1.47× against the KF's
  2.60×); in the world frame none does up to 0.3, while 0.35 hands over in 15 of 40 and 3
  EKF runs (1 UKF run) diverge, 0.4 in 33 with 6 diverged. The default is 0.25.
* The EKF drops the second-order term, so for it ``second_order_tolerance`` adds the
  brief's test as well: in the Drake loop (40 runs, 28 m, q* world) the EKF with tests 1 and
  2 alone lost 1 run (seed 35: its NIS blew up at step 51, after the hand-over); with
  ``second_order_tolerance = 1`` none (1.26× the bound; still inconsistent, NEES 13.9: the
  dropped term stays comparable to the noise in its steady state). The UKF keeps the term
  and the particle filter has none to drop: they leave it out.
* The bridge (40 runs per cell, ``--bridge``; EKF with the second-order test, UKF without):
  at σ = 1 m (paper frame) a one-way bridge (no fallback) lets every run take its Gaussian
  back (median step 68), after which the UKF holds (1.05×, NEES 6.6) but the EKF does not
  (7.5×, NEES 347, 1 run lost): its steady state widens past the angle it took over at
  (0.15 gives the same; 0.1 never takes it back, 1.00×). With the fallback at 1.2 × 0.25
  rad the EKF is at 1.01× (NEES 6.1) and the UKF at 1.00× (5.9), none lost, with 16
  returns to particles per run (1.5: 1.06× and 1.01×, EKF NEES 7.0, 9 per run). σ = 0.5 m:
  EKF 1.03×, UKF 1.00× (KF 2.60×). In the paper scenario and at 2.8 and 14 m (world) the
  results are those without the bridge (it hands over from the KF directly, or within two
  steps); at 28 m the same RMSE. The default is ``fallback_factor = 1.2``.
* The NIS fallback (Drake loop, 100 runs of the attitude study's EKF, Algorithm 2
  rate-limited to 0.1 rad per step, where the excitation is weak): the estimator-health
  monitor stopped 11 runs without the bridge (RMSE 1.59 m, the EKF mostly still the KF), 33
  with the bridge but without this fallback (innovations blown up after a slip; 0.71 m), 4
  with both (0.72 m); under the information-seeking planner at that budget 5, 11 and 1. At
  σ = 0.5 and 1 m in the numpy loop it never fires.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

_I6 = np.eye(6)

#: The NIS beyond which a bridged Gaussian filter is lost: the χ²(2) quantile of 1 − 10⁻⁶
#: (−2 ln 10⁻⁶), about one false alarm per two thousand 500-step runs.
LOST_NIS = 2.0 * math.log(1e6)


def cross_range_angle(x: np.ndarray, P: np.ndarray, q_s: np.ndarray) -> np.ndarray:
    """``θᵢ = √tr(P⊥ᵢ) / dᵢ`` for both sonars (shape (2,)) [rad].

    ``dᵢ = |q ± ½ q_s|`` and the line of sight ``uᵢ`` at the estimate ``q = x[:3]``;
    ``tr P⊥ᵢ = tr P_qq − uᵢᵀ P_qq uᵢ`` the position variance across it. A range below 1 nm
    gives an infinite angle.
    """
    q = np.asarray(x, dtype=float)[:3]
    half = 0.5 * np.asarray(q_s, dtype=float).reshape(3)
    P_qq = np.asarray(P, dtype=float)[:3, :3]
    trace = float(np.trace(P_qq))
    out = np.empty(2)
    for i, r in enumerate((q + half, q - half)):
        d = float(np.linalg.norm(r))
        if d < 1e-9:
            out[i] = math.inf
            continue
        u = r / d
        out[i] = math.sqrt(max(trace - float(u @ P_qq @ u), 0.0)) / d
    return out


def second_order_range_error(x: np.ndarray, P: np.ndarray, q_s: np.ndarray) -> np.ndarray:
    """``tr(P⊥ᵢ)/(2 dᵢ)`` for both sonars (shape (2,)) [m]: the mean of the quadratic term of
    ``d(q + e) = d + uᵀe + (|e|² − (uᵀe)²)/(2d) + …`` under ``e ~ N(0, P_qq)``, the range a
    linearisation at the estimate drops (``= θ² d / 2`` with :func:`cross_range_angle`)."""
    q = np.asarray(x, dtype=float)[:3]
    half = 0.5 * np.asarray(q_s, dtype=float).reshape(3)
    angles = cross_range_angle(x, P, q_s)
    distances = np.array([np.linalg.norm(q + half), np.linalg.norm(q - half)])
    return 0.5 * angles * angles * distances


def prior_share_predict(S: np.ndarray, A: np.ndarray) -> np.ndarray:
    """The prior's share of the covariance through a prediction: ``A S Aᵀ`` (no process noise)."""
    return A @ S @ A.T


def prior_share_update(
    S: np.ndarray, P_filtered: np.ndarray, q_s: np.ndarray, Gamma: float
) -> np.ndarray:
    """Through the linear KF's update on ``Y = q_sᵀ q + v̄``: ``(I − K C) S (I − K C)ᵀ``.

    ``C = [q_sᵀ, 0]``; ``K = P Cᵀ Γ⁻¹`` from the KF's covariance *after* the update, which for
    the KF's gain ``K = P⁻ Cᵀ (C P⁻ Cᵀ + Γ)⁻¹`` is the same gain.
    """
    q_s = np.asarray(q_s, dtype=float).reshape(3)
    K = np.asarray(P_filtered, dtype=float)[:, :3] @ q_s / float(Gamma)
    I_KC = _I6.copy()
    I_KC[:, :3] -= K[:, None] * q_s
    S = I_KC @ np.asarray(S, dtype=float) @ I_KC.T
    return 0.5 * (S + S.T)


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

    def prior_forgotten(
        self, P: np.ndarray, linear_steps_done: int, prior_covariance: np.ndarray
    ) -> bool:
        """Test 1 (or ``max_linear_steps`` reached): the KF's covariance rests on its data.

        ``prior_covariance`` is the prior's share ``S`` of ``P``."""
        if self.max_linear_steps is not None and linear_steps_done >= self.max_linear_steps:
            return True
        if linear_steps_done < self.min_linear_steps:
            return False
        prior = float(np.trace(np.asarray(prior_covariance, dtype=float)[:3, :3]))
        return prior <= self.prior_share * float(np.trace(np.asarray(P, dtype=float)[:3, :3]))

    def gaussian_holds(
        self,
        x: np.ndarray,
        P: np.ndarray,
        q_s: np.ndarray,
        noise_std: np.ndarray | None = None,
    ) -> bool:
        """Test 2 and, with ``second_order_tolerance``, the second-order test (``noise_std``
        the per-sonar ``√(η/f)``): a Gaussian describes the posterior ``N(x, P)``."""
        if self.angle_tolerance is not None and not np.all(
            cross_range_angle(x, P, q_s) <= self.angle_tolerance
        ):
            return False
        if self.second_order_tolerance is None:
            return True
        if noise_std is None:
            raise ValueError("noise_std: needed with second_order_tolerance, got None")
        limit = self.second_order_tolerance * np.asarray(noise_std, dtype=float)
        return bool(np.all(second_order_range_error(x, P, q_s) <= limit))

    def fallback_due(self, x: np.ndarray, P: np.ndarray, q_s: np.ndarray) -> bool:
        """With ``particle_bridge``: a Gaussian filter's ``N(x, P)`` has become too wide for a
        Gaussian (a cross-range angle above ``fallback_factor · angle_tolerance``)."""
        if not self.particle_bridge:
            return False
        limit = self.fallback_factor * float(self.angle_tolerance)
        return bool(np.any(cross_range_angle(x, P, q_s) > limit))

    def lost(self, nis: float) -> bool:
        """With ``particle_bridge``: a Gaussian filter's innovation is beyond any chance under
        its own covariance (NIS above :data:`LOST_NIS`), as when it slips onto the mirror
        solution while its covariance stays narrow."""
        return self.particle_bridge and nis > LOST_NIS

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
        if self.max_linear_steps is not None and linear_steps_done >= self.max_linear_steps:
            return True
        if not self.prior_forgotten(P, linear_steps_done, prior_covariance):
            return False
        return self.gaussian_holds(x, P, q_s, noise_std)
