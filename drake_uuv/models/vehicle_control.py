"""The hovering UUV's low-level law for one controller tick, on Python floats.

The design (references, computed torque, gains, allocation) is described where the law runs,
``drake_uuv/plants/low_level_controller.py``; this module holds its arithmetic once, for the
``LowLevelController`` system and for the plant that steps the vehicle and its controller
together (``drake_uuv/plants/hovering_auv_stepped.py``).

Rotations are 3×3 nested lists of rows and vectors lists of Python floats: the law runs at
every controller tick (25 times per outer step), on 3-vectors, where numpy's per-call overhead
costs more than the arithmetic. The tests check each helper against ``drake_uuv.models.so3``.
"""

from __future__ import annotations

import math
from operator import add
from typing import NamedTuple

import numpy as np

from drake_uuv.models.marine_vehicle import MarineVehicleModel
from drake_uuv.models.so3 import log_so3
from drake_uuv.models.thrust_allocation import ThrustAllocator
from drake_uuv.models.vehicle_dynamics import matrix_times

__all__ = ["Latch", "LowLevelLaw", "Tick", "exp_rows", "log_rows", "times_transpose"]

Rows = list[list[float]]

_SMALL_ANGLE = 1e-9


def exp_rows(w: list[float]) -> Rows:
    """``Exp(w)`` (Rodrigues): ``I + a K + b K²`` with ``K² = w wᵀ − θ² I``."""
    w0, w1, w2 = w
    squared = w0 * w0 + w1 * w1 + w2 * w2
    theta = math.sqrt(squared)
    if theta < _SMALL_ANGLE:
        a, b = 1.0, 0.5
    else:
        a, b = math.sin(theta) / theta, (1.0 - math.cos(theta)) / squared
    c = 1.0 - b * squared
    return [
        [c + b * w0 * w0, b * w0 * w1 - a * w2, b * w0 * w2 + a * w1],
        [b * w0 * w1 + a * w2, c + b * w1 * w1, b * w1 * w2 - a * w0],
        [b * w0 * w2 - a * w1, b * w1 * w2 + a * w0, c + b * w2 * w2],
    ]


def log_rows(E: Rows) -> list[float]:
    """``Log(E)``, the rotation vector of angle in [0, π].

    Up to a quarter turn (the attitude errors of a tracking loop) from the skew part
    ``sin θ n`` and the trace ``1 + 2 cos θ``, ``θ = atan2(sin θ, cos θ)``; beyond, where
    ``sin θ`` loses its digits toward a half turn, by ``so3.log_so3`` (via the quaternion).
    """
    (e00, e01, e02), (e10, e11, e12), (e20, e21, e22) = E
    cosine = 0.5 * (e00 + e11 + e22 - 1.0)
    if cosine < 0.0:
        return log_so3(np.array(E)).tolist()
    v0, v1, v2 = 0.5 * (e21 - e12), 0.5 * (e02 - e20), 0.5 * (e10 - e01)
    sine = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    if sine < _SMALL_ANGLE:
        return [v0, v1, v2]
    k = math.atan2(sine, cosine) / sine
    return [k * v0, k * v1, k * v2]


def times(A: Rows, B: Rows) -> Rows:
    """``A B`` for 3×3 rows."""
    (a00, a01, a02), (a10, a11, a12), (a20, a21, a22) = A
    (b00, b01, b02), (b10, b11, b12), (b20, b21, b22) = B
    return [
        [a00 * b00 + a01 * b10 + a02 * b20, a00 * b01 + a01 * b11 + a02 * b21,
         a00 * b02 + a01 * b12 + a02 * b22],
        [a10 * b00 + a11 * b10 + a12 * b20, a10 * b01 + a11 * b11 + a12 * b21,
         a10 * b02 + a11 * b12 + a12 * b22],
        [a20 * b00 + a21 * b10 + a22 * b20, a20 * b01 + a21 * b11 + a22 * b21,
         a20 * b02 + a21 * b12 + a22 * b22],
    ]  # fmt: skip


def times_transpose(A: Rows, B: Rows) -> Rows:
    """``A Bᵀ`` for 3×3 rows (the same products, summed in the same order, as ``times``)."""
    return times(A, list(zip(*B, strict=True)))


def _apply(R: Rows, v: list[float]) -> list[float]:
    """``R v``."""
    v0, v1, v2 = v
    return [r0 * v0 + r1 * v1 + r2 * v2 for r0, r1, r2 in R]


def _apply_transpose(R: Rows, v: list[float]) -> list[float]:
    """``Rᵀ v``."""
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = R
    v0, v1, v2 = v
    return [
        r00 * v0 + r10 * v1 + r20 * v2,
        r01 * v0 + r11 * v1 + r21 * v2,
        r02 * v0 + r12 * v1 + r22 * v2,
    ]


class Latch(NamedTuple):
    """What the law holds from an outer tick k (time ``t_k``) to the next."""

    a_W: list[float]  # R(kt) u1_B, the commanded world acceleration [m/s²]
    v_k: list[float]  # v_WU(kt) [m/s]
    R_k: Rows  # R_WB(kt)
    t_k: float  # kt [s]
    u2: list[float]  # the commanded world angular velocity [rad/s]
    R_target: Rows  # R(k+1) = Exp(u2 t) R(kt)


