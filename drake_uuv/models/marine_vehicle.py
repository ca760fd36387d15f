"""Fossen's 6-DOF marine-vehicle equations of motion in plain numpy.

``M ν̇ + C(ν) ν + D(ν) ν + g(η) = τ`` (Fossen, *Handbook of Marine Craft Hydrodynamics and
Motion Control*, 2nd ed. 2021, for a vehicle in still water), with

* ``ν = [v_B, ω_B]`` the body-frame velocity of the body origin U and the body angular
  velocity, both expressed in the body frame B;
* ``M = M_RB + M_A`` the rigid-body mass matrix about U (Fossen 2021, Ch. 3, the centre
  of gravity G at ``r_BG``) plus the added mass;
* ``C(ν) = C_RB(ν) + C_A(ν)`` in the linear-velocity-independent parametrisation of Fossen
  2021, Ch. 3 (his PythonVehicleSimulator ``lib/gnc.py``: ``m2c``). Both parts are
  skew-symmetric, so they do no work: ``νᵀ C(ν) ν = 0``;
* ``D(ν) = D_lin + D_quad |ν|``, diagonal, so ``D(ν) ν`` dissipates in every degree of freedom;
* ``g(η)`` the restoring forces of the weight W at G and the buoyancy B at the centre of
  buoyancy ``r_BB``.

Frame convention. Fossen writes the world frame North-East-Down and the body frame
forward-starboard-down. Here the world frame W has z *up* (Drake's; gravity along −z) and the
body frame B is forward-left-up. M, C and D are frame-agnostic (they hold in any right-handed
body frame), only ``g(η)`` depends on where "up" is. With ``k_B = R_WBᵀ e_z`` the world's up
direction in body coordinates, the weight is ``−W k_B`` at G and the buoyancy ``+B k_B`` at the
centre of buoyancy, and ``g`` stands on the left-hand side, so

    g(η) = −[ (B − W) k_B ;  (B r_BB − W r_BG) × k_B ]
         =  [ (W − B) k_B ;  (W r_BG − B r_BB) × k_B ].

This equals Fossen's ``gvect`` after the change of frames (checked in the tests). For a
small pitch θ about body y with G at U and the centre of buoyancy a height ``z_BG`` above it,
the restoring moment is ``B z_BG sin θ`` against the tilt.

Attitude is the unit quaternion ``q_WB = [w, x, y, z]`` (Drake's order), with
``q̇ = ½ q ⊗ [0, ω_B]``. Integration drifts off the unit sphere; see
:func:`quaternion_derivative` for the projection that pulls it back.
"""

from __future__ import annotations

import math

import numpy as np

from drake_uuv.models.so3 import hat

__all__ = [
    "MarineVehicleModel",
    "coriolis_matrix",
    "quaternion_derivative",
    "restoring_force",
    "rigid_body_mass_matrix",
]

# Rate [1/s] at which quaternion_derivative pulls |q| back to 1. Slow next to the vehicle's
# own dynamics (no stiffness for an explicit integrator), fast next to the integrator's drift.
QUATERNION_NORM_GAIN = 1.0


def rigid_body_mass_matrix(mass: float, inertia_G: np.ndarray, r_BG: np.ndarray) -> np.ndarray:
    """``M_RB`` about the body origin (Fossen 2021, Ch. 3): ``Hᵀ(r_BG) diag(m I, I_G) H(r_BG)``.

    ``inertia_G`` is the 3×3 inertia about the centre of gravity G in body axes; ``r_BG`` is G
    from the body origin, body frame.
    """
    S = hat(np.asarray(r_BG, dtype=float))
    M = np.zeros((6, 6))
    M[:3, :3] = mass * np.eye(3)
    M[:3, 3:] = -mass * S
    M[3:, :3] = mass * S
    M[3:, 3:] = np.asarray(inertia_G, dtype=float) - mass * S @ S
    return M


