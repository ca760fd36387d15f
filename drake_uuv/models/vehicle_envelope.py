"""The paper's closed loop on a thruster-driven vehicle: limits derived from the vehicle.

The outer loop (attitude generator, tracking law) knows nothing of thrusters; it can only be
told a rate limit (``attitude.max_angular_rate``) and an acceleration limit
(``tracking.max_acceleration``). :func:`feasible_limits` derives both from the vehicle, in
three steps that each use one figure of :mod:`drake_uuv.models.vehicle_limits`:

1. **Speed budget** ``v_s``: half the vehicle's worst-direction top speed. Drag grows with the
   square of the speed, so cruising at half the top speed takes about a quarter of the
   thrust and leaves the rest for turning and accelerating.
2. **Rate limit** ``ω``: Algorithm 2's baseline direction ``ζ(k)`` sweeps its azimuth at
   ``ρπ/t`` (one turn every ``2/ρ`` steps), the excitation that makes the state observable;
   ``ω`` is that rate rounded *up* to 0.1 rad/s, so the vehicle keeps up with the sweep and
   only the plan's elevation nod and the minimal rotation's jumps are clipped.
3. **Acceleration limit** ``a``: the largest acceleration whose worst-case thrust
   utilisation (:func:`~drake_uuv.models.vehicle_limits.utilisation_budget`), together with
   cruising at ``v_s``, turning at ``ω``, rate steps of ``2ω`` (a rate-limited plan reverses
   its rate) and the restoring moment at the plan's worst tilt, stays at most 1; rounded
   *down* to 0.1 m/s².

Nothing in the envelope saturates a thruster, whatever the directions. The tracking law's
LQR weights then follow Bryson's rule with the same figures (acceptable relative speed
``v_s``, acceptable acceleration ``a``) instead of its defaults (2 m/s, 3.2 m/s²), which ask
for relative speeds beyond what the vehicle can swim.

What the envelope cannot cover is the target: the paper's target is a velocity random walk
whose speed grows as ``√(|v̄(0)|² + k t² tr W)`` (:func:`target_speed_rms`), and once it
swims faster than the vehicle's top speed no configuration can hold station on it
(:func:`target_speed_exceedance`). :func:`followable_target_scale` gives the factor on W of
a target the vehicle can follow: one whose RMS speed at the end of the run is ``v_s``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from drake_uuv.models.attitude_plans import trajectory_attitude
from drake_uuv.models.marine_vehicle import MarineVehicleModel
from drake_uuv.models.thrust_allocation import ThrustAllocator
from drake_uuv.models.vehicle_limits import (
    VehicleLimits,
    thruster_loads,
    utilisation_budget,
    vehicle_limits,
)

__all__ = [
    "FeasibleLimits",
    "feasible_limits",
    "followable_target_scale",
    "largest_acceleration",
    "plan_max_tilt",
    "target_speed_exceedance",
    "target_speed_rms",
]


def plan_max_tilt(
    baseline_B: np.ndarray, rho: float, h_amplitude: float, h_frequency: float, steps: int
) -> float:
    """Largest angle [rad] between the body's z axis and the world's up over Algorithm 2's
    attitudes ``R̄(0..steps−1)`` (:func:`~drake_uuv.models.attitude_plans.trajectory_attitude`).
    """
    b = np.asarray(baseline_B, dtype=float)
    cosines = [trajectory_attitude(k, b, rho, h_amplitude, h_frequency)[2, 2] for k in range(steps)]
    return float(np.arccos(np.clip(min(cosines), -1.0, 1.0)))


def largest_acceleration(
    model: MarineVehicleModel, allocator: ThrustAllocator, *, upper: float = 10.0, **demands: float
) -> float:
    """The largest acceleration [m/s²] up to ``upper`` whose :func:`utilisation_budget` total,
    with the other ``demands`` (the keywords of
    :func:`~drake_uuv.models.vehicle_limits.thruster_loads` but ``acceleration``: ``speed``,
    ``angular_rate``, ``rate_step``, ``tilt``, ``attitude_bandwidth``,
    ``attitude_damping_ratio``), is at most 1; 0 if the other demands alone exceed the thrust.

    The total is ``max_i (a A_i + R_i)`` over thrusters i, with ``A_i`` the load of a unit
    acceleration and ``R_i`` the other demands' summed load, so the answer is in closed form:
    ``min_i (1 − R_i) / A_i``.
    """
    loads = thruster_loads(model, allocator, acceleration=1.0, **demands)
    per_unit = loads.pop("acceleration")
    rest = sum(loads.values())
    if rest.max() > 1.0:
        return 0.0
    pushed = per_unit > 0.0  # a thruster the acceleration does not load never limits it
    return float(np.min((1.0 - rest[pushed]) / per_unit[pushed], initial=upper))


@dataclass(frozen=True)
class FeasibleLimits:
    """The derived operating envelope (see the module notes) and what it sets."""

    limits: VehicleLimits  # the vehicle's worst-direction capabilities, each alone
    speed_budget: float  # v_s [m/s]: half the worst-direction top speed
    sweep_rate: float  # ρπ/t [rad/s]: Algorithm 2's azimuth sweep
    angular_rate: float  # ω [rad/s]: attitude.max_angular_rate
    tilt: float  # [rad] worst tilt whose restoring moment the budget carries
    acceleration_exact: float  # [m/s²] the budget's largest acceleration at (v_s, ω, 2ω, tilt)
    acceleration: float  # [m/s²] tracking.max_acceleration (rounded down)
    budget: dict[str, float] = field(default_factory=dict)  # utilisation at the envelope

    @property
    def velocity_weight(self) -> float:
        """Bryson's rule: ``1/v_s²`` on the relative velocity error."""
        return 1.0 / self.speed_budget**2

    @property
    def input_weight(self) -> float:
        """Bryson's rule: ``1/a²`` on the world acceleration."""
        return 1.0 / self.acceleration**2

    def overrides(self) -> tuple[str, ...]:
        """The ``--set`` overrides of the feasible configuration: the LQR law with q* fixed in
        the world (a body-fixed q* turning at ω would need ``|q*| ω`` more speed), the rate
        and acceleration limits, and Bryson's weights."""
        return (
            "tracking=!LqrTracking",
            "tracking.reference_frame=world",
            f"tracking.max_acceleration={self.acceleration:g}",
            f"tracking.velocity_weight={self.velocity_weight:.4g}",
            f"tracking.input_weight={self.input_weight:.4g}",
            f"attitude.max_angular_rate={self.angular_rate:g}",
        )


