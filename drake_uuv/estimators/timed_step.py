"""One step of a Gaussian estimator with its ranges at their own ping times, for a batch of
runs.

The step's augmented state ``z = [x_k, ū_k]`` (:mod:`drake_uuv.models.timing`) takes each
instant's ranges through the estimator's own update hook on ``y = x(τ)`` (so the paper's KF,
the EKF, the IEKF and the UKF each keep their update), conditioned back onto ``z``; the step
ends at ``x_{k+1} = G(t) z + B(t) a_k``. An estimator that needs both ranges at one instant
(the paper's KF, a linear start) gets the earlier range carried to the later ping time.

Over a batch each run's ranges fall in at most two instants of the step, its earlier and its
later ping time: the batch takes its runs' earlier instants at once, then their later ones
(each run at its own τ; a run without a range at an instant is left as it is, by a mask).
:func:`instants` and :func:`instant_ranges` are one run's, for the particle cloud.
"""

from dataclasses import dataclass, field

import numpy as np
from numba import njit

from drake_uuv.estimators.contract import Estimate, MeasurementUpdate, Ranges
from drake_uuv.estimators.ping_window import StepBatch, StepRanges
from drake_uuv.models.filter_runs import update_through_runs
from drake_uuv.models.measurement import GATED, NO_ARRIVAL, VALID
from drake_uuv.models.timing import carried_range_runs, transition, transition_runs

#: An instant's status of a run without a range there.
NO_UPDATE = -1.0


@dataclass
class InstantOutcome:
    """An instant's updates of each run: status (B; VALID, GATED or :data:`NO_UPDATE`), NIS
    and innovation dimension (B), whether it holds a range that arrived at this tick (B), the
    world baseline there (B, 3) and, for a linear update on the paper's Y, its Γ (B)."""

    status: np.ndarray
    nis: np.ndarray
    dof: np.ndarray
    new: np.ndarray
    q_s: np.ndarray | None = None
    gamma: np.ndarray | None = None


@dataclass
class StepOutcome:
    """The beliefs at the step's end (stored frame; (B, 6), (B, 6, 6)) and its instants'
    updates."""

    x: np.ndarray
    P: np.ndarray
    updates: list[InstantOutcome] = field(default_factory=list)


@dataclass
class _Instant:
    tau: float
    sonars: list[int]
    samples: np.ndarray  # 2×f, NaN outside ``sonars``
    extra: np.ndarray  # extra variance per sonar


def instants(step: StepRanges, paired: bool) -> list[_Instant]:
    """One run's usable ranges of ``step`` grouped by ping time, earliest first (``paired``:
    one instant at the later time holding both, when both returned; none with one)."""
    valid = [i for i in range(2) if step.valid(i)]
    if paired and len(valid) < 2:
        return []
    groups: dict[float, list[int]] = {}
    for i in valid:
        groups.setdefault(float(step.tau[i]), []).append(i)
    if paired and len(groups) > 1:
        return [_Instant(max(groups), valid, step.samples.copy(), np.zeros(2))]
    out = []
    for tau in sorted(groups):
        samples = np.full_like(step.samples, np.nan)
        samples[groups[tau]] = step.samples[groups[tau]]
        out.append(_Instant(tau, groups[tau], samples, np.zeros(2)))
    return out


def _instant_masks(
    step: StepBatch, paired: np.ndarray
) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray], np.ndarray, np.ndarray]:
    """Each run's earlier and later instant, ``(use (B, 2), τ (B))`` each, the runs whose
    earlier range is carried to the later instant (paired, both returned, τ differ) and each
    run's earlier sonar."""
    B = len(paired)
    use_early, use_late = np.zeros((B, 2), dtype=bool), np.zeros((B, 2), dtype=bool)
    tau_early, tau_late = np.zeros(B), np.zeros(B)
    carried, early = np.zeros(B, dtype=bool), np.zeros(B, dtype=np.intp)
    _instants_of_runs(
        step.valid(), step.tau, paired, use_early, tau_early, use_late, tau_late, carried, early
    )
    return (use_early, tau_early), (use_late, tau_late), carried, early


@njit(cache=True)
def _instants_of_runs(valid, tau, paired, use_early, tau_early, use_late, tau_late, carried, early):
    for r in range(valid.shape[0]):
        first = 0 if tau[r, 0] < tau[r, 1] else 1
        early[r] = first
        both = valid[r, 0] and valid[r, 1]
        differ = both and tau[r, 0] != tau[r, 1]
        if paired[r]:  # both at the later time, the earlier carried there; none with one
            if both:
                use_late[r, 0] = use_late[r, 1] = True
                tau_late[r] = max(tau[r, 0], tau[r, 1])
                carried[r] = differ
            continue
        if differ:  # the earlier range, then the later
            use_early[r, first] = True
            tau_early[r] = tau[r, first]
            use_late[r, 1 - first] = True
            tau_late[r] = tau[r, 1 - first]
        elif both:
            use_late[r, 0] = use_late[r, 1] = True
            tau_late[r] = tau[r, 0]
        else:
            for i in range(2):
                if valid[r, i]:
                    use_late[r, i] = True
                    tau_late[r] = tau[r, i]


