"""One step of a Gaussian estimator with its ranges at their own ping times (one run: late
ranges step one run at a time for now; the estimator's hooks take it as a batch of one).

The step's augmented state ``z = [x_k, ū_k]`` (:mod:`drake_uuv.models.timing`) takes each
instant's ranges through the estimator's own update hook on ``y = x(τ)`` (so the paper's KF,
the EKF, the IEKF and the UKF each keep their update), conditioned back onto ``z``; the step
ends at ``x_{k+1} = G(t) z + B(t) a_k``. An estimator that needs both ranges at one instant
(the paper's KF, a linear start) gets the earlier range carried to the later ping time.
"""

from dataclasses import dataclass, field

import numpy as np

from drake_uuv.estimators.contract import Estimate, MeasurementUpdate, Ranges
from drake_uuv.estimators.ping_window import StepRanges
from drake_uuv.models.measurement import GATED, NO_ARRIVAL, VALID
from drake_uuv.models.timing import augment, carried_range, transition, update_through


@dataclass
class InstantOutcome:
    """An instant's update: its status (VALID or GATED), NIS and innovation dimension, and
    whether it holds a range that arrived at this tick."""

    status: int
    nis: float
    dof: int
    new: bool
    q_s: np.ndarray | None = None
    gamma: float | None = None


@dataclass
class StepOutcome:
    """The belief at the step's end (stored frame) and its instants' updates."""

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
    """The step's usable ranges grouped by ping time, earliest first (``paired``: one instant
    at the later time holding both, when both returned; none with one)."""
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


def gaussian_step(
    host, context, x: np.ndarray, P: np.ndarray, step: StepRanges, with_ranges: bool = True
) -> StepOutcome:
    """Steps the Gaussian belief ``N(x, P)`` at ``t_k`` (stored frame) through ``step`` (its
    ranges left out without ``with_ranges``: the prediction alone)."""
    t = host.time_step
    model = host.error_model
    _, _, W = host.model
    navigated = model.navigated_motion
    a = np.zeros(3) if navigated else step.acceleration
    sigma_theta = model.attitude_covariance(step.R_start)
    extra_W = model.acceleration_covariance(a, sigma_theta)
    P = P.copy()
    velocity = model.velocity_covariance(step.start[3:], sigma_theta)
    if velocity is not None:  # the dead-reckoned position's walk over the step
        P[:3, :3] += (t * t) * velocity
    z, P_z = augment(x, P, W if extra_W is None else W + extra_W)

    def at(tau: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(G, c, q_s)``: the relative state at τ is ``G z + c``."""
        G, B = transition(tau)
        c = B @ a
        if navigated:
            c = c + step.vehicle(tau, t)
        return G, c, step.attitude(tau, t) @ host.baseline

    outcome = StepOutcome(x, P)
    paired = bool(np.any(host.needs_both_ranges(context)))
    for instant in instants(step, paired) if with_ranges else []:
        G, c, q_s = at(instant.tau)
        if paired and len(instant.sonars) == 2 and step.tau[0] != step.tau[1]:
            early = int(np.argmin(step.tau))
            shift, variance = carried_range(z, P_z, early, at(float(step.tau[early])), (G, c, q_s))
            instant.samples[early] += shift
            instant.extra[early] += variance
        y = G @ z + c
        P_y = G @ P_z @ G.T
        ranges = batch_of_one(instant_ranges(host, instant, q_s, step))
        update: MeasurementUpdate | None = host.measurement_update(
            context, Estimate(y[np.newaxis], P_y[np.newaxis]), ranges
        )
        if update is None or not update.updated[0]:
            continue
        nis, dof = float(update.nis[0]), int(update.dof[0])
        gamma = None if update.gamma is None else float(update.gamma[0])
        new = bool(np.any(step.new[instant.sonars]))
        if nis > host.gate_threshold(dof):
            outcome.updates.append(InstantOutcome(GATED, nis, dof, new))
            continue
        z, P_z = update_through(z, P_z, G, y, update.x[0], update.P[0])
        outcome.updates.append(InstantOutcome(VALID, nis, dof, new, q_s, gamma))
    G, B = transition(t)
    outcome.x = G @ z + B @ a
    outcome.P = G @ P_z @ G.T
    outcome.P = 0.5 * (outcome.P + outcome.P.T)
    return outcome


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