def coriolis_matrix(M: np.ndarray, nu: np.ndarray) -> np.ndarray:
    """``C(ν)`` of a symmetric mass matrix M, Fossen 2021, Ch. 3 (``m2c`` in his ``gnc.py``).

    ``C = [[0, −S(M11 ν1 + M12 ν2)], [−S(M11 ν1 + M12 ν2), −S(M21 ν1 + M22 ν2)]]``; linear in
    M, so ``C_RB + C_A`` is this of ``M_RB + M_A``.
    """
    M = 0.5 * (M + M.T)
    p1 = M[:3] @ nu
    p2 = M[3:] @ nu
    C = np.zeros((6, 6))
    C[:3, 3:] = -hat(p1)
    C[3:, :3] = -hat(p1)
    C[3:, 3:] = -hat(p2)
    return C


def restoring_force(
    weight: float, buoyancy: float, r_BG: np.ndarray, r_BB: np.ndarray, R_WB: np.ndarray
) -> np.ndarray:
    """``g(η)`` for a z-up world frame (see the module notes): weight at G, buoyancy at CB."""
    k_B = np.asarray(R_WB)[2]  # R_WBᵀ e_z: the world's up direction in body coordinates
    moment_arm = weight * np.asarray(r_BG) - buoyancy * np.asarray(r_BB)
    return np.concatenate([(weight - buoyancy) * k_B, np.cross(moment_arm, k_B)])


def quaternion_derivative(q_WB: np.ndarray, w_B: np.ndarray) -> np.ndarray:
    """``q̇ = ½ q ⊗ [0, ω_B] + λ (1 − |q|²) q`` (Hamilton product, ``[w, x, y, z]``).

    The first term is the exact kinematics on the unit sphere; it is tangent to every sphere
    ``|q| = const`` (``qᵀ q̇ = 0``), so an integrator's truncation error can change ``|q|``
    and nothing restores it. The second term makes the unit sphere attractive:
    ``d|q|²/dt = 2λ (1 − |q|²) |q|²``, so ``|q|`` returns to 1 at rate ``2λ``
    (``λ = QUATERNION_NORM_GAIN``) and is untouched while it is 1. Every output that
    reads the attitude also divides by ``|q|``, so a drift never reaches a rotation matrix.
    """
    w, x, y, z = q_WB
    p, q, r = w_B
    stabilise = QUATERNION_NORM_GAIN * (1.0 - (w * w + x * x + y * y + z * z))
    return np.array(
        [
            0.5 * (-x * p - y * q - z * r) + stabilise * w,
            0.5 * (w * p + y * r - z * q) + stabilise * x,
            0.5 * (w * q + z * p - x * r) + stabilise * y,
            0.5 * (w * r + x * q - y * p) + stabilise * z,
        ]
    )


def rotation_from_quaternion(q_WB: np.ndarray) -> np.ndarray:
    """``R_WB`` of a quaternion that may be slightly off the unit sphere (normalised first)."""
    return np.array(rotation_rows(q_WB.tolist()))


def rotation_rows(q: list[float]) -> list[list[float]]:
    """The rows of ``R_WB`` of ``q / |q|``, on Python floats (``vehicle_kernels._rotation``
    computes the same in the compiled vehicle)."""
    w, x, y, z = q
    s = 2.0 / (w * w + x * x + y * y + z * z)
    return [
        [1.0 - s * (y * y + z * z), s * (x * y - w * z), s * (x * z + w * y)],
        [s * (x * y + w * z), 1.0 - s * (x * x + z * z), s * (y * z - w * x)],
        [s * (x * z - w * y), s * (y * z + w * x), 1.0 - s * (x * x + y * y)],
    ]