def feasible_limits(
    model: MarineVehicleModel,
    allocator: ThrustAllocator,
    *,
    attitude_bandwidth: float,
    attitude_damping_ratio: float,
    time_step: float,
    rho: float,
    max_tilt: float,
) -> FeasibleLimits:
    """The envelope of the module notes for a vehicle and Algorithm 2 with ``rho`` at period
    ``time_step``; ``max_tilt`` [rad] is the plan's worst tilt (:func:`plan_max_tilt`): the
    restoring moment is largest at π/2, so a plan that passes it is budgeted there."""
    if not (math.isfinite(time_step) and time_step > 0.0):
        raise ValueError(f"time_step: must be > 0, got {time_step!r}")
    if not (math.isfinite(rho) and rho > 0.0):
        raise ValueError(f"rho: must be > 0, got {rho!r}")
    if not (math.isfinite(max_tilt) and 0.0 <= max_tilt <= math.pi):
        raise ValueError(f"max_tilt: must be in [0, π], got {max_tilt!r}")
    limits = vehicle_limits(model, allocator)
    speed = 0.5 * limits.speed
    sweep = rho * math.pi / time_step
    # Round to 0.1 with a little slack for the floating-point product (0.3000000001 → 0.3).
    rate = math.ceil(sweep * 10.0 - 1e-9) / 10.0
    tilt = min(max_tilt, 0.5 * math.pi)
    demands = dict(
        speed=speed,
        angular_rate=rate,
        rate_step=2.0 * rate,
        tilt=tilt,
        attitude_bandwidth=attitude_bandwidth,
        attitude_damping_ratio=attitude_damping_ratio,
    )
    exact = largest_acceleration(model, allocator, **demands, upper=limits.acceleration)
    acceleration = math.floor(exact * 10.0 + 1e-9) / 10.0
    if acceleration <= 0.0:
        raise ValueError(
            f"max_tilt: the vehicle has no acceleration left at speed {speed:.3g} m/s, rate "
            f"{rate:g} rad/s and tilt {tilt:.3g} rad, got {max_tilt!r}"
        )
    budget = utilisation_budget(model, allocator, acceleration=acceleration, **demands)
    return FeasibleLimits(limits, speed, sweep, rate, tilt, exact, acceleration, budget)


