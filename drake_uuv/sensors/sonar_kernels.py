"""The dual sonar's arithmetic over a batch of runs: numba kernels that loop over runs.

One tick of B runs is one kernel call (:func:`measure_plain` for the paper's sonar,
:func:`measure` with timing, faults or a beam): numpy's cost per call would dominate at B = 1
(dozens of calls on 3-vectors) and its passes over (B, 3) arrays at B = 1000. Each run is
computed alone by scalar code, so its bits do not depend on B or on its place in the batch,
and a NaN run cannot raise (``error_model="numpy"``: a division by zero gives inf or NaN).

The arithmetic follows the single-run numpy of before operation by operation: a 3-vector dot
product is the fused multiply-add chain of the BLAS ``ddot`` that ``p @ p`` calls (OpenBLAS's
kernel on an FMA CPU; :func:`dot3`), a sum of f squares is numpy's pairwise summation
(:func:`_pairwise_sum`), and the world baseline ``R_WB b`` of the tick is computed by numpy
before the call (BLAS, as before). So the sonar at the paper's timing, with or without
faults, gives at B = 1 the bits it gave before. Rotations interpolated between ticks
(:func:`interpolate_attitude`) multiply 3×3 matrices without fused operations: their last
bits differ from the BLAS products of before (a range by ~1e-13 m).

Layouts (per run): the previous tick's geometry is :class:`~drake_uuv.sensors.sonar_timing.
TickGeometry`'s vector (35); a ping's entry (a FIFO slot) is f samples, status, multipath,
ping time, ``p_TS_W`` (f + 6); the packed output is :func:`~drake_uuv.sensors.dual_sonar.
output_layout`'s outputs one after the other, each ``B × size`` row-major by run.
"""

import math

import numpy as np
from numba import njit, types
from numba.extending import intrinsic

from drake_uuv.models.measurement import (
    DROPPED,
    NO_ARRIVAL,
    OUT_OF_BEAM,
    OUT_OF_RANGE,
    VALID,
)

#: Indices of the kernels' float settings (a vector of :data:`SETTINGS_SIZE` that
#: :class:`~drake_uuv.sensors.dual_sonar.SonarMeasurement` fills once).
(TIME_STEP, TAU1, TAU2, SCALE, SIGMA1, SIGMA2, ETA1, ETA2, M, GAMMA_CONSTANT, PAPER_PRINTED,
 MAX_RANGE, BEAM_HALF_ANGLE, DROPOUT1, DROPOUT2, OUTLIER_PROBABILITY, OUTLIER_SCALE, B0, B1,
 B2) = range(20)  # fmt: skip
SETTINGS_SIZE = 20

_SMALL_ANGLE = 1e-9
_NAN = math.nan

#: Every kernel: compiled once and cached on disk; IEEE division (a run's 0/0 gives NaN
#: instead of raising, which would stop the batch).
_jit = njit(cache=True, error_model="numpy")


@intrinsic
def _fma(typingctx, a, b, c):  # noqa: ANN001, ANN202 - numba's intrinsic protocol
    """``a·b + c`` rounded once (LLVM's ``fma``; a library call where the CPU has none)."""
    signature = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, sig, args):  # noqa: ANN001, ANN202
        return builder.fma(*args)

    return signature, codegen


@njit(cache=True, error_model="numpy", inline="always")
def dot3(a0: float, a1: float, a2: float, b0: float, b1: float, b2: float) -> float:
    """``a · b`` as the BLAS ``ddot`` of numpy's ``a @ b`` sums three terms: an FMA chain."""
    return _fma(a2, b2, _fma(a1, b1, a0 * b0))


