"""Thrust allocation: from a body wrench to the forces of fixed thrusters, with saturation.

Thruster i sits at ``r_i`` (body frame, from the body origin U) and pushes along the unit
vector ``d_i`` with a force ``f_i ∈ [−f_max, f_max]`` (bidirectional propellers). Its
contribution to the body wrench ``τ = [force; moment about U]`` is column i of the
allocation matrix ``A = [d_i; r_i × d_i]``, so ``τ = A f`` (Fossen 2021, the chapter on thrust
allocation).

Unsaturated, the allocation is the weighted least-norm solution ``f = A⁺_W τ`` with
``A⁺_W = W⁻¹ Aᵀ (A W⁻¹ Aᵀ)⁻¹``, which minimises ``Σ w_i f_i²`` subject to ``A f = τ`` (Fossen
2021, the same chapter). A must have rank 6 (every wrench reachable).

Saturation, by priority with the attitude first. The wrench splits into its force part and
its moment part, and ``A⁺_W`` is linear, so ``f = f_moment + f_force``:

1. ``f_moment = A⁺_W [0; τ_moment]``, scaled down as a whole (direction kept) if any thruster
   would exceed ``f_max``;
2. ``f_force = A⁺_W [τ_force; 0]`` is then scaled by the largest ``s ∈ [0, 1]`` that keeps every
   ``|f_moment,i + s f_force,i| ≤ f_max``.

So the moment is delivered exactly whenever it alone is feasible, and the force keeps its
direction and loses magnitude. Holding the attitude keeps the sonar baseline where the outer
loop put it; a force shortfall only slows the vehicle down. The null space of A is not used
to lower the peak thrust: the least-norm solution already spreads the thrust evenly over
symmetric thruster layouts.
"""

from __future__ import annotations

import numpy as np

from drake_uuv.models.vehicle_kernels import allocate_runs

__all__ = ["ThrustAllocator", "allocation_matrix", "weighted_pseudo_inverse"]


def allocation_matrix(positions: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """The 6×n matrix ``A`` with columns ``[d_i; r_i × d_i]`` (directions normalised).

    Raises ValueError if the shapes are not n×3 or a direction is zero.
    """
    r = np.asarray(positions, dtype=float)
    d = np.asarray(directions, dtype=float)
    if r.ndim != 2 or r.shape[1] != 3 or not np.all(np.isfinite(r)):
        raise ValueError(f"positions: must be n×3 and finite, got {r.tolist()!r}")
    if d.shape != r.shape or not np.all(np.isfinite(d)):
        raise ValueError(f"directions: must be {r.shape[0]}×3 and finite, got {d.tolist()!r}")
    lengths = np.linalg.norm(d, axis=1)
    if np.any(lengths < 1e-9):
        raise ValueError(f"directions: must be non-zero, got {d.tolist()!r}")
    d = d / lengths[:, None]
    return np.vstack([d.T, np.cross(r, d).T])


def weighted_pseudo_inverse(A: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """``A⁺_W = W⁻¹ Aᵀ (A W⁻¹ Aᵀ)⁻¹``, ``W = diag(weights)``: the least-``Σ w_i f_i²`` inverse."""
    A = np.asarray(A, dtype=float)
    w = np.asarray(weights, dtype=float)
    if w.shape != (A.shape[1],) or not np.all(w > 0.0) or not np.all(np.isfinite(w)):
        raise ValueError(f"weights: must be {A.shape[1]} positive numbers, got {w.tolist()!r}")
    if np.linalg.matrix_rank(A) < A.shape[0]:
        raise ValueError(
            f"positions, directions: the allocation matrix has rank {np.linalg.matrix_rank(A)} "
            f"< {A.shape[0]}, so some wrench cannot be produced, got A = {A.round(6).tolist()!r}"
        )
    W_inv_At = A.T / w[:, None]
    return W_inv_At @ np.linalg.inv(A @ W_inv_At)


class ThrustAllocator:
    """Body wrench → thruster forces, with attitude-first saturation (see the module notes).

    Args:
        positions: n×3 thruster positions in the body frame [m].
        directions: n×3 thrust directions in the body frame (normalised here).
        max_thrust: ``f_max`` [N], the same for every thruster, > 0.
        weights: n positive weights of the least-norm cost (default all 1).
    """

    def __init__(
        self,
        positions: np.ndarray,
        directions: np.ndarray,
        max_thrust: float,
        weights: np.ndarray | None = None,
    ) -> None:
        self.A = allocation_matrix(positions, directions)
        n = self.A.shape[1]
        if not (np.isfinite(max_thrust) and max_thrust > 0.0):
            raise ValueError(f"max_thrust: must be > 0, got {max_thrust!r}")
        self.max_thrust = float(max_thrust)
        self.A_pinv = weighted_pseudo_inverse(self.A, np.ones(n) if weights is None else weights)
        self._pinv = np.array(self.A_pinv, order="C")  # the kernels read-only copy
        self._pinv.flags.writeable = False

    @property
    def num_thrusters(self) -> int:
        return self.A.shape[1]

    def utilisation(self, wrench: np.ndarray) -> np.ndarray:
        """``max_i |A⁺_W τ|_i / f_max`` per wrench (rows of an m×6 array, or one 6-vector).

        At most 1 exactly when the allocation delivers the wrench unscaled. For the default
        layout and equal weights this is ``(|F_x| + |F_y| + |M_z|/0.32 m) / (2√2 f_max)`` for
        the angled group and ``(|F_z| + |M_x|/0.22 m + |M_y|/0.25 m) / (4 f_max)`` for the
        vertical group, whichever is larger.
        """
        thrust = np.asarray(wrench, dtype=float) @ self.A_pinv.T
        return np.abs(thrust).max(axis=-1) / self.max_thrust

    def wrench(self, thrust: np.ndarray) -> np.ndarray:
        """The body wrench ``A f`` of a thrust vector."""
        return self.A @ thrust

    def allocate(self, wrench: np.ndarray) -> tuple[np.ndarray, float, float]:
        """Thrusts for ``wrench = [force; moment]`` and the scales applied to each part.

        Returns ``(f, force_scale, moment_scale)``; both scales are 1 when the wrench is
        feasible, and then ``A f = wrench`` exactly.
        """
        thrust, scales = self.allocate_runs(np.asarray(wrench, dtype=float).reshape(1, 6))
        return thrust[0], float(scales[0, 0]), float(scales[0, 1])

    def allocate_runs(self, wrench: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`allocate` of each run's wrench (B×6): thrusts (B×n) and scales (B×2, force
        then moment), each run alone (compiled: ``vehicle_kernels.allocate_runs``)."""
        wrench = np.array(wrench, dtype=float, order="C", ndmin=2)
        thrust = np.empty((len(wrench), self.num_thrusters))
        scales = np.empty((len(wrench), 2))
        allocate_runs(wrench, self._pinv, self.max_thrust, thrust, scales)
        return thrust, scales