class Tick(NamedTuple):
    """One tick's output: the thrusts to hold and what the controller publishes."""

    thrust: list[float]  # [N]
    wrench: list[float]  # the body wrench asked of the allocation [N, N m]
    v_ref: list[float]  # the velocity reference [m/s]
    force_scale: float  # the scales the allocation applied (1: unsaturated)
    moment_scale: float


class LowLevelLaw:
    """Velocity and attitude tracking by computed torque, allocated to the thrusters.

    Args:
        model: the vehicle's ``M``, ``C``, ``D``, ``g``.
        allocator: its thrust allocation.
        period: h [s], the tick; the thrusts are held over it.
        outer_period: t [s], the outer loop's period.
        gains: ``(ω², 2ζω, ω_v)``: attitude stiffness [1/s²] and damping [1/s], velocity [1/s].
        trajectory: True for the ``"trajectory"`` attitude reference, False for ``"step"``.
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
    ) -> None:
        self.model, self.allocator = model, allocator
        self.period, self.outer_period = period, outer_period
        self._half_h = 0.5 * period
        self._kp, self._kd, self._kv = gains
        self._trajectory = trajectory
        self._M = matrix_times(model.M)

    def wrench_gains(self) -> dict[str, np.ndarray]:
        """The gains in wrench terms: ``M_rot ω²``, ``2ζω M_rot``, ``M_trans ω_v``."""
        M = self.model.M
        return {
            "attitude_stiffness": self._kp * M[3:, 3:],
            "attitude_damping": self._kd * M[3:, 3:],
            "velocity": self._kv * M[:3, :3],
        }

    def latch(self, time: float, R: Rows, nu: list[float], u1_B: list[float],
              u2_W: list[float]) -> Latch:  # fmt: skip
        """The latch of an outer tick at ``time``: the vehicle's state and the fresh commands."""
        u2 = list(u2_W)
        t = self.outer_period
        return Latch(
            a_W=_apply(R, u1_B),
            v_k=_apply(R, nu[:3]),
            R_k=R,
            t_k=time,
            u2=u2,
            R_target=times(exp_rows([t * w for w in u2]), R),
        )

    def tick(self, s: float, R: Rows, nu: list[float], latch: Latch) -> Tick:
        """The thrusts at ``s = τ − t_k`` into the step, for the vehicle at ``R``, ``nu``."""
        a_W, v_k, u2 = latch.a_W, latch.v_k, latch.u2
        u, v, w, p, q, r = nu
        (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = R
        if self._trajectory:
            R_ref, w_ref = times(exp_rows([s * c for c in u2]), latch.R_k), u2
        else:
            R_ref, w_ref = latch.R_target, (0.0, 0.0, 0.0)
        e0, e1, e2 = log_rows(times_transpose(R_ref, R))
        kp, kd, kv = self._kp, self._kd, self._kv
        # α_W = ω² e + 2ζω (ω_ref − R ω_B), a_W,cmd = a_W + ω_v (v_ref − R v_B).
        alpha = (
            kp * e0 + kd * (w_ref[0] - (r00 * p + r01 * q + r02 * r)),
            kp * e1 + kd * (w_ref[1] - (r10 * p + r11 * q + r12 * r)),
            kp * e2 + kd * (w_ref[2] - (r20 * p + r21 * q + r22 * r)),
        )
        v_ref = [v_k[0] + a_W[0] * s, v_k[1] + a_W[1] * s, v_k[2] + a_W[2] * s]
        a_cmd = (
            a_W[0] + kv * (v_ref[0] - (r00 * u + r01 * v + r02 * w)),
            a_W[1] + kv * (v_ref[1] - (r10 * u + r11 * v + r12 * w)),
            a_W[2] + kv * (v_ref[2] - (r20 * u + r21 * v + r22 * w)),
        )
        # ν̇_des = [R_WBᵀ a_W,cmd − ω_B × v_B, R_WBᵀ α_W] (v̇_W = R (v̇_B + ω_B × v_B)).
        a0, a1, a2 = _apply_transpose(R, a_cmd)
        nu_dot = [a0 - (q * w - r * v), a1 - (r * u - p * w), a2 - (p * v - q * u),
                  *_apply_transpose(R, alpha)]  # fmt: skip
        # The thrust is held for h while ν moves on: the bias at mid-period, ν + ½h ν̇_des,
        # makes the held wrench right to second order in h (drag grows with the speed).
        half = self._half_h
        nu_mid = [a + half * b for a, b in zip(nu, nu_dot, strict=True)]
        bias = self.model._bias(nu_mid, self._M(nu_mid), R[2])
        wrench = list(map(add, self._M(nu_dot), bias))
        thrust, force_scale, moment_scale = self.allocator.allocate_floats(wrench)
        return Tick(thrust, wrench, v_ref, force_scale, moment_scale)