@_jit
def _block_sum(a: np.ndarray, lo: int, n: int) -> float:
    """``a[lo:lo + n].sum()`` for ``n ≤ 128`` as numpy sums it (8 accumulators from 8 on)."""
    if n < 8:
        res = 0.0
        for i in range(n):
            res += a[lo + i]
        return res
    r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
    r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
    i = 8
    end = n - n % 8
    while i < end:
        r0 += a[lo + i]
        r1 += a[lo + i + 1]
        r2 += a[lo + i + 2]
        r3 += a[lo + i + 3]
        r4 += a[lo + i + 4]
        r5 += a[lo + i + 5]
        r6 += a[lo + i + 6]
        r7 += a[lo + i + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += a[lo + i]
        i += 1
    return res


@_jit
def _pairwise_sum(a: np.ndarray, lo: int, n: int) -> float:
    """``a[lo:lo + n].sum()`` as numpy sums it: blocks of up to 128 (:func:`_block_sum`),
    longer runs split in two halves (a multiple of 8 first) and summed left + right.

    numpy's recursion, unrolled with a stack of pending halves (a cached numba function
    must not call itself)."""
    if n <= 128:
        return _block_sum(a, lo, n)
    depth = 64
    los, ns = np.empty(depth, np.int64), np.empty(depth, np.int64)
    lefts, waiting = np.empty(depth), np.zeros(depth, np.int64)
    los[0], ns[0], waiting[0] = lo, n, 0
    top, result, returned = 1, 0.0, False
    while top > 0:
        k = top - 1
        if returned:  # the half on top of frame k came back with result
            if waiting[k] == 0:  # its left half: keep it, sum the right half
                lefts[k], waiting[k], returned = result, 1, False
                half = ns[k] // 2
                half -= half % 8
                los[top], ns[top], waiting[top] = los[k] + half, ns[k] - half, 0
                top += 1
            else:  # its right half: frame k is done
                result = lefts[k] + result
                top -= 1
            continue
        if ns[k] <= 128:
            result, returned = _block_sum(a, los[k], ns[k]), True
            top -= 1
        else:
            half = ns[k] // 2
            half -= half % 8
            los[top], ns[top], waiting[top] = los[k], half, 0
            top += 1
    return result


@njit(cache=True, error_model="numpy", inline="always")
def _clip_at_zero(x: float) -> float:
    """``np.maximum(x, 0.0)`` (NaN stays NaN)."""
    return x if x > 0.0 or x != x else 0.0


@_jit
def _paper_measurement(
    arrivals: np.ndarray, f: int, settings: np.ndarray, squares: np.ndarray
) -> tuple[float, float, float]:
    """``(Y, m, Γ)`` of one run's arriving samples (row i of ``arrivals``, its first f
    entries, sonar i's), as :func:`~drake_uuv.models.measurement.paper_measurement`;
    ``squares`` is scratch (f)."""
    mean_square1 = mean_square2 = 0.0
    for i in range(2):
        for j in range(f):
            x = arrivals[i, j]
            squares[j] = x * x
        if i == 0:
            mean_square1 = _pairwise_sum(squares, 0, f) / f
        else:
            mean_square2 = _pairwise_sum(squares, 0, f) / f
    eta1, eta2 = settings[ETA1], settings[ETA2]
    if settings[PAPER_PRINTED] != 0.0:
        gamma = (
            settings[GAMMA_CONSTANT]
            + 4 * (mean_square1 - eta1) * eta1
            + 4 * (mean_square2 - eta2) * eta2
        )
    else:
        gamma = (
            eta1 * _clip_at_zero(mean_square1 - eta1)
            + eta2 * _clip_at_zero(mean_square2 - eta2)
            + settings[GAMMA_CONSTANT]
        )
    d1, d2 = arrivals[0, 0], arrivals[1, 0]
    return 0.5 * (d1 * d1 - d2 * d2), settings[M], gamma


@_jit
def _write_run(
    out: np.ndarray,
    B: int,
    f: int,
    r: int,
    arrivals: np.ndarray,
    q_s: np.ndarray,
    settings: np.ndarray,
    squares: np.ndarray,
) -> None:
    """Writes run r's outputs from its arriving entries (``arrivals`` 2 × (f + 6)) into the
    packed output, each output's block ``B × size``."""
    Y, m, gamma = _paper_measurement(arrivals, f, settings, squares)
    o = 0
    for i in range(2):  # ranges
        out[o + 2 * r + i] = arrivals[i, 0]
    o += 2 * B
    for i in range(2):  # range_samples
        for j in range(f):
            out[o + 2 * f * r + i * f + j] = arrivals[i, j]
    o += 2 * f * B
    out[o + r] = Y
    o += B
    out[o + r] = m
    o += B
    out[o + r] = gamma
    o += B
    for k in range(3):  # b_W
        out[o + 3 * r + k] = q_s[r, k]
    o += 3 * B
    for field in range(3):  # sonar_status, multipath, ping_time
        for i in range(2):
            out[o + 2 * r + i] = arrivals[i, f + field]
        o += 2 * B
    for i in range(2):  # p_TS_W
        for k in range(3):
            out[o + 6 * r + 3 * i + k] = arrivals[i, f + 3 + k]


@_jit
def measure_plain(
    now: float,
    q_s: np.ndarray,
    p_WU: np.ndarray,
    p_WT: np.ndarray,
    noise: np.ndarray,
    settings: np.ndarray,
    out: np.ndarray,
) -> None:
    """The paper's sonar (pings at the tick, every range returned) of B runs into ``out``.

    ``q_s``, ``p_WU``, ``p_WT`` (B, 3), ``noise`` (B, 2f) standard normal."""
    B = q_s.shape[0]
    f = noise.shape[1] // 2
    arrivals = np.empty((2, f + 6))
    squares = np.empty(f)
    scale = settings[SCALE]
    for r in range(B):
        for i in range(2):
            for k in range(3):
                half = 0.5 * q_s[r, k]
                arrivals[i, f + 3 + k] = p_WU[r, k] - p_WT[r, k] + (half if i == 0 else -half)
            p0, p1, p2 = arrivals[i, f + 3], arrivals[i, f + 4], arrivals[i, f + 5]
            measured = scale * math.sqrt(dot3(p0, p1, p2, p0, p1, p2))
            sigma = settings[SIGMA1 + i]
            for j in range(f):
                arrivals[i, j] = measured + sigma * noise[r, i * f + j]
            arrivals[i, f] = VALID
            arrivals[i, f + 1] = 0.0
            arrivals[i, f + 2] = now
        _write_run(out, B, f, r, arrivals, q_s, settings, squares)


# --- Rotations: one run's 3×3 matrices as 9-vectors, row-major (no reshape per run) --------


@_jit
def _copy9(A: np.ndarray, out: np.ndarray) -> None:
    for c in range(9):
        out[c] = A[c]


@_jit
def _matmul33(A: np.ndarray, B: np.ndarray, C: np.ndarray) -> None:
    """``C = A B``."""
    for i in range(3):
        for j in range(3):
            C[3 * i + j] = A[3 * i] * B[j] + A[3 * i + 1] * B[3 + j] + A[3 * i + 2] * B[6 + j]


@_jit
def _matmul33_bt(A: np.ndarray, B: np.ndarray, C: np.ndarray) -> None:
    """``C = A Bᵀ``."""
    for i in range(3):
        for j in range(3):
            C[3 * i + j] = (
                A[3 * i] * B[3 * j] + A[3 * i + 1] * B[3 * j + 1] + A[3 * i + 2] * B[3 * j + 2]
            )


@_jit
def _log_so3(R: np.ndarray, q: np.ndarray, out: np.ndarray) -> None:
    """``out = Log(R)`` as :func:`~drake_uuv.models.so3.log_so3` (Shepperd's quaternion,
    then its angle); ``q`` is scratch (4)."""
    d0, d1, d2 = R[0], R[4], R[8]
    trace = d0 + d1 + d2
    if d0 != d0:  # NaN: the first NaN, as np.argmax
        i = 0
    elif d1 != d1:
        i = 1
    elif d2 != d2:
        i = 2
    else:
        i = 0 if d0 >= d1 else 1
        if d2 > R[4 * i]:
            i = 2
    if trace >= R[4 * i]:
        w = 0.5 * math.sqrt(_clip_at_zero(1.0 + trace))
        s = 0.25 / w
        q[0] = w
        q[1] = (R[7] - R[5]) * s
        q[2] = (R[2] - R[6]) * s
        q[3] = (R[3] - R[1]) * s
    else:
        j, k = (i + 1) % 3, (i + 2) % 3
        v = 0.5 * math.sqrt(_clip_at_zero(1.0 + R[4 * i] - R[4 * j] - R[4 * k]))
        s = 0.25 / v
        q[0] = (R[3 * k + j] - R[3 * j + k]) * s
        q[1 + i] = v
        q[1 + j] = (R[3 * j + i] + R[3 * i + j]) * s
        q[1 + k] = (R[3 * k + i] + R[3 * i + k]) * s
    if q[0] < 0.0:
        for c in range(4):
            q[c] = -q[c]
    n = math.sqrt(_fma(q[3], q[3], dot3(q[0], q[1], q[2], q[0], q[1], q[2])))
    for c in range(4):
        q[c] = q[c] / n
    s = math.sqrt(dot3(q[1], q[2], q[3], q[1], q[2], q[3]))
    factor = 2.0 if s < _SMALL_ANGLE else 2.0 * math.atan2(s, q[0]) / s
    for c in range(3):
        out[c] = factor * q[1 + c]


@_jit
def _exp_so3(w: np.ndarray, K: np.ndarray, K2: np.ndarray, R: np.ndarray) -> None:
    """``R = Exp(w)`` as :func:`~drake_uuv.models.so3.exp_so3` (Rodrigues); ``K``, ``K2``
    are scratch (9)."""
    theta = math.sqrt(dot3(w[0], w[1], w[2], w[0], w[1], w[2]))
    K[0], K[1], K[2] = 0.0, -w[2], w[1]
    K[3], K[4], K[5] = w[2], 0.0, -w[0]
    K[6], K[7], K[8] = -w[1], w[0], 0.0
    _matmul33(K, K, K2)
    if theta < _SMALL_ANGLE:
        a, b = 1.0, 0.5
    else:
        a, b = math.sin(theta) / theta, (1.0 - math.cos(theta)) / (theta * theta)
    for c in range(9):
        R[c] = (1.0 if c % 4 == 0 else 0.0) + a * K[c] + b * K2[c]


@_jit
def interpolate_attitude(
    R0: np.ndarray, R1: np.ndarray, s: float, scratch: np.ndarray, out: np.ndarray
) -> None:
    """``out``: the attitude at fraction ``s`` of the geodesic from ``R0`` to ``R1`` (9 each,
    row-major), ``Exp(s Log(R1 R0ᵀ)) R0`` (:func:`~drake_uuv.models.ping_geometry.
    interpolate_attitude`); ``scratch`` (5, 9), ``out`` not ``R0``."""
    if s == 0.0:
        _copy9(R0, out)
        return
    relative, K, K2, step, vectors = scratch[0], scratch[1], scratch[2], scratch[3], scratch[4]
    _matmul33_bt(R1, R0, relative)
    w = vectors[:3]
    _log_so3(relative, vectors[3:7], w)
    for c in range(3):
        w[c] = s * w[c]
    _exp_so3(w, K, K2, step)
    _matmul33(step, R0, out)


def beam_axis(
    R_WB: np.ndarray, R_point: np.ndarray, q_prior: np.ndarray, offset: np.ndarray, sign: float,
    baseline: np.ndarray,
) -> np.ndarray:  # fmt: skip
    """The world direction a ping's pan-tilt points along, from the sonar to the predicted
    target (``R_WB``, ``R_point`` 3×3).

    The vehicle aims from the sonar at the predicted target, ``−(q_prior + offset)`` with the
    offset ``± ½ R_point b`` it believes; the pan-tilt turns that into the body frame by the
    attitude it believes (``R_point``, the navigated one) and the true attitude carries it
    back to the world: ``R_WB R_pointᵀ (−(q_prior ± ½ R_point b))``. Pointing by the true
    attitude, the axis is the predicted direction itself (computed as such)."""
    axis = np.empty(3)
    _beam_axis(
        np.ascontiguousarray(R_WB, dtype=float).ravel(),
        np.ascontiguousarray(R_point, dtype=float).ravel(),
        np.asarray(q_prior, dtype=float), np.asarray(offset, dtype=float), float(sign),
        np.asarray(baseline, dtype=float), axis,
    )  # fmt: skip
    return axis


@_jit
def _beam_axis(
    R_WB: np.ndarray, R_point: np.ndarray, q_prior: np.ndarray, offset: np.ndarray, sign: float,
    baseline: np.ndarray, axis: np.ndarray,
) -> None:  # fmt: skip
    """:func:`beam_axis` into ``axis``, the matrices as 9-vectors."""
    same = True
    for c in range(9):
        if R_point[c] != R_WB[c]:
            same = False
    if same:
        for k in range(3):
            axis[k] = -(q_prior[k] + offset[k])
        return
    aim = np.empty(3)
    for k in range(3):
        aim[k] = (
            R_point[k] * -q_prior[0] + R_point[3 + k] * -q_prior[1] + R_point[6 + k] * -q_prior[2]
        ) - sign * 0.5 * baseline[k]
    for k in range(3):
        axis[k] = R_WB[3 * k] * aim[0] + R_WB[3 * k + 1] * aim[1] + R_WB[3 * k + 2] * aim[2]


@_jit
def _out_of_beam(p_TS: np.ndarray, axis: np.ndarray, radius: float, beam_half_angle: float) -> bool:
    """Whether the target (``−p_TS`` from the sonar) is off the pan-tilt's cone about
    ``axis``: the wider of the beam and the scanned region's angular radius."""
    distance = math.sqrt(dot3(axis[0], axis[1], axis[2], axis[0], axis[1], axis[2]))
    scanned = math.pi if radius >= distance else math.asin(radius / distance)
    half_angle = scanned if scanned > beam_half_angle else beam_half_angle
    t0, t1, t2 = -p_TS[0], -p_TS[1], -p_TS[2]
    to_target = math.sqrt(dot3(t0, t1, t2, t0, t1, t2))
    cos_angle = dot3(t0, t1, t2, axis[0], axis[1], axis[2]) / (to_target * distance + 1e-300)
    return cos_angle < math.cos(half_angle)


# --- The general sonar: timing, faults, a beam ----------------------------------------------


@_jit
def measure(
    now: float,
    q_s: np.ndarray,
    p_WU: np.ndarray,
    R_WB: np.ndarray,
    p_WT: np.ndarray,
    noise: np.ndarray,
    v_WU: np.ndarray,
    v_WT: np.ndarray,
    previous: np.ndarray,
    prior: np.ndarray,
    R_nav: np.ndarray,
    radius: np.ndarray,
    uniform: np.ndarray,
    exponential: np.ndarray,
    fifo1: np.ndarray,
    fifo2: np.ndarray,
    delays: np.ndarray,
    flags: np.ndarray,
    settings: np.ndarray,
    out: np.ndarray,
    next_previous: np.ndarray,
    next_fifo1: np.ndarray,
    next_fifo2: np.ndarray,
) -> None:
    """B runs of a sonar with timing, faults or a beam: the packed outputs into ``out`` and,
    with timing, the next state (this tick's geometry, the FIFOs moved on by the pings
    measured now) into ``next_*``.

    Per run: ``q_s``, ``p_WU``, ``p_WT`` (3), ``R_WB`` (9), ``noise`` (2f); with timing
    (``flags[0]``) ``v_WU``, ``v_WT`` (3), ``previous`` (35) and sonar i's FIFO ``fifo{i}``
    ((d_i − 1)(f + 6), empty for d_i < 2); with a beam (``flags[1]``) ``prior`` (6),
    ``R_nav`` (9), ``radius`` (1, the scanned radius); with random faults (``flags[2]``)
    ``uniform`` (4), ``exponential`` (2). Arrays of a feature that is off are not read."""
    B = q_s.shape[0]
    f = noise.shape[1] // 2
    E = f + 6
    timed, beam, random = flags[0] != 0, flags[1] != 0, flags[2] != 0
    time_step = settings[TIME_STEP]
    scale = settings[SCALE]
    baseline = settings[B0 : B2 + 1]
    measured = np.empty((2, E))
    arrivals = np.empty((2, E))
    squares = np.empty(f)
    nan3 = np.full(3, _NAN)
    offset, axis, q_prior = np.empty(3), np.empty(3), np.empty(3)
    R_ping, R_point = np.empty(9), np.empty(9)
    scratch = np.empty((5, 9))
    for r in range(B):
        R = R_WB[r]
        R_point_tick = R_nav[r] if beam else R
        q_prior_tick = prior[r, :3] if beam else nan3
        radius_tick = radius[r, 0] if beam else _NAN
        first_tick = (not timed) or previous[r, 0] != previous[r, 0]
        for i in range(2):
            sign = 1.0 if i == 0 else -1.0
            p_TS = measured[i, f + 3 :]
            has_ping = True
            ping_radius = radius_tick
            if delays[i] == 0:  # the ping at the tick
                time = now
                for k in range(3):
                    half = 0.5 * q_s[r, k]
                    offset[k] = half if i == 0 else -half
                    p_TS[k] = p_WU[r, k] - p_WT[r, k] + offset[k]
                _copy9(R, R_ping)
                _copy9(R_point_tick, R_point)
                for k in range(3):
                    q_prior[k] = q_prior_tick[k]
            elif first_tick:  # no ping between ticks before the first
                has_ping = False
                time = _NAN
                for k in range(3):
                    p_TS[k] = _NAN
            else:  # the ping of the previous step, from the geometry of both ticks
                g = previous[r]
                tau = settings[TAU1 + i]
                s = tau / time_step
                s2, s3 = s * s, s * s * s
                h00, h10 = 2 * s3 - 3 * s2 + 1, s3 - 2 * s2 + s
                h01, h11 = -2 * s3 + 3 * s2, s3 - s2
                interpolate_attitude(g[7:16], R, s, scratch, R_ping)
                if beam:
                    interpolate_attitude(g[26:35], R_point_tick, s, scratch, R_point)
                for k in range(3):
                    q = (
                        h00 * (g[1 + k] - g[16 + k])
                        + h10 * time_step * (g[4 + k] - g[19 + k])
                        + h01 * (p_WU[r, k] - p_WT[r, k])
                        + h11 * time_step * (v_WU[r, k] - v_WT[r, k])
                    )
                    half = 0.5 * (
                        R_ping[3 * k + 0] * baseline[0]
                        + R_ping[3 * k + 1] * baseline[1]
                        + R_ping[3 * k + 2] * baseline[2]
                    )
                    offset[k] = half if i == 0 else -half
                    p_TS[k] = q + offset[k]
                    q_prior[k] = g[22 + k]
                time = g[0] + tau
                ping_radius = g[25]
            true_range = 0.0
            if has_ping:
                true_range = math.sqrt(dot3(p_TS[0], p_TS[1], p_TS[2], p_TS[0], p_TS[1], p_TS[2]))
            status = VALID
            if true_range > settings[MAX_RANGE]:
                status = OUT_OF_RANGE
            if beam and has_ping and status == VALID:
                _beam_axis(R_ping, R_point, q_prior, offset, sign, baseline, axis)
                if _out_of_beam(p_TS, axis, ping_radius, settings[BEAM_HALF_ANGLE]):
                    status = OUT_OF_BEAM
            multipath = 0.0
            if random:
                if status == VALID and uniform[r, i] < settings[DROPOUT1 + i]:
                    status = DROPPED
                if uniform[r, 2 + i] < settings[OUTLIER_PROBABILITY]:
                    multipath = settings[OUTLIER_SCALE] * exponential[r, i]
            sigma = settings[SIGMA1 + i]
            measured_range = scale * true_range
            for j in range(f):
                measured[i, j] = measured_range + sigma * noise[r, i * f + j]
                if random:
                    measured[i, j] += multipath
            if not has_ping:
                status, multipath = NO_ARRIVAL, 0.0
            if status != VALID:
                for j in range(f):
                    measured[i, j] = _NAN
            measured[i, f] = status
            measured[i, f + 1] = multipath
            measured[i, f + 2] = time
        for c in range(E):  # sonar i's arrival: the oldest of its FIFO, or the ping now
            arrivals[0, c] = fifo1[r, c] if delays[0] >= 2 else measured[0, c]
            arrivals[1, c] = fifo2[r, c] if delays[1] >= 2 else measured[1, c]
        _write_run(out, B, f, r, arrivals, q_s, settings, squares)
        if timed:
            g = next_previous[r]
            g[0] = now
            for k in range(3):
                g[1 + k] = p_WU[r, k]
                g[4 + k] = v_WU[r, k]
                g[16 + k] = p_WT[r, k]
                g[19 + k] = v_WT[r, k]
                g[22 + k] = q_prior_tick[k]
            g[25] = radius_tick
            for k in range(9):
                g[7 + k] = R_WB[r, k]
                g[26 + k] = R_point_tick[k]
            _push(fifo1, measured[0], r, next_fifo1)
            _push(fifo2, measured[1], r, next_fifo2)


@_jit
def _push(fifo: np.ndarray, entry: np.ndarray, r: int, next_fifo: np.ndarray) -> None:
    """Run r's FIFO (oldest first) without its oldest entry and with ``entry`` appended."""
    n, E = fifo.shape[1], entry.shape[0]
    if n == 0:
        return
    for c in range(n - E):
        next_fifo[r, c] = fifo[r, E + c]
    for c in range(E):
        next_fifo[r, n - E + c] = entry[c]