def target_speed_rms(
    initial_velocity: np.ndarray, acceleration_covariance: np.ndarray, time_step: float, k: int
) -> float:
    """RMS speed [m/s] of the paper's random-walk target at step k:
    ``√(|v̄(0)|² + k t² tr W)`` (its velocity gains ``t ū``, ``ū ~ N(0, W)``, each step)."""
    v0 = np.asarray(initial_velocity, dtype=float)
    W = np.asarray(acceleration_covariance, dtype=float)
    return float(math.sqrt(v0 @ v0 + k * time_step**2 * np.trace(W)))


def target_speed_exceedance(
    initial_velocity: np.ndarray,
    acceleration_covariance: np.ndarray,
    time_step: float,
    steps: int,
    start: int,
    speed: float,
    samples: int = 4000,
    seed: int = 0,
) -> tuple[float, float]:
    """How often the paper's target is faster than ``speed``, over steps ``start..steps−1``:
    ``(fraction of steps, fraction of runs with any such step)``, from ``samples`` seeded
    draws of the target's velocity random walk."""
    rng = np.random.default_rng(seed)
    L = np.linalg.cholesky(np.asarray(acceleration_covariance, dtype=float))
    v0 = np.asarray(initial_velocity, dtype=float)
    # v̄(k) = v̄(0) + t Σ_{j<k} ū(j): steps 1..steps−1 need steps−1 increments.
    increments = time_step * rng.standard_normal((samples, steps - 1, 3)) @ L.T
    velocity = v0 + np.concatenate([np.zeros((samples, 1, 3)), np.cumsum(increments, 1)], 1)
    fast = np.linalg.norm(velocity[:, start:], axis=2) > speed
    return float(np.mean(fast)), float(np.mean(np.any(fast, axis=1)))


def followable_target_scale(
    initial_velocity: np.ndarray,
    acceleration_covariance: np.ndarray,
    time_step: float,
    steps: int,
    speed: float,
) -> float:
    """The factor ``s`` on W for which the target's RMS speed at the last step ``steps − 1``
    is ``speed``: ``s = (speed² − |v̄(0)|²) / ((steps − 1) t² tr W)`` (:func:`target_speed_rms`)."""
    v0 = np.asarray(initial_velocity, dtype=float)
    if not (math.isfinite(speed) and speed * speed > v0 @ v0):
        raise ValueError(
            f"speed: must exceed the target's initial speed {math.sqrt(v0 @ v0):.3g} m/s, "
            f"got {speed!r}"
        )
    if steps < 2:
        raise ValueError(f"steps: must be ≥ 2, got {steps!r}")
    trace = float(np.trace(np.asarray(acceleration_covariance, dtype=float)))
    return (speed * speed - v0 @ v0) / ((steps - 1) * time_step**2 * trace)
