"""The hovering UUV's arithmetic over a batch of runs, compiled with numba.

One implementation of the vehicle's state equation (``VehicleDynamics``), Kutta's RK3 step,
the low-level law of one controller tick (``LowLevelLaw``) and the attitude-first thrust
allocation (``ThrustAllocator``), for every batch size: each kernel loops over the runs of
its ``(B, n)`` arguments and does one run's whole work in compiled code. A run's numbers
depend on its own row only, so they are the same bits whatever its batch; a run's branches
(saturation, small angles, a half-turn attitude error) are taken inside its own iteration.
Compiled, not numpy over the runs: per run and controller tick the work is a few hundred
floating-point operations on 3- to 13-vectors (an outer step of the stepped plant is 25 ticks
and 75 derivative evaluations), where numpy's cost per call would dominate at small B.

The operations are those of the Python-float code these kernels took over, in the same
order (numba adds no fast-math contraction), so a single run keeps its bits to the last
(the rotations on 9-tuples, ``Exp``, ``Log`` and the 3×3 products, are
:mod:`drake_uuv.models.vehicle_rotations`', which says how their ``Log`` keeps numpy's dot).

``error_model="numpy"``: a run whose state holds NaN or inf (a failed run) divides by zero
or takes a square root of NaN without raising, and only its own row turns NaN.

The model's parameters travel as the arrays of :class:`KernelArrays` (:func:`kernel_arrays`,
both :mod:`drake_uuv.models.vehicle_kernel_arrays`' and importable from here). ``cache=True``
keeps the machine code between processes (7 s of CPU to compile on a cold cache, under a
second to load). Every kernel is in this file but the rotations they call
(``vehicle_rotations.py``): numba's cache does not notice a change in a compiled function
that another file's kernel calls, so after changing ``vehicle_rotations.py`` delete this
file's cache (``drake_uuv/models/__pycache__/vehicle_kernels.*.nb[ci]``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from drake_uuv.models.vehicle_kernel_arrays import KernelArrays, kernel_arrays, sparse_rows
from drake_uuv.models.vehicle_rotations import (
    _times3,
    _times_transpose3,
    exp_rotation,
    log_rotation,
)

__all__ = [
    "KernelArrays",
    "allocate_runs",
    "attitude_runs",
    "controller_runs",
    "derivative_runs",
    "exp_rotation",
    "kernel_arrays",
    "log_rotation",
    "rk3_runs",
    "sparse_rows",
    "stepped_runs",
]

# Offsets in KernelArrays.law.
_F_MAX, _LAG_T, _KP, _KD, _KV, _H, _OUTER, _TRAJECTORY, _TICKS = range(9)
# Offsets in KernelArrays.hull.
_LINEAR, _QUADRATIC, _ARM, _NET_WEIGHT, _NORM_GAIN = 0, 6, 12, 15, 16
# The matrices of KernelArrays.values and .columns.
_M, _M_INV, _M_INV_A = 0, 1, 2


# --- One run's pieces ----------------------------------------------------------------------


@njit(cache=True, error_model="numpy")
def _times(values: np.ndarray, columns: np.ndarray, k: int, v: np.ndarray,
           out: np.ndarray) -> None:  # fmt: skip
    """``out = matrix @ v`` for matrix k of ``sparse_rows``: each row's non-zero entries, in
    column order."""
    for i in range(values.shape[1]):
        acc = 0.0
        for j in range(values.shape[2]):
            column = columns[k, i, j]
            if column < 0:
                break
            acc += values[k, i, j] * v[column]
        out[i] = acc


@njit(cache=True, error_model="numpy")
def _rotation(qw: float, qx: float, qy: float, qz: float):
    """The rows of ``R_WB`` of ``q / |q|`` (9 floats, row-major)."""
    s = 2.0 / (qw * qw + qx * qx + qy * qy + qz * qz)
    return (
        1.0 - s * (qy * qy + qz * qz), s * (qx * qy - qw * qz), s * (qx * qz + qw * qy),
        s * (qx * qy + qw * qz), 1.0 - s * (qx * qx + qz * qz), s * (qy * qz - qw * qx),
        s * (qx * qz - qw * qy), s * (qy * qz + qw * qx), 1.0 - s * (qx * qx + qy * qy),
    )  # fmt: skip


@njit(cache=True, error_model="numpy")
def _bias(nu: np.ndarray, p: np.ndarray, k0: float, k1: float, k2: float, hull: np.ndarray,
          out: np.ndarray) -> None:  # fmt: skip
    """``C(ν) ν + D(ν) ν + g(η)`` with ``p = M ν`` and ``k = R_WBᵀ e_z`` (the model's _bias)."""
    u, v, w, wx, wy, wz = nu[0], nu[1], nu[2], nu[3], nu[4], nu[5]
    p0, p1, p2, p3, p4, p5 = p[0], p[1], p[2], p[3], p[4], p[5]
    dl, dq = _LINEAR, _QUADRATIC
    d0 = (hull[dl] + hull[dq] * abs(u)) * u
    d1 = (hull[dl + 1] + hull[dq + 1] * abs(v)) * v
    d2 = (hull[dl + 2] + hull[dq + 2] * abs(w)) * w
    d3 = (hull[dl + 3] + hull[dq + 3] * abs(wx)) * wx
    d4 = (hull[dl + 4] + hull[dq + 4] * abs(wy)) * wy
    d5 = (hull[dl + 5] + hull[dq + 5] * abs(wz)) * wz
    a0, a1, a2, f = hull[_ARM], hull[_ARM + 1], hull[_ARM + 2], hull[_NET_WEIGHT]
    out[0] = wy * p2 - wz * p1 + d0 + f * k0
    out[1] = wz * p0 - wx * p2 + d1 + f * k1
    out[2] = wx * p1 - wy * p0 + d2 + f * k2
    out[3] = wy * p5 - wz * p4 + v * p2 - w * p1 + d3 + a1 * k2 - a2 * k1
    out[4] = wz * p3 - wx * p5 + w * p0 - u * p2 + d4 + a2 * k0 - a0 * k2
    out[5] = wx * p4 - wy * p3 + u * p1 - v * p0 + d5 + a0 * k1 - a1 * k0


@njit(cache=True, error_model="numpy")
def _rates(x: np.ndarray, drive: np.ndarray, hull: np.ndarray, values: np.ndarray,
           columns: np.ndarray, out: np.ndarray, work: np.ndarray) -> None:  # fmt: skip
    """``[ṗ, q̇, ν̇]`` into ``out[:13]`` with ``drive = M⁻¹ A f`` (``work``: 2×6 scratch)."""
    qw, qx, qy, qz = x[3], x[4], x[5], x[6]
    u, v, w, p, q, r = x[7], x[8], x[9], x[10], x[11], x[12]
    r00, r01, r02, r10, r11, r12, k0, k1, k2 = _rotation(qw, qx, qy, qz)
    nu = x[7:13]
    momentum, bias = work[0], work[1]
    _times(values, columns, _M, nu, momentum)
    _bias(nu, momentum, k0, k1, k2, hull, bias)
    _times(values, columns, _M_INV, bias, momentum)  # M⁻¹ bias (the momentum is spent)
    k = hull[_NORM_GAIN] * (1.0 - (qw * qw + qx * qx + qy * qy + qz * qz))
    out[0] = r00 * u + r01 * v + r02 * w
    out[1] = r10 * u + r11 * v + r12 * w
    out[2] = k0 * u + k1 * v + k2 * w
    out[3] = 0.5 * (-qx * p - qy * q - qz * r) + k * qw
    out[4] = 0.5 * (qw * p + qy * r - qz * q) + k * qx
    out[5] = 0.5 * (qw * q + qz * p - qx * r) + k * qy
    out[6] = 0.5 * (qw * r + qx * q - qy * p) + k * qz
    for i in range(6):
        out[7 + i] = drive[i] - momentum[i]


@njit(cache=True, error_model="numpy")
def _state_rates(x: np.ndarray, drive: np.ndarray, hull: np.ndarray, values: np.ndarray,
                 columns: np.ndarray, law: np.ndarray, out: np.ndarray,
                 work: np.ndarray) -> None:  # fmt: skip
    """``ẋ``. Without a lag ``drive = M⁻¹ A sat(f_cmd)``; with one ``drive = sat(f_cmd)``,
    the hull is driven by the lag state ``x[13:]``, which moves toward it (``work``: 3×n
    scratch, n ≥ 6)."""
    if law[_LAG_T] > 0.0:
        n = x.shape[0] - 13
        lagged = work[2, :6]
        _times(values, columns, _M_INV_A, x[13:], lagged)
        _rates(x, lagged, hull, values, columns, out, work)
        rate = 1.0 / law[_LAG_T]
        for i in range(n):
            out[13 + i] = (drive[i] - x[13 + i]) * rate
    else:
        _rates(x, drive, hull, values, columns, out, work)


@njit(cache=True, error_model="numpy")
def _drive(command: np.ndarray, values: np.ndarray, columns: np.ndarray, law: np.ndarray,
           saturated: np.ndarray,
           out: np.ndarray) -> None:  # fmt: skip
    """``sat(f_cmd)`` into ``saturated`` and what drives ``_state_rates`` into ``out``."""
    f_max = law[_F_MAX]
    n = command.shape[0]
    for i in range(n):
        f = command[i]
        saturated[i] = f_max if f > f_max else -f_max if f < -f_max else f
    if law[_LAG_T] > 0.0:
        for i in range(n):
            out[i] = saturated[i]
    else:  # A f is constant over the step
        _times(values, columns, _M_INV_A, saturated, out)


@njit(cache=True, error_model="numpy")
def _rk3(x: np.ndarray, command: np.ndarray, h: float, hull: np.ndarray, values: np.ndarray,
         columns: np.ndarray, law: np.ndarray, out: np.ndarray,
         work: np.ndarray) -> None:  # fmt: skip
    """Kutta's third-order step of ``x`` over h under ``command`` held (Drake's
    ``RungeKutta3Integrator``): ``k1 = F(x)``, ``k2 = F(x + h/2 k1)``,
    ``k3 = F(x − h k1 + 2h k2)``, ``x + h/6 (k1 + 4 k2 + k3)`` (``work``: 9×nx scratch)."""
    nx = x.shape[0]
    k1, k2, k3, y = work[0, :nx], work[1, :nx], work[2, :nx], work[3, :nx]
    drive, saturated, scratch = work[4], work[5], work[6:9]
    _drive(command, values, columns, law, saturated, drive)
    _state_rates(x, drive, hull, values, columns, law, k1, scratch)
    half, two = 0.5 * h, 2.0 * h
    for i in range(nx):
        y[i] = x[i] + half * k1[i]
    _state_rates(y, drive, hull, values, columns, law, k2, scratch)
    for i in range(nx):
        y[i] = x[i] - h * k1[i] + two * k2[i]
    _state_rates(y, drive, hull, values, columns, law, k3, scratch)
    sixth, two_thirds = h / 6.0, 2.0 * h / 3.0
    for i in range(nx):
        out[i] = x[i] + sixth * k1[i] + two_thirds * k2[i] + sixth * k3[i]


@njit(cache=True, error_model="numpy")
def _allocate(wrench: np.ndarray, pinv: np.ndarray, f_max: float, thrust: np.ndarray,
              work: np.ndarray):  # fmt: skip
    """Attitude-first allocation (``ThrustAllocator``): thrusts into ``thrust``, returns
    ``(force_scale, moment_scale)`` (``work``: 2×n scratch). Maxima and minima keep their
    first candidate against NaN, as Python's ``max`` and ``min``."""
    n = pinv.shape[0]
    fx, fy, fz, mx, my, mz = wrench[0], wrench[1], wrench[2], wrench[3], wrench[4], wrench[5]
    f_moment, f_force = work[0, :n], work[1, :n]
    for i in range(n):
        f_moment[i] = pinv[i, 3] * mx + pinv[i, 4] * my + pinv[i, 5] * mz
    peak = abs(f_moment[0])
    for i in range(1, n):
        if abs(f_moment[i]) > peak:
            peak = abs(f_moment[i])
    moment_scale = 1.0
    if peak > f_max:
        moment_scale = f_max / peak
        for i in range(n):
            f_moment[i] = moment_scale * f_moment[i]
    for i in range(n):
        f_force[i] = pinv[i, 0] * fx + pinv[i, 1] * fy + pinv[i, 2] * fz
        thrust[i] = f_moment[i] + f_force[i]
    largest = abs(thrust[0])
    for i in range(1, n):
        if abs(thrust[i]) > largest:
            largest = abs(thrust[i])
    if largest <= f_max:
        return 1.0, moment_scale
    # Largest s with |f_moment + s f_force| ≤ f_max for every thruster (|f_moment| ≤ f_max).
    limit = 0.0
    for i in range(n):
        m, f = f_moment[i], f_force[i]
        bound = (f_max - m) / f if f > 0.0 else (-f_max - m) / f if f < 0.0 else math.inf
        if i == 0 or bound < limit:
            limit = bound
    at_least_0 = limit if limit > 0.0 else 0.0  # max(0.0, limit): 0 against NaN
    force_scale = at_least_0 if at_least_0 < 1.0 else 1.0
    for i in range(n):
        thrust[i] = f_moment[i] + force_scale * f_force[i]
    return force_scale, moment_scale


@njit(cache=True, error_model="numpy")
def _latch(time: float, R, nu: np.ndarray, u1: np.ndarray, u2: np.ndarray, t: float,
           latch: np.ndarray, target: np.ndarray, rate: np.ndarray) -> None:  # fmt: skip
    """An outer tick at ``time``: ``latch = [R u1_B, R v_B, R (9), time]``, the target
    ``Exp(u2 t) R`` and the rate ``u2``."""
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = R
    latch[0] = r00 * u1[0] + r01 * u1[1] + r02 * u1[2]
    latch[1] = r10 * u1[0] + r11 * u1[1] + r12 * u1[2]
    latch[2] = r20 * u1[0] + r21 * u1[1] + r22 * u1[2]
    latch[3] = r00 * nu[0] + r01 * nu[1] + r02 * nu[2]
    latch[4] = r10 * nu[0] + r11 * nu[1] + r12 * nu[2]
    latch[5] = r20 * nu[0] + r21 * nu[1] + r22 * nu[2]
    for c in range(9):
        latch[6 + c] = R[c]
    latch[15] = time
    R_target = _times3(exp_rotation(t * u2[0], t * u2[1], t * u2[2]), R)
    for c in range(9):
        target[c] = R_target[c]
    for c in range(3):
        rate[c] = u2[c]


@njit(cache=True, error_model="numpy")
def _tick(s: float, R, nu: np.ndarray, latch: np.ndarray, u2: np.ndarray, target: np.ndarray,
          hull: np.ndarray, values: np.ndarray, columns: np.ndarray, pinv: np.ndarray,
          law: np.ndarray,
          thrust: np.ndarray, wrench: np.ndarray, v_ref: np.ndarray, work: np.ndarray):  # fmt: skip
    """One controller tick ``s = τ − kt`` into the step for the vehicle at ``R``, ``nu``: the
    thrusts, the wrench and the velocity reference into the outputs; returns the allocation's
    ``(force_scale, moment_scale)`` (``work``: 4×max(n, 6) scratch). The law is
    ``LowLevelLaw``'s (``drake_uuv/plants/low_level_controller.py`` describes it)."""
    u, v, w, p, q, r = nu[0], nu[1], nu[2], nu[3], nu[4], nu[5]
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = R
    w_ref0, w_ref1, w_ref2 = 0.0, 0.0, 0.0
    R_k = (latch[6], latch[7], latch[8], latch[9], latch[10], latch[11], latch[12], latch[13],
           latch[14])  # fmt: skip
    if law[_TRAJECTORY] != 0.0:
        R_ref = _times3(exp_rotation(s * u2[0], s * u2[1], s * u2[2]), R_k)
        w_ref0, w_ref1, w_ref2 = u2[0], u2[1], u2[2]
    else:
        R_ref = (target[0], target[1], target[2], target[3], target[4], target[5], target[6],
                 target[7], target[8])  # fmt: skip
    e0, e1, e2 = log_rotation(_times_transpose3(R_ref, R))
    kp, kd, kv = law[_KP], law[_KD], law[_KV]
    # α_W = ω² e + 2ζω (ω_ref − R ω_B), a_W,cmd = a_W + ω_v (v_ref − R v_B).
    alpha0 = kp * e0 + kd * (w_ref0 - (r00 * p + r01 * q + r02 * r))
    alpha1 = kp * e1 + kd * (w_ref1 - (r10 * p + r11 * q + r12 * r))
    alpha2 = kp * e2 + kd * (w_ref2 - (r20 * p + r21 * q + r22 * r))
    a_W0, a_W1, a_W2 = latch[0], latch[1], latch[2]
    v_ref[0] = latch[3] + a_W0 * s
    v_ref[1] = latch[4] + a_W1 * s
    v_ref[2] = latch[5] + a_W2 * s
    c0 = a_W0 + kv * (v_ref[0] - (r00 * u + r01 * v + r02 * w))
    c1 = a_W1 + kv * (v_ref[1] - (r10 * u + r11 * v + r12 * w))
    c2 = a_W2 + kv * (v_ref[2] - (r20 * u + r21 * v + r22 * w))
    # ν̇_des = [R_WBᵀ a_W,cmd − ω_B × v_B, R_WBᵀ α_W] (v̇_W = R (v̇_B + ω_B × v_B)).
    nu_dot, nu_mid, momentum, bias = work[0, :6], work[1, :6], work[2, :6], work[3, :6]
    nu_dot[0] = r00 * c0 + r10 * c1 + r20 * c2 - (q * w - r * v)
    nu_dot[1] = r01 * c0 + r11 * c1 + r21 * c2 - (r * u - p * w)
    nu_dot[2] = r02 * c0 + r12 * c1 + r22 * c2 - (p * v - q * u)
    nu_dot[3] = r00 * alpha0 + r10 * alpha1 + r20 * alpha2
    nu_dot[4] = r01 * alpha0 + r11 * alpha1 + r21 * alpha2
    nu_dot[5] = r02 * alpha0 + r12 * alpha1 + r22 * alpha2
    # The thrust is held for h while ν moves on: the bias at mid-period, ν + ½h ν̇_des,
    # makes the held wrench right to second order in h (drag grows with the speed).
    half = 0.5 * law[_H]
    for i in range(6):
        nu_mid[i] = nu[i] + half * nu_dot[i]
    _times(values, columns, _M, nu_mid, momentum)
    _bias(nu_mid, momentum, r20, r21, r22, hull, bias)
    _times(values, columns, _M, nu_dot, momentum)
    for i in range(6):
        wrench[i] = momentum[i] + bias[i]
    return _allocate(wrench, pinv, law[_F_MAX], thrust, work)


@njit(cache=True, error_model="numpy")
def _rows9(a: np.ndarray):
    return a[0], a[1], a[2], a[3], a[4], a[5], a[6], a[7], a[8]


# --- Kernels over the runs -----------------------------------------------------------------


@njit(cache=True, error_model="numpy")
def derivative_runs(x: np.ndarray, command: np.ndarray, hull: np.ndarray,
                    values: np.ndarray, columns: np.ndarray, law: np.ndarray,
                    out: np.ndarray) -> None:  # fmt: skip
    """``ẋ`` of each run (``x``, ``out``: B×nx; ``command``: B×n) (``VehicleDynamics``)."""
    work = np.empty((9, max(x.shape[1], command.shape[1], 6)))
    drive, saturated = work[4], work[5]
    for b in range(x.shape[0]):
        _drive(command[b], values, columns, law, saturated, drive)
        _state_rates(x[b], drive, hull, values, columns, law, out[b], work[6:9])


@njit(cache=True, error_model="numpy")
def rk3_runs(x: np.ndarray, command: np.ndarray, h: float, hull: np.ndarray,
             values: np.ndarray, columns: np.ndarray, law: np.ndarray,
             out: np.ndarray) -> None:  # fmt: skip
    """One RK3 step of each run over h, its command held (B×nx, B×n → B×nx)."""
    work = np.empty((9, max(x.shape[1], command.shape[1], 6)))
    for b in range(x.shape[0]):
        _rk3(x[b], command[b], h, hull, values, columns, law, out[b], work)


@njit(cache=True, error_model="numpy")
def allocate_runs(wrench: np.ndarray, pinv: np.ndarray, f_max: float, thrust: np.ndarray,
                  scales: np.ndarray) -> None:  # fmt: skip
    """Each run's thrusts (B×n) and its force and moment scales (B×2) for its wrench (B×6)."""
    work = np.empty((2, pinv.shape[0]))
    for b in range(wrench.shape[0]):
        scales[b, 0], scales[b, 1] = _allocate(wrench[b], pinv, f_max, thrust[b], work)


@njit(cache=True, error_model="numpy")
def _count(saturation: np.ndarray, out: np.ndarray, ticks: float, force: float,
           moment: float, either: float) -> None:  # fmt: skip
    out[0] = saturation[0] + ticks
    out[1] = saturation[1] + force
    out[2] = saturation[2] + moment
    out[3] = saturation[3] + either


@njit(cache=True, error_model="numpy")
def stepped_runs(time: float, x: np.ndarray, u1: np.ndarray, u2: np.ndarray,
                 saturation: np.ndarray, hull: np.ndarray, values: np.ndarray,
                 columns: np.ndarray, pinv: np.ndarray, law: np.ndarray, x_out: np.ndarray,
                 latch: np.ndarray, target: np.ndarray, rate: np.ndarray, v_ref: np.ndarray,
                 thrust: np.ndarray, wrench: np.ndarray, scale: np.ndarray,
                 saturation_out: np.ndarray) -> None:  # fmt: skip
    """One outer step of each run (``SteppedHoveringAuv``): latch the commands at ``time``,
    then per controller tick the law's thrusts and one RK3 step of the vehicle under them.

    Reads the vehicle state ``x`` (B×nx), the commands (B×3 each) and the saturation counts
    (B×4); writes the state at the next outer tick, the latch (B×16), target (B×9), rate
    (B×3), and the last tick's velocity reference (B×3), thrusts (B×n), wrench (B×6) and
    scales (B×2), and the counts plus this step's.
    """
    n = pinv.shape[0]
    nx = x.shape[1]
    h, t, ticks = law[_H], law[_OUTER], int(law[_TICKS])
    work = np.empty((9, max(nx, n, 6)))
    state = np.empty(nx)
    for b in range(x.shape[0]):
        xb = x_out[b]
        for i in range(nx):
            state[i] = x[b, i]
        R = _rotation(state[3], state[4], state[5], state[6])
        _latch(time, R, state[7:13], u1[b], u2[b], t, latch[b], target[b], rate[b])
        force = moment = either = 0.0
        force_scale = moment_scale = 1.0
        for j in range(ticks):
            R = _rotation(state[3], state[4], state[5], state[6])
            force_scale, moment_scale = _tick(
                j * h,
                R,
                state[7:13],
                latch[b],
                rate[b],
                target[b],
                hull,
                values,
                columns,
                pinv,
                law,
                thrust[b],
                wrench[b],
                v_ref[b],
                work,
            )
            smaller = moment_scale if moment_scale < force_scale else force_scale
            if force_scale < 1.0:
                force += 1.0
            if moment_scale < 1.0:
                moment += 1.0
            if smaller < 1.0:
                either += 1.0
            _rk3(state, thrust[b], h, hull, values, columns, law, xb, work)
            for i in range(nx):
                state[i] = xb[i]
        scale[b, 0], scale[b, 1] = force_scale, moment_scale
        _count(saturation[b], saturation_out[b], float(ticks), force, moment, either)


@njit(cache=True, error_model="numpy")
def controller_runs(time: float, fresh: bool, R_WB: np.ndarray, nu_B: np.ndarray,
                    u1: np.ndarray, u2: np.ndarray, saturation: np.ndarray, hull: np.ndarray,
                    values: np.ndarray, columns: np.ndarray, pinv: np.ndarray,
                    law: np.ndarray, latch: np.ndarray,
                    target: np.ndarray, rate: np.ndarray, v_ref: np.ndarray,
                    thrust: np.ndarray, wrench: np.ndarray, scale: np.ndarray,
                    saturation_out: np.ndarray) -> None:  # fmt: skip
    """One controller tick of each run (``LowLevelController``) at ``time``, for the vehicle
    at ``R_WB`` (B×9), ``nu_B`` (B×6). ``fresh`` (an outer tick, the same for every run):
    latch the commands first into ``latch``, ``target``, ``rate``, else those hold the last
    latch on entry. Writes the tick's outputs and the counts plus one tick's."""
    work = np.empty((9, max(pinv.shape[0], 6)))
    for b in range(R_WB.shape[0]):
        R = _rows9(R_WB[b])
        if fresh:
            _latch(time, R, nu_B[b], u1[b], u2[b], law[_OUTER], latch[b], target[b], rate[b])
        force_scale, moment_scale = _tick(
            time - latch[b, 15],
            R,
            nu_B[b],
            latch[b],
            rate[b],
            target[b],
            hull,
            values,
            columns,
            pinv,
            law,
            thrust[b],
            wrench[b],
            v_ref[b],
            work,
        )
        scale[b, 0], scale[b, 1] = force_scale, moment_scale
        smaller = moment_scale if moment_scale < force_scale else force_scale
        _count(saturation[b], saturation_out[b], 1.0, 1.0 if force_scale < 1.0 else 0.0,
               1.0 if moment_scale < 1.0 else 0.0, 1.0 if smaller < 1.0 else 0.0)  # fmt: skip


@njit(cache=True, error_model="numpy")
def attitude_runs(x: np.ndarray, out: np.ndarray) -> None:
    """``R_WB`` (B×9, row-major) of each run's quaternion ``x[:, 3:7]`` (normalised)."""
    for b in range(x.shape[0]):
        R = _rotation(x[b, 3], x[b, 4], x[b, 5], x[b, 6])
        for c in range(9):
            out[b, c] = R[c]
