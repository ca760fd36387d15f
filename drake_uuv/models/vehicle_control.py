"""The hovering UUV's low-level law: its parameters, for the compiled tick.

The design (references, computed torque, gains, allocation) is described where the law runs,
``drake_uuv/plants/low_level_controller.py``; the arithmetic of one tick is compiled once
(``drake_uuv/models/vehicle_kernels.py``: ``controller_runs`` for the ``LowLevelController``
system, ``stepped_runs`` for the plant that steps the vehicle and its controller together,
``drake_uuv/plants/hovering_auv_stepped.py``), each looping over the runs of a batch. This
module holds what they read: :class:`LowLevelLaw`.
"""

from __future__ import annotations

import numpy as np

from drake_uuv.models.marine_vehicle import QUATERNION_NORM_GAIN, MarineVehicleModel
from drake_uuv.models.thrust_allocation import ThrustAllocator
from drake_uuv.models.vehicle_kernels import KernelArrays, kernel_arrays

__all__ = ["LowLevelLaw"]


class LowLevelLaw:
    """Velocity and attitude tracking by computed torque, allocated to the thrusters.

    Args:
        model: the vehicle's ``M``, ``C``, ``D``, ``g``.
        allocator: its thrust allocation.
        period: h [s], the tick; the thrusts are held over it.
        outer_period: t [s], the outer loop's period.
        gains: ``(ω², 2ζω, ω_v)``: attitude stiffness [1/s²] and damping [1/s], velocity [1/s].
        trajectory: True for the ``"trajectory"`` attitude reference, False for ``"step"``.
        thrust_time_constant: T [s] of the vehicle's thrust lag (0: none), for the kernel
            that also steps the vehicle.

    ``arrays`` (:class:`~drake_uuv.models.vehicle_kernels.KernelArrays`) is what the
    compiled law reads.
    """

    def __init__(
        self,
        model: MarineVehicleModel,
        allocator: ThrustAllocator,
        *,
        period: float,
        outer_period: float,
        gains: tuple[float, float, float],
        trajectory: bool,
        thrust_time_constant: float = 0.0,
    ) -> None:
        self.model, self.allocator = model, allocator
        self.period, self.outer_period = period, outer_period
        self._kp, self._kd, self._kv = gains
        self.trajectory = trajectory
        self.ticks = round(outer_period / period)
        self.arrays: KernelArrays = kernel_arrays(
            model,
            allocator,
            thrust_time_constant,
            period=period,
            outer_period=outer_period,
            gains=gains,
            trajectory=trajectory,
            norm_gain=QUATERNION_NORM_GAIN,
        )

    def wrench_gains(self) -> dict[str, np.ndarray]:
        """The gains in wrench terms: ``M_rot ω²``, ``2ζω M_rot``, ``M_trans ω_v``."""
        M = self.model.M
        return {
            "attitude_stiffness": self._kp * M[3:, 3:],
            "attitude_damping": self._kd * M[3:, 3:],
            "velocity": self._kv * M[:3, :3],
        }
