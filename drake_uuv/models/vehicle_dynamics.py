"""The thruster-driven vehicle's state equation on Python floats, and a fixed step of it.

State ``x = [p_WU (3), q_WB (4: w, x, y, z), ν_B (6: v_B, ω_B), f (n, with a thrust lag only)]``
and, with ``f_cmd`` the commanded thrusts and ``sat`` their clip to ``±f_max``,

    ṗ_WU = R(q) v_B
    q̇_WB = ½ q ⊗ [0, ω_B] + λ (1 − |q|²) q                   (quaternion_derivative)
    ν̇    = M⁻¹ (A f − C(ν) ν − D(ν) ν − g(η))                 (Fossen, MarineVehicleModel)
    ḟ    = (sat(f_cmd) − f) / T   with a lag T > 0; without one f = sat(f_cmd).

Python floats, not numpy: this runs a few times per controller tick, on 3- to 13-vectors, where
numpy's per-call overhead costs more than the arithmetic. ``M`` and ``M⁻¹`` are applied by
their non-zero entries (diagonal for a vehicle with G at U and diagonal added mass).

:meth:`VehicleDynamics.step` is Kutta's third-order Runge–Kutta step, the tableau of Drake's
``RungeKutta3Integrator``, with the command held over the step (a controller's period).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from drake_uuv.models.marine_vehicle import (
    QUATERNION_NORM_GAIN,
    MarineVehicleModel,
    rotation_rows,
)
from drake_uuv.models.thrust_allocation import ThrustAllocator

__all__ = ["VehicleDynamics", "matrix_times", "sparse_rows", "times"]

Rows = list[list[tuple[int, float]]]


def sparse_rows(matrix: np.ndarray) -> Rows:
    """The non-zero entries of each row of ``matrix``, as ``(column, value)`` pairs."""
    return [[(j, float(m)) for j, m in enumerate(row) if m != 0.0] for row in np.asarray(matrix)]


def times(rows: Rows, v: list[float]) -> list[float]:
    """``matrix @ v`` for ``rows = sparse_rows(matrix)``, on Python floats."""
    return [sum([m * v[j] for j, m in row]) for row in rows]


def matrix_times(matrix: np.ndarray) -> Callable[[list[float]], list[float]]:
    """``v ↦ matrix @ v`` on Python floats: element-wise for a diagonal 6×6 matrix (a mass
    matrix with G at U and diagonal added mass), else by the rows' non-zero entries."""
    matrix = np.asarray(matrix, dtype=float)
    diagonal = np.diag(matrix).tolist()
    if matrix.shape == (6, 6) and np.array_equal(matrix, np.diag(diagonal)):
        m0, m1, m2, m3, m4, m5 = diagonal

        def diagonal_times(v: list[float]) -> list[float]:
            v0, v1, v2, v3, v4, v5 = v
            return [m0 * v0, m1 * v1, m2 * v2, m3 * v3, m4 * v4, m5 * v5]

        return diagonal_times
    rows = sparse_rows(matrix)
    return lambda v: times(rows, v)


class VehicleDynamics:
    """``ẋ = F(x, f_cmd)`` of the module notes for one vehicle and thruster layout.

    Args:
        model: the hull's ``M``, ``C``, ``D``, ``g`` (``MarineVehicleModel``).
        allocator: the thruster layout (its ``A`` and ``max_thrust``).
        thrust_time_constant: T [s] of the thrust lag, 0 for none.
    """

    def __init__(
        self, model: MarineVehicleModel, allocator: ThrustAllocator, thrust_time_constant: float
    ) -> None:
        self.model = model
        self.num_thrusters = allocator.num_thrusters
        self.max_thrust = allocator.max_thrust
        self.time_constant = float(thrust_time_constant)
        self.lag = self.time_constant > 0.0
        self.num_states = 13 + (self.num_thrusters if self.lag else 0)
        self._M = matrix_times(model.M)
        self._M_inv = matrix_times(model.M_inv)
        # M⁻¹ A: the acceleration per newton of each thruster.
        self._M_inv_A = matrix_times(model.M_inv @ allocator.A)

    def saturate(self, command: list[float]) -> list[float]:
        """``sat(f_cmd)``: each thrust clipped to ``±max_thrust``."""
        f_max = self.max_thrust
        return [f_max if f > f_max else -f_max if f < -f_max else f for f in command]

    def derivative(self, x: list[float], command: list[float]) -> list[float]:
        """``ẋ`` at state ``x`` under the commanded thrusts ``command`` (lists of floats)."""
        f = self.saturate(command)
        if not self.lag:
            return self._rates(x, self._M_inv_A(f))
        return self._lagged_rates(x, f)

    def step(self, x: list[float], command: list[float], h: float) -> list[float]:
        """``x(t + h)`` by Kutta's third-order step under ``command`` held over ``[t, t + h]``:
        ``k1 = F(x)``, ``k2 = F(x + h/2 k1)``, ``k3 = F(x − h k1 + 2h k2)``,
        ``x + h/6 (k1 + 4 k2 + k3)`` (Drake's ``RungeKutta3Integrator``)."""
        f = self.saturate(command)
        if self.lag:
            rates, drive = self._lagged_rates, f
        else:
            rates, drive = self._rates, self._M_inv_A(f)  # A f is constant over the step
        k1 = rates(x, drive)
        half, two = 0.5 * h, 2.0 * h
        k2 = rates([a + half * b for a, b in zip(x, k1, strict=True)], drive)
        k3 = rates([a - h * b + two * c for a, b, c in zip(x, k1, k2, strict=True)], drive)
        sixth, two_thirds = h / 6.0, 2.0 * h / 3.0
        return [
            a + sixth * b + two_thirds * c + sixth * d
            for a, b, c, d in zip(x, k1, k2, k3, strict=True)
        ]

    def _lagged_rates(self, x: list[float], f: list[float]) -> list[float]:
        """``ẋ`` with the lag: the hull driven by the lag state ``x[13:]``, which moves toward
        the saturated command ``f``."""
        thrust = x[13:]
        rate = 1.0 / self.time_constant
        return self._rates(x, self._M_inv_A(thrust)) + [
            (c - t) * rate for c, t in zip(f, thrust, strict=True)
        ]

    def _rates(self, x: list[float], drive: list[float]) -> list[float]:
        """``[ṗ, q̇, ν̇]`` with ``drive = M⁻¹ A f``."""
        quaternion, nu = x[3:7], x[7:13]
        qw, qx, qy, qz = quaternion
        u, v, w, p, q, r = nu
        (r00, r01, r02), (r10, r11, r12), k_B = rotation_rows(quaternion)
        bias = self.model._bias(nu, self._M(nu), k_B)
        d0, d1, d2, d3, d4, d5 = drive
        b0, b1, b2, b3, b4, b5 = self._M_inv(bias)
        k = QUATERNION_NORM_GAIN * (1.0 - (qw * qw + qx * qx + qy * qy + qz * qz))
        return [
            r00 * u + r01 * v + r02 * w,
            r10 * u + r11 * v + r12 * w,
            k_B[0] * u + k_B[1] * v + k_B[2] * w,
            0.5 * (-qx * p - qy * q - qz * r) + k * qw,
            0.5 * (qw * p + qy * r - qz * q) + k * qx,
            0.5 * (qw * q + qz * p - qx * r) + k * qy,
            0.5 * (qw * r + qx * q - qy * p) + k * qz,
            d0 - b0, d1 - b1, d2 - b2, d3 - b3, d4 - b4, d5 - b5,
        ]  # fmt: skip