def gaussian_step(
    host,
    context,
    x: np.ndarray,
    P: np.ndarray,
    step: StepBatch,
    with_ranges: np.ndarray | bool = True,
) -> StepOutcome:
    """Steps the Gaussian beliefs ``N(x, P)`` ((B, 6), (B, 6, 6)) at ``t_k`` (stored frame)
    through ``step`` (its ranges left out of the runs without ``with_ranges`` (B): the
    prediction alone)."""
    t = host.time_step
    model = host.error_model
    _, _, W = host.model
    B = len(x)
    navigated = model.navigated_motion
    a = np.zeros((B, 3)) if navigated else step.acceleration
    sigma_theta = model.attitude_covariance(step.R_start)
    extra_W = model.acceleration_covariance(a, sigma_theta)
    P = P.copy()
    velocity = model.velocity_covariance(step.start[:, 3:], sigma_theta)
    if velocity is not None:  # the dead-reckoned position's walk over the step
        P[:, :3, :3] += (t * t) * velocity
    z = np.concatenate([x, np.zeros((B, 3))], axis=1)
    P_z = np.zeros((B, 9, 9))
    P_z[:, :6, :6] = P
    P_z[:, 6:, 6:] = W if extra_W is None else W + extra_W

    def at(tau: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(G, c, q_s)``: the relative states at τ (B) are ``G z + c``."""
        G, B_tau = transition_runs(tau)
        c = (B_tau @ a[:, :, np.newaxis])[:, :, 0]
        if navigated:
            c = c + step.vehicle(tau, t)
        q_s = (step.attitude(tau, t) * host.baseline).sum(axis=2)
        return G, c, q_s

    outcome = StepOutcome(x, P)
    paired = np.zeros(B, dtype=bool) | host.needs_both_ranges(context)
    ranges_on = np.zeros(B, dtype=bool) | with_ranges
    first, second, carried, early = _instant_masks(step, paired)
    f = step.samples.shape[2]
    for index, (use, tau) in enumerate((first, second)):
        use = use & ranges_on[:, np.newaxis]
        if not use.any():  # no run has a range at this instant (the same numbers)
            continue
        G, c, q_s = at(tau)
        samples = np.where(use[:, :, np.newaxis], step.samples, np.nan)
        extra = np.zeros((B, 2))
        carry = carried & use.all(axis=1)
        if index == 1 and carry.any():
            shift, variance = carried_range_runs(z, P_z, early, at(step.tau[np.arange(B), early]),
                                                 (G, c, q_s))  # fmt: skip
            rows = np.flatnonzero(carry)
            samples[rows, early[rows]] += shift[rows, np.newaxis]
            extra[rows, early[rows]] += variance[rows]
        y = (G @ z[:, :, np.newaxis])[:, :, 0] + c
        P_y = G @ P_z @ np.swapaxes(G, 1, 2)
        ranges = _instant_ranges_runs(host, samples, use, q_s, step.attitude(tau, t), extra, f)
        update: MeasurementUpdate | None = host.measurement_update(
            context, Estimate(y, P_y), ranges
        )
        if update is None:
            continue
        updated = update.updated & use.any(axis=1)
        gated = updated & (update.nis > host.gate_thresholds(update.dof))
        accept = updated & ~gated
        z, P_z = update_through_runs(z, P_z, G, y, update.x, update.P, accept)
        status = np.where(accept, float(VALID), np.where(gated, float(GATED), NO_UPDATE))
        new = (step.new & use).any(axis=1)
        outcome.updates.append(
            InstantOutcome(status, update.nis, update.dof, new, q_s, update.gamma)
        )
    G, B_t = transition(t)
    outcome.x = (G @ z[:, :, np.newaxis])[:, :, 0] + (B_t @ a[:, :, np.newaxis])[:, :, 0]
    P_next = G @ P_z @ G.T
    outcome.P = 0.5 * (P_next + np.swapaxes(P_next, 1, 2))
    return outcome


def _instant_ranges_runs(
    host,
    samples: np.ndarray,
    use: np.ndarray,
    q_s: np.ndarray,
    R_nav: np.ndarray,
    extra: np.ndarray,
    f: int,
) -> Ranges:
    """The ranges of the runs' instant (``samples`` NaN outside ``use``), with the error
    model's noise."""
    model = host.error_model
    status = np.where(use, float(VALID), float(NO_ARRIVAL))
    z = samples.sum(axis=2) / f
    sound = model.range_variance(z)
    if sound is not None:
        extra = extra + sound
    return Ranges(samples, z, use, status, q_s, model.attitude_covariance(R_nav), extra)


def batch_of_one(ranges: Ranges) -> Ranges:
    """One instant's ranges (without a run axis) as a batch of one run."""

    def one(value: np.ndarray | None) -> np.ndarray | None:
        return None if value is None else np.asarray(value)[np.newaxis]

    return Ranges(
        one(ranges.samples), one(ranges.z), one(ranges.valid), one(ranges.status),
        one(ranges.q_s), one(ranges.attitude_covariance), one(ranges.extra_variance),
    )  # fmt: skip


def instant_ranges(host, instant: _Instant, q_s: np.ndarray, step: StepRanges) -> Ranges:
    """The ranges of one instant of a step, with the error model's noise."""
    samples = instant.samples
    valid = np.zeros(2, dtype=bool)
    valid[instant.sonars] = True
    status = np.where(valid, VALID, NO_ARRIVAL).astype(float)
    z = samples.mean(axis=1)
    model = host.error_model
    extra = instant.extra.copy()
    sound = model.range_variance(z)
    if sound is not None:
        extra += sound
    R_nav = step.attitude(instant.tau, host.time_step)
    return Ranges(
        samples, z, valid, status, q_s, model.attitude_covariance(R_nav),
        extra if extra.any() else None,
    )  # fmt: skip
