"""The dual sonar's arithmetic over a batch of runs: numba kernels that loop over runs.

One tick of B runs is one kernel call (:func:`measure_plain` for the paper's sonar,
:func:`measure` with timing, faults or a beam): numpy's cost per call would dominate at B = 1
(dozens of calls on 3-vectors) and its passes over (B, 3) arrays at B = 1000. Each run is
computed alone by scalar code, so its bits do not depend on B or on its place in the batch,
and a NaN run cannot raise (``error_model="numpy"``: a division by zero gives inf or NaN).

The arithmetic follows the single-run numpy of before operation by operation: a 3-vector dot
product is the fused multiply-add chain of the BLAS ``ddot`` that ``p @ p`` calls, a sum of f
squares is numpy's pairwise summation (both :mod:`drake_uuv.sensors.sonar_sums`'), and the
world baseline ``R_WB b`` of the tick is computed by numpy before the call (BLAS, as before).
So the sonar at the paper's timing, with or without faults, gives at B = 1 the bits it gave
before. Rotations interpolated between ticks and the pan-tilt's beam are
:mod:`drake_uuv.sensors.sonar_geometry`'s (its interpolated rotations' last bits differ from
the BLAS products of before: a range by ~1e-13 m).

Layouts (per run): the previous tick's geometry is :class:`~drake_uuv.sensors.sonar_timing.
TickGeometry`'s vector (35); a ping's entry (a FIFO slot) is f samples, status, multipath,
ping time, ``p_TS_W`` (f + 6); the packed output is :func:`~drake_uuv.sensors.dual_sonar.
output_layout`'s outputs one after the other, each ``B × size`` row-major by run.

numba's cache keys a compiled kernel on its own file's source only: after changing
``sonar_sums.py`` or ``sonar_geometry.py``, whose functions these kernels call, delete this
file's cache (``drake_uuv/sensors/__pycache__/sonar_kernels.*.nb[ci]``).
"""

import math

import numpy as np
from numba import njit

from drake_uuv.models.measurement import (
    DROPPED,
    NO_ARRIVAL,
    OUT_OF_BEAM,
    OUT_OF_RANGE,
    VALID,
)
from drake_uuv.sensors.sonar_geometry import (
    _beam_axis,
    _copy9,
    _out_of_beam,
    interpolate_attitude,
)
from drake_uuv.sensors.sonar_geometry import beam_axis as beam_axis  # importable from here
from drake_uuv.sensors.sonar_sums import _clip_at_zero, _pairwise_sum, dot3

#: Indices of the kernels' float settings (a vector of :data:`SETTINGS_SIZE` that
#: :class:`~drake_uuv.sensors.dual_sonar.SonarMeasurement` fills once).
(TIME_STEP, TAU1, TAU2, SCALE, SIGMA1, SIGMA2, ETA1, ETA2, M, GAMMA_CONSTANT, PAPER_PRINTED,
 MAX_RANGE, BEAM_HALF_ANGLE, DROPOUT1, DROPOUT2, OUTLIER_PROBABILITY, OUTLIER_SCALE, B0, B1,
 B2) = range(20)  # fmt: skip
SETTINGS_SIZE = 20

_NAN = math.nan

#: Every kernel: compiled once and cached on disk; IEEE division (a run's 0/0 gives NaN
#: instead of raising, which would stop the batch).
_jit = njit(cache=True, error_model="numpy")


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


# --- The general sonar: timing, faults, a beam ----------------------------------------------


