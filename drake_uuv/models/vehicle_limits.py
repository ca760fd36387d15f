"""What a thruster-driven vehicle can do: acceleration, rates and speed from its thrust limits.

Every figure is a worst case over directions in the body frame (a Fibonacci lattice on the
sphere), because the outer loop commands world-frame motion while the attitude generator
turns the body arbitrarily. "Can do" means the allocation (``ThrustAllocator``, weighted
pseudo-inverse) delivers the wrench without scaling it, i.e. its utilisation
``max_i |A⁺ τ|_i / f_max`` is at most 1.

:func:`vehicle_limits` gives each capability alone; :func:`utilisation_budget` adds up what a
commanded envelope (acceleration, speed, rate, rate steps, tilt) needs. Utilisation is a
norm of the wrench, hence subadditive, so the sum of the parts' worst cases is an upper
bound: an envelope whose total is below 1 never saturates (the sum is taken thruster by
thruster, see :func:`utilisation_budget`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from drake_uuv.models.marine_vehicle import MarineVehicleModel
from drake_uuv.models.thrust_allocation import ThrustAllocator

__all__ = [
    "VehicleLimits",
    "sphere_directions",
    "thruster_loads",
    "utilisation_budget",
    "vehicle_limits",
]


def sphere_directions(n: int = 2000) -> np.ndarray:
    """``n`` nearly uniform unit vectors (Fibonacci lattice), n×3."""
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    azimuth = math.pi * (3.0 - math.sqrt(5.0)) * i
    r = np.sqrt(1.0 - z * z)
    return np.column_stack([r * np.cos(azimuth), r * np.sin(azimuth), z])


@dataclass(frozen=True)
class VehicleLimits:
    """Worst-direction capabilities, each alone (from rest, upright, no other demand)."""

    acceleration: float  # [m/s²] linear acceleration of U in any direction, from rest
    angular_acceleration: float  # [rad/s²] about any axis, at rest
    speed: float  # [m/s] steady speed in any direction (thrust = drag)
    angular_rate: float  # [rad/s] steady rotation about any axis (thrust = drag + gyroscopic)


def _largest(utilisation, directions: np.ndarray, upper: float) -> np.ndarray:
    """Per direction, the largest x ≤ upper with ``utilisation(x, directions) ≤ 1`` (bisection).

    ``utilisation`` must grow with x along each direction (drag does).
    """
    low, high = np.zeros(len(directions)), np.full(len(directions), upper)
    for _ in range(60):
        middle = 0.5 * (low + high)
        ok = utilisation(middle, directions) <= 1.0
        low, high = np.where(ok, middle, low), np.where(ok, high, middle)
    return low


def _coriolis(model: MarineVehicleModel, nu: np.ndarray) -> np.ndarray:
    """``C(ν) ν`` for the rows of ν (Kirchhoff's form, as ``MarineVehicleModel.coriolis_force``)."""
    p = nu @ model.M.T
    v, w = nu[:, :3], nu[:, 3:]
    return np.hstack([np.cross(w, p[:, :3]), np.cross(w, p[:, 3:]) + np.cross(v, p[:, :3])])


def _drag(model: MarineVehicleModel, nu: np.ndarray) -> np.ndarray:
    """``C(ν) ν + D(ν) ν`` for the rows of ν (no restoring: upright and neutral here)."""
    damping = (model.linear_damping + model.quadratic_damping * np.abs(nu)) * nu
    return _coriolis(model, nu) + damping


def _per_thruster(allocator: ThrustAllocator, wrenches: np.ndarray) -> np.ndarray:
    """The worst ``|A⁺ τ|_i / f_max`` over the rows τ, for each thruster i."""
    return np.abs(np.asarray(wrenches) @ allocator.A_pinv.T).max(axis=0) / allocator.max_thrust


def vehicle_limits(
    model: MarineVehicleModel, allocator: ThrustAllocator, n: int = 2000
) -> VehicleLimits:
    """The worst-direction capabilities of a vehicle (see the module notes)."""
    d = sphere_directions(n)
    zeros = np.zeros_like(d)
    # M ν̇ for ν̇ = [a d, 0] and [0, α d]: utilisation is linear in a and α.
    per_acceleration = allocator.utilisation(np.hstack([d, zeros]) @ model.M.T)
    per_angular_acceleration = allocator.utilisation(np.hstack([zeros, d]) @ model.M.T)

    def speed_use(v: np.ndarray, dirs: np.ndarray) -> np.ndarray:
        return allocator.utilisation(_drag(model, np.hstack([v[:, None] * dirs, zeros])))

    def rate_use(w: np.ndarray, dirs: np.ndarray) -> np.ndarray:
        return allocator.utilisation(_drag(model, np.hstack([zeros, w[:, None] * dirs])))

    return VehicleLimits(
        acceleration=float(1.0 / per_acceleration.max()),
        angular_acceleration=float(1.0 / per_angular_acceleration.max()),
        speed=float(_largest(speed_use, d, 10.0).min()),
        angular_rate=float(_largest(rate_use, d, 100.0).min()),
    )


def thruster_loads(
    model: MarineVehicleModel,
    allocator: ThrustAllocator,
    *,
    acceleration: float,
    speed: float,
    angular_rate: float,
    rate_step: float,
    tilt: float,
    attitude_bandwidth: float,
    attitude_damping_ratio: float,
    n: int = 400,
) -> dict[str, np.ndarray]:
    """Each demand's worst load on each thruster over directions, ``max |A⁺ τ|_i / f_max``:
    one array (per thruster) for each demand of an operating envelope,

    - ``acceleration`` [m/s²]: ``M [a d; 0]``;
    - ``speed`` [m/s]: drag ``D(ν) ν`` at ``v d``;
    - ``angular_rate`` [rad/s]: drag and gyroscopic moments ``(C + D)(ν) ν`` at ``ω d``;
    - ``coupling``: the Coriolis terms of moving and turning at once (``C(ν) ν`` at
      ``[v d1, ω d2]`` minus both alone), over all pairs of directions;
    - ``rate_step`` [rad/s]: a step Δω of the commanded rate, which the low-level attitude
      loop first meets with ``M_rot 2ζω Δω`` (its rate-error gain);
    - ``tilt`` [rad]: the restoring moment ``g(η)`` at that tilt from upright.

    The acceleration's load is linear in ``acceleration``; no other load depends on it.
    ``n`` directions sample the sphere (``n/4`` squared pairs for the coupling).
    """
    d = sphere_directions(n)
    zeros = np.zeros_like(d)
    loads = {
        "acceleration": acceleration * _per_thruster(allocator, np.hstack([d, zeros]) @ model.M.T),
        "speed": _per_thruster(allocator, _drag(model, np.hstack([speed * d, zeros]))),
        "angular_rate": _per_thruster(
            allocator, _drag(model, np.hstack([zeros, angular_rate * d]))
        ),
    }
    pair = sphere_directions(max(n // 4, 2))
    v, w = np.repeat(speed * pair, len(pair), 0), np.tile(angular_rate * pair, (len(pair), 1))
    coupling = (
        _coriolis(model, np.hstack([v, w]))
        - _coriolis(model, np.hstack([v, 0.0 * w]))
        - _coriolis(model, np.hstack([0.0 * v, w]))
    )
    loads["coupling"] = _per_thruster(allocator, coupling)
    gain = 2.0 * attitude_damping_ratio * attitude_bandwidth
    step = np.hstack([zeros, d]) @ model.M.T
    loads["rate_step"] = rate_step * gain * _per_thruster(allocator, step)
    # Tilted by `tilt` about any horizontal axis: the world's up in the body is k_B.
    azimuth = np.linspace(0.0, 2.0 * math.pi, 73)
    k_B = np.column_stack(
        [
            math.sin(tilt) * np.cos(azimuth),
            math.sin(tilt) * np.sin(azimuth),
            np.full_like(azimuth, math.cos(tilt)),
        ]
    )
    rows = np.zeros((len(k_B), 3, 3))
    rows[:, 2] = k_B  # restoring_force reads only the third row of R_WB
    loads["tilt"] = _per_thruster(allocator, [model.restoring_force(R) for R in rows])
    return loads


def utilisation_budget(
    model: MarineVehicleModel, allocator: ThrustAllocator, **envelope: float
) -> dict[str, float]:
    """Worst-case utilisation of each demand of an operating envelope (the keywords of
    :func:`thruster_loads`), and a bound of their sum.

    Returns each part's worst utilisation and ``total``: per thruster, the sum of each part's
    worst load on it, maximised over thrusters. That bounds the utilisation of any
    combination of the demands (each thruster's load is a sum of the parts' loads), and is
    far tighter than the sum of the parts when they load different thrusters (a rate step in
    yaw and a tilt load the angled and the vertical group).
    """
    loads = thruster_loads(model, allocator, **envelope)
    parts = {name: float(load.max()) for name, load in loads.items()}
    parts["total"] = float(sum(loads.values()).max())
    return parts
