"""The thruster-driven vehicle's state equation and a fixed step of it, for one run or a batch.

State ``x = [p_WU (3), q_WB (4: w, x, y, z), ν_B (6: v_B, ω_B), f (n, with a thrust lag only)]``
and, with ``f_cmd`` the commanded thrusts and ``sat`` their clip to ``±f_max``,

    ṗ_WU = R(q) v_B
    q̇_WB = ½ q ⊗ [0, ω_B] + λ (1 − |q|²) q                   (quaternion_derivative)
    ν̇    = M⁻¹ (A f − C(ν) ν − D(ν) ν − g(η))                 (Fossen, MarineVehicleModel)
    ḟ    = (sat(f_cmd) − f) / T   with a lag T > 0; without one f = sat(f_cmd).

The arithmetic is compiled (``drake_uuv/models/vehicle_kernels.py``: numba kernels that loop
over the runs of a batch); ``M`` and ``M⁻¹`` are applied by their non-zero entries.

:meth:`VehicleDynamics.step` is Kutta's third-order Runge–Kutta step, the tableau of Drake's
``RungeKutta3Integrator``, with the command held over the step (a controller's period).
"""

from __future__ import annotations

import numpy as np

from drake_uuv.models.marine_vehicle import QUATERNION_NORM_GAIN, MarineVehicleModel
from drake_uuv.models.thrust_allocation import ThrustAllocator
from drake_uuv.models.vehicle_kernels import KernelArrays, derivative_runs, kernel_arrays, rk3_runs

__all__ = ["VehicleDynamics"]


class VehicleDynamics:
    """``ẋ = F(x, f_cmd)`` of the module notes for one vehicle and thruster layout.

    Args:
        model: the hull's ``M``, ``C``, ``D``, ``g`` (``MarineVehicleModel``).
        allocator: the thruster layout (its ``A`` and ``max_thrust``).
        thrust_time_constant: T [s] of the thrust lag, 0 for none.

    :meth:`derivative_runs` and :meth:`step_runs` take a batch (B×nx states, B×n commands);
    :meth:`derivative` and :meth:`step` one run as lists of floats (a batch of one).
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
        self.arrays: KernelArrays = kernel_arrays(
            model, allocator, self.time_constant, norm_gain=QUATERNION_NORM_GAIN
        )

    def saturate(self, command: list[float]) -> list[float]:
        """``sat(f_cmd)``: each thrust clipped to ``±max_thrust``."""
        f_max = self.max_thrust
        return [f_max if f > f_max else -f_max if f < -f_max else f for f in command]

    def derivative_runs(self, x: np.ndarray, command: np.ndarray) -> np.ndarray:
        """``ẋ`` of each run (B×nx) under its commanded thrusts (B×n)."""
        x, command = _float_rows(x), _float_rows(command)
        out = np.empty_like(x)
        a = self.arrays
        derivative_runs(x, command, a.hull, a.values, a.columns, a.law, out)
        return out

    def step_runs(self, x: np.ndarray, command: np.ndarray, h: float) -> np.ndarray:
        """Each run's :meth:`step` (B×nx states, B×n commands held over ``[t, t + h]``)."""
        x, command = _float_rows(x), _float_rows(command)
        out = np.empty_like(x)
        a = self.arrays
        rk3_runs(x, command, float(h), a.hull, a.values, a.columns, a.law, out)
        return out

    def derivative(self, x: list[float], command: list[float]) -> list[float]:
        """``ẋ`` at state ``x`` under the commanded thrusts ``command`` (one run)."""
        return self.derivative_runs(np.array([x]), np.array([command]))[0].tolist()

    def step(self, x: list[float], command: list[float], h: float) -> list[float]:
        """``x(t + h)`` by Kutta's third-order step under ``command`` held over ``[t, t + h]``:
        ``k1 = F(x)``, ``k2 = F(x + h/2 k1)``, ``k3 = F(x − h k1 + 2h k2)``,
        ``x + h/6 (k1 + 4 k2 + k3)`` (Drake's ``RungeKutta3Integrator``)."""
        return self.step_runs(np.array([x]), np.array([command]), h)[0].tolist()


def _float_rows(value: np.ndarray) -> np.ndarray:
    """A C-contiguous writable float64 2-D copy (the kernels' one signature)."""
    return np.array(value, dtype=float, order="C", ndmin=2)