@_jit
def measure(
    now: float, q_s: np.ndarray, p_WU: np.ndarray, R_WB: np.ndarray, p_WT: np.ndarray,
    noise: np.ndarray, v_WU: np.ndarray, v_WT: np.ndarray, previous: np.ndarray,
    prior: np.ndarray, R_nav: np.ndarray, radius: np.ndarray, uniform: np.ndarray,
    exponential: np.ndarray, fifo1: np.ndarray, fifo2: np.ndarray, delays: np.ndarray,
    flags: np.ndarray, settings: np.ndarray, out: np.ndarray, next_previous: np.ndarray,
    next_fifo1: np.ndarray, next_fifo2: np.ndarray,
) -> None:  # fmt: skip
    """B runs of a sonar with timing, faults or a beam: the packed outputs into ``out`` and,
    with timing, the next state (this tick's geometry, the FIFOs moved on by the pings
    measured now) into ``next_*``.

    Per run: ``q_s``, ``p_WU``, ``p_WT`` (3), ``R_WB`` (9), ``noise`` (2f); with timing
    (``flags[0]``) ``v_WU``, ``v_WT`` (3), ``previous`` (35) and sonar i's FIFO ``fifo{i}``
    ((d_i − 1)(f + 6), empty for d_i < 2); with a beam (``flags[1]``) ``prior`` (6),
    ``R_nav`` (9), ``radius`` (1, the scanned radius); with random faults (``flags[2]``)
    ``uniform`` (4), ``exponential`` (2). Arrays of a feature that is off are not read.

    Each sonar's ping of the tick is placed by :func:`_ping` and measured by :func:`_judge`;
    with timing, :func:`_remember` keeps this tick's geometry for the next."""
    B = q_s.shape[0]
    f = noise.shape[1] // 2
    E = f + 6
    timed, beam, random = flags[0] != 0, flags[1] != 0, flags[2] != 0
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
            p_TS = measured[i, f + 3 :]
            has_ping, time, ping_radius = _ping(
                i, r, now, first_tick, beam, q_s, p_WU, p_WT, v_WU, v_WT, R, R_point_tick,
                q_prior_tick, radius_tick, previous, delays, settings, scratch, offset,
                q_prior, R_ping, R_point, p_TS,
            )  # fmt: skip
            _judge(i, r, f, has_ping, time, ping_radius, beam, random, p_TS, offset, q_prior,
                   R_ping, R_point, noise, uniform, exponential, settings, axis,
                   measured)  # fmt: skip
        for c in range(E):  # sonar i's arrival: the oldest of its FIFO, or the ping now
            arrivals[0, c] = fifo1[r, c] if delays[0] >= 2 else measured[0, c]
            arrivals[1, c] = fifo2[r, c] if delays[1] >= 2 else measured[1, c]
        _write_run(out, B, f, r, arrivals, q_s, settings, squares)
        if timed:
            _remember(r, now, p_WU, v_WU, p_WT, v_WT, R_WB, R_point_tick, q_prior_tick,
                      radius_tick, next_previous)  # fmt: skip
            _push(fifo1, measured[0], r, next_fifo1)
            _push(fifo2, measured[1], r, next_fifo2)


@_jit
def _ping(
    i, r, now, first_tick, beam, q_s, p_WU, p_WT, v_WU, v_WT, R, R_point_tick, q_prior_tick,
    radius_tick, previous, delays, settings, scratch, offset, q_prior, R_ping, R_point, p_TS,
):  # fmt: skip
    """Where sonar i's ping measured at this tick was, for run r: ``p_TS``, the sonar's
    ``offset`` from U, the attitudes ``R_ping`` (true) and ``R_point`` (believed) and the
    prior ``q_prior`` it was aimed by; returns ``(has_ping, time, radius)``: whether there was
    a ping, its time and its scanned radius. Sonar i without delay pings at the tick; with
    one, its ping of the previous step, from the geometry of both ticks (``previous``)."""
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
        time_step = settings[TIME_STEP]
        baseline = settings[B0 : B2 + 1]
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
    return has_ping, time, ping_radius


@_jit
def _judge(
    i, r, f, has_ping, time, ping_radius, beam, random, p_TS, offset, q_prior, R_ping, R_point,
    noise, uniform, exponential, settings, axis, measured,
) -> None:  # fmt: skip
    """Sonar i's ping of run r measured into ``measured[i]``: its f samples (NaN unless
    VALID), status (out of range, out of the beam, dropped, no arrival), multipath and ping
    time; ``axis`` is scratch (3)."""
    sign = 1.0 if i == 0 else -1.0
    true_range = 0.0
    if has_ping:
        true_range = math.sqrt(dot3(p_TS[0], p_TS[1], p_TS[2], p_TS[0], p_TS[1], p_TS[2]))
    status = VALID
    if true_range > settings[MAX_RANGE]:
        status = OUT_OF_RANGE
    if beam and has_ping and status == VALID:
        baseline = settings[B0 : B2 + 1]
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
    measured_range = settings[SCALE] * true_range
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


@_jit
def _remember(
    r, now, p_WU, v_WU, p_WT, v_WT, R_WB, R_point_tick, q_prior_tick, radius_tick, next_previous
) -> None:  # fmt: skip
    """Run r's geometry of this tick into ``next_previous`` (:class:`~drake_uuv.sensors.
    sonar_timing.TickGeometry`'s vector), for the pings measured at the next tick."""
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