class MarineVehicleModel:
    """One vehicle's ``M``, ``C(ν)``, ``D(ν)`` and ``g(η)``, and its accelerations.

    Args:
        mass: m [kg].
        inertia_G: 3×3 inertia about the centre of gravity G, body axes [kg m²].
        r_BG, r_BB: centre of gravity and centre of buoyancy from the body origin, body
            frame [m].
        added_mass: 6×6 symmetric ``M_A`` (Fossen's sign: positive entries, e.g.
            ``M_A[0, 0] = −X_u̇``) [kg, kg m, kg m²].
        linear_damping, quadratic_damping: the diagonals of ``D_lin`` and ``D_quad``, all ≥ 0.
        weight, buoyancy: W = m g and B [N].
    """

    def __init__(
        self,
        mass: float,
        inertia_G: np.ndarray,
        r_BG: np.ndarray,
        r_BB: np.ndarray,
        added_mass: np.ndarray,
        linear_damping: np.ndarray,
        quadratic_damping: np.ndarray,
        weight: float,
        buoyancy: float,
    ) -> None:
        if not (math.isfinite(mass) and mass > 0.0):
            raise ValueError(f"mass: must be > 0, got {mass!r}")
        self.r_BG = np.asarray(r_BG, dtype=float).reshape(3)
        self.r_BB = np.asarray(r_BB, dtype=float).reshape(3)
        self.M_RB = rigid_body_mass_matrix(mass, inertia_G, self.r_BG)
        self.M_A = np.asarray(added_mass, dtype=float).reshape(6, 6)
        if not np.allclose(self.M_A, self.M_A.T, rtol=0.0, atol=1e-12 * np.abs(self.M_A).max()):
            raise ValueError(f"added_mass: must be symmetric, got {self.M_A.tolist()!r}")
        self.M = self.M_RB + self.M_A
        eigenvalues = np.linalg.eigvalsh(self.M)
        if not eigenvalues[0] > 0.0:
            raise ValueError(
                f"added_mass: M = M_RB + M_A must be positive definite (smallest eigenvalue "
                f"{eigenvalues[0]:.6g}; Fossen's added mass is +diag(−X_u̇, …)), "
                f"got {self.M_A.tolist()!r}"
            )
        self.M_inv = np.linalg.inv(self.M)
        self.linear_damping = np.asarray(linear_damping, dtype=float).reshape(6)
        self.quadratic_damping = np.asarray(quadratic_damping, dtype=float).reshape(6)
        for name, value in (
            ("linear_damping", self.linear_damping),
            ("quadratic_damping", self.quadratic_damping),
        ):
            if not np.all(value >= 0.0):
                raise ValueError(f"{name}: must be ≥ 0 (dissipative), got {value.tolist()!r}")
        self.mass = float(mass)
        self.weight = float(weight)
        self.buoyancy = float(buoyancy)
        # Moment arm of the restoring moment, W r_BG − B r_BB, and the net weight W − B.
        self._restoring_arm = self.weight * self.r_BG - self.buoyancy * self.r_BB
        # The same as Python floats for bias_force.
        self._arm = self._restoring_arm.tolist()
        self._net_weight = self.weight - self.buoyancy
        self._linear = self.linear_damping.tolist()
        self._quadratic = self.quadratic_damping.tolist()

    def coriolis_matrix(self, nu: np.ndarray) -> np.ndarray:
        """``C(ν) = C_RB(ν) + C_A(ν)``."""
        return coriolis_matrix(self.M_RB, nu) + coriolis_matrix(self.M_A, nu)

    def coriolis_force(self, nu: np.ndarray) -> np.ndarray:
        """``C(ν) ν`` without forming C: Kirchhoff's ``[ω × p1, ω × p2 + v × p1]``, ``p = M ν``."""
        p = self.M @ nu
        v, w = nu[:3], nu[3:]
        p1, p2 = p[:3], p[3:]
        return np.array(
            [
                w[1] * p1[2] - w[2] * p1[1],
                w[2] * p1[0] - w[0] * p1[2],
                w[0] * p1[1] - w[1] * p1[0],
                w[1] * p2[2] - w[2] * p2[1] + v[1] * p1[2] - v[2] * p1[1],
                w[2] * p2[0] - w[0] * p2[2] + v[2] * p1[0] - v[0] * p1[2],
                w[0] * p2[1] - w[1] * p2[0] + v[0] * p1[1] - v[1] * p1[0],
            ]
        )

    def damping_force(self, nu: np.ndarray) -> np.ndarray:
        """``D(ν) ν = (D_lin + D_quad |ν|) ν`` (element-wise)."""
        return (self.linear_damping + self.quadratic_damping * np.abs(nu)) * nu

    def restoring_force(self, R_WB: np.ndarray) -> np.ndarray:
        """``g(η)`` (see the module notes)."""
        k = R_WB[2]
        a = self._restoring_arm
        f = self.weight - self.buoyancy
        return np.array(
            [
                f * k[0],
                f * k[1],
                f * k[2],
                a[1] * k[2] - a[2] * k[1],
                a[2] * k[0] - a[0] * k[2],
                a[0] * k[1] - a[1] * k[0],
            ]
        )

    def bias_force(self, nu: np.ndarray, R_WB: np.ndarray) -> np.ndarray:
        """``C(ν) ν + D(ν) ν + g(η)``: what τ must supply for ``ν̇ = 0``.

        The same terms as :meth:`coriolis_force`, :meth:`damping_force` and
        :meth:`restoring_force`, on Python floats, in the order the compiled vehicle
        (``vehicle_kernels._bias``) takes them.
        """
        return np.array(self._bias(nu.tolist(), (self.M @ nu).tolist(), R_WB[2].tolist()))

    def _bias(self, nu: list[float], p: list[float], k: list[float]) -> list[float]:
        u, v, w, wx, wy, wz = nu
        p0, p1, p2, p3, p4, p5 = p
        dl, dq, a, f = self._linear, self._quadratic, self._arm, self._net_weight
        # D(ν) ν: each axis's linear and quadratic damping.
        d0, d1 = (dl[0] + dq[0] * abs(u)) * u, (dl[1] + dq[1] * abs(v)) * v
        d2, d3 = (dl[2] + dq[2] * abs(w)) * w, (dl[3] + dq[3] * abs(wx)) * wx
        d4, d5 = (dl[4] + dq[4] * abs(wy)) * wy, (dl[5] + dq[5] * abs(wz)) * wz
        # With p = M ν, C(ν) ν is ω × p_v in the force and ω × p_ω + v × p_v in the moment; then
        # g(η): (W − B) k in the force, the restoring arm's a × k in the moment.
        return [
            wy * p2 - wz * p1 + d0 + f * k[0],
            wz * p0 - wx * p2 + d1 + f * k[1],
            wx * p1 - wy * p0 + d2 + f * k[2],
            wy * p5 - wz * p4 + v * p2 - w * p1 + d3 + a[1] * k[2] - a[2] * k[1],
            wz * p3 - wx * p5 + w * p0 - u * p2 + d4 + a[2] * k[0] - a[0] * k[2],
            wx * p4 - wy * p3 + u * p1 - v * p0 + d5 + a[0] * k[1] - a[1] * k[0],
        ]

    def acceleration(self, nu: np.ndarray, R_WB: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """``ν̇ = M⁻¹ (τ − C(ν) ν − D(ν) ν − g(η))``."""
        return self.M_inv @ (tau - self.bias_force(nu, R_WB))

    def kinetic_energy(self, nu: np.ndarray) -> float:
        """``½ νᵀ M ν`` (rigid body and added fluid mass)."""
        return 0.5 * float(nu @ self.M @ nu)

    def potential_energy(self, p_WU: np.ndarray, R_WB: np.ndarray) -> float:
        """``W z_G − B z_CB`` in the z-up world (zero at U on z = 0 with G and CB at U)."""
        z_G = p_WU[2] + R_WB[2] @ self.r_BG
        z_B = p_WU[2] + R_WB[2] @ self.r_BB
        return self.weight * z_G - self.buoyancy * z_B
