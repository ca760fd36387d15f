"""The information-seeking planner's constraints and choice: its plan kernel (numba).

:class:`~drake_uuv.models.information_planner.InformationSeekingPlanner` scores each
candidate over its horizon (:mod:`drake_uuv.models.information_scoring`); a candidate is
then admissible within the reference limit and the excitation floor, and the best admissible
one is taken. :func:`plan_kernel` does this for every run (:func:`_plan_run` each,
:func:`_reference_limit`, :func:`_excitation_floor` and :func:`_choose` its stages);
:func:`candidates_kernel` gives each run's candidates.

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

numba's cache keys a compiled kernel on its own file's source only (a change in a function it
calls from another file goes unnoticed): after changing ``information_scoring.py`` or
``attitude_plans.py``, delete this file's cache
(``drake_uuv/models/__pycache__/information_choice.*.nb[ci]``).
"""

import math

import numpy as np
from numba import njit

from drake_uuv.models.attitude_plans import exp_so3_kernel, matmul3_kernel
from drake_uuv.models.information_scoring import (
    _CAP,
    _COAST,
    _EPSILON,
    _FLOOR,
    _MAX_REFERENCE,
    _NORM,
    _PREDICTION,
    _T,
    _THRESHOLD,
    _THRESHOLD_SET,
    _TIE,
    _WINDOW,
    _buffers,
    _candidate_baselines,
    _rotate,
    _score_candidates,
    _symmetric_eigen_3,
)


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
def candidates_kernel(options, parameters, b, candidates, R_WB):  # pragma: no cover - compiled
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
    n = candidates.shape[0]
    t = parameters[_T]
    buffers, firsts, values, flags, vectors, small = workspace
    scores, objective, acceleration, excitation = values[0], values[1], values[2], values[3]
    admissible, enough = flags[0], flags[1]
    own_rotation, baselines = vectors[0], vectors[1]
    baseline, r_q, G, L, turn = small[0, 0], small[0, 1], small[1], small[2], small[3]
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

    limit = parameters[_MAX_REFERENCE]
    if limit < np.inf and known > 0.0:  # the reference limit, when the run knows R(k−1)
        _reference_limit(rotation, r_q, q_star, Rp, t, limit, acceleration, admissible)
    if parameters[_FLOOR] > 0.0:
        _excitation_floor(options, parameters, H, filled, baseline, baselines, G, L,
                          admissible, enough, excitation, objective)  # fmt: skip
    index = _choose(admissible, objective)
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
def _reference_limit(
    rotation, r_q, q_star, Rp, t, limit, acceleration, admissible
):  # pragma: no cover - compiled
    """The reference limit: each candidate's ``|R(k+1) q* − 2 R(k) q* + R(k−1) q*| / t²`` into
    ``acceleration`` (``r_q`` is ``R(k) q*``, ``Rp`` is ``R(k−1)``), admissible where within
    ``limit``; if none is, the least demanding candidate(s)."""
    n = rotation.shape[0]
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


@njit(cache=True, error_model="numpy")
def _excitation_floor(
    options, parameters, H, filled, baseline, baselines, G, L, admissible, enough, excitation,
    objective,
):  # pragma: no cover - compiled  # fmt: skip
    """The excitation floor on the trailing planning window ending with each candidate: its
    smallest eigenvalue into ``excitation``, admissible where it meets the floor (its share
    while the window fills); if none does, the objective becomes the novelty of the
    candidate's baseline, ``x_cᵀ (Λ + εI)⁻¹ x_c`` (``G``, ``L``: 3×3 scratch)."""
    n, kept = baselines.shape[0], H.shape[0]
    floor = parameters[_FLOOR]
    window = options[_WINDOW]
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


@njit(cache=True, error_model="numpy")
def _choose(admissible, objective):  # pragma: no cover - compiled
    """The index of the best admissible candidate by ``objective`` (NaN counts as best, as
    argmax). Candidates within rounding of the best are ties, taken in grid order: the first
    one. (The first step's novelty is exactly equal around a ring, so otherwise rounding
    would choose.)"""
    n = objective.shape[0]
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
    return index


@njit(cache=True, error_model="numpy")
def plan_kernel(
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
