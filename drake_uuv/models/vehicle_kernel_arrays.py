"""The arrays the vehicle's kernels read: one vehicle, its thrusters and its controller.

:func:`kernel_arrays` packs a ``MarineVehicleModel``, a ``ThrustAllocator`` and the low-level
controller's settings into the :class:`KernelArrays` that
:mod:`drake_uuv.models.vehicle_kernels` takes (its offsets into ``hull`` and ``law`` follow
the order written here), the mass matrices as :func:`sparse_rows`. Plain numpy, once per
vehicle.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class KernelArrays(NamedTuple):
    """One vehicle, its thrusters and its controller, as the kernels read them.

    - ``hull`` (17): ``D_lin`` (6), ``D_quad`` (6), ``W r_BG − B r_BB`` (3), ``W − B``, and
      the quaternion norm gain λ.
    - ``values``, ``columns`` (3×6×max(n, 6)): the non-zero entries of each row, and their
      columns (−1 after the last), of the mass matrix ``M`` (rigid body and added mass),
      its inverse, and ``M⁻¹ A``, the acceleration per newton of each thruster (6×n), in
      that order (:func:`sparse_rows`): a product skips the zeros of a diagonal mass.
    - ``pinv`` (n×6): ``A⁺_W``, the weighted pseudo-inverse of the allocation.
    - ``law`` (9): ``f_max``, the thrust lag T (0: none), the gains ω², 2ζω, ω_v, the
      controller period h, the outer period t, 1 for the ``"trajectory"`` attitude reference
      (0: ``"step"``), and the ticks per outer step t/h.
    """

    hull: np.ndarray
    values: np.ndarray
    columns: np.ndarray
    pinv: np.ndarray
    law: np.ndarray


def kernel_arrays(
    model,
    allocator,
    thrust_time_constant: float = 0.0,
    *,
    period: float = 0.0,
    outer_period: float = 0.0,
    gains: tuple[float, float, float] = (0.0, 0.0, 0.0),
    trajectory: bool = True,
    norm_gain: float = 1.0,
) -> KernelArrays:
    """The :class:`KernelArrays` of a ``MarineVehicleModel`` and a ``ThrustAllocator`` (the
    controller's fields may stay 0 for the state equation alone)."""

    def contiguous(value: np.ndarray, dtype: type = float) -> np.ndarray:
        array = np.array(value, dtype=dtype, order="C")
        array.flags.writeable = False
        return array

    hull = np.concatenate(
        [
            model.linear_damping,
            model.quadratic_damping,
            model.weight * model.r_BG - model.buoyancy * model.r_BB,
            [model.weight - model.buoyancy, norm_gain],
        ]
    )
    ticks = round(outer_period / period) if period > 0.0 else 0
    law = [allocator.max_thrust, thrust_time_constant, *gains, period, outer_period,
           1.0 if trajectory else 0.0, ticks]  # fmt: skip
    values, columns = sparse_rows([model.M, model.M_inv, model.M_inv @ allocator.A])
    return KernelArrays(
        contiguous(hull),
        contiguous(values),
        contiguous(columns, np.int64),
        contiguous(allocator.A_pinv),
        contiguous(law),
    )


def sparse_rows(matrices: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Matrices of r rows as ``(values, columns)``, each m×r×c (c the most columns): row i of
    matrix k's non-zero entries in column order, their columns, −1 after the last."""
    width = max(np.shape(matrix)[1] for matrix in matrices)
    rows = max(np.shape(matrix)[0] for matrix in matrices)
    values = np.zeros((len(matrices), rows, width))
    columns = np.full((len(matrices), rows, width), -1, dtype=np.int64)
    for k, matrix in enumerate(matrices):
        for i, row in enumerate(np.asarray(matrix, dtype=float)):
            (nonzero,) = np.nonzero(row)
            values[k, i, : len(nonzero)] = row[nonzero]
            columns[k, i, : len(nonzero)] = nonzero
    return values, columns
