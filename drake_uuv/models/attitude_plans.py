"""The paper's attitude plans and the attitude command, for a batch of runs.

* :func:`zeta` and :func:`trajectory_attitude`: Algorithm 2's desired baseline direction
  ``ζ(k)`` and the attitude ``R̄(k)`` that takes the body baseline ``b`` along it (one step:
  the plan depends on k alone, so a batch computes it once and every run uses it).
* :func:`attitude_commands`: ``u2 = Log(R̄ Rᵀ)/t`` per run (so that
  ``R(k+1) = Exp(u2 t) R(k) = R̄``), scaled down to a rate limit where a run exceeds it;
  :func:`planned_attitudes`: the next two attitudes those commands produce.
  :func:`attitude_command` is the single-run form.
* :func:`quaternion_attitudes`: Algorithm 1's uniformly random attitude per run from a
  standard-normal 4-vector.

The per-run kernels are compiled with numba (``cache=True``): a loop over runs whose
arithmetic for run i is the same whatever the batch, where the dozens of numpy calls of a
batched ``Log`` would cost ten times more than the rest of a single run's attitude step. The
SO(3) formulas are :mod:`drake_uuv.models.so3`'s (Shepperd's quaternion, Rodrigues), written
out on scalars. ``error_model="numpy"``: a run holding NaN gives NaN, never an exception.
"""

import math

import numpy as np
from numba import njit

from drake_uuv.models.so3 import minimal_rotation, norm

_SMALL_ANGLE = 1e-9


def zeta(
    k: int, baseline_norm: float, rho: float, h_amplitude: float, h_frequency: float
) -> np.ndarray:
    """Algorithm 2's desired baseline direction ``ζ(k) = |b| [sin(ρkπ), cos(ρkπ), h(k)]``.

    ``h(k) = h_amplitude · cos(h_frequency · kπ)``; the paper uses ρ = 1/24, h = ½ cos(kπ/6).
    """
    return baseline_norm * np.array(
        [
            math.sin(rho * k * math.pi),
            math.cos(rho * k * math.pi),
            h_amplitude * math.cos(h_frequency * k * math.pi),
        ]
    )


def trajectory_attitude(
    k: int, baseline_B: np.ndarray, rho: float, h_amplitude: float, h_frequency: float
) -> np.ndarray:
    """Algorithm 2's ``R̄(k)``: the minimal rotation taking ``b`` along ``ζ(k)``.

    The paper writes the axis as "a product of b and ζ": it is the normalised cross product
    ``b × ζ`` and the angle ``arccos(bᵀζ / (|b||ζ|))`` (:func:`~drake_uuv.models.so3.
    minimal_rotation`, which also handles the parallel and antiparallel cases).
    """
    target = zeta(k, norm(baseline_B), rho, h_amplitude, h_frequency)
    return minimal_rotation(baseline_B, target)


# ------------------------------------------------------------ scalar SO(3) kernels (numba)


@njit(cache=True, error_model="numpy")
def log_so3_kernel(M: np.ndarray) -> tuple[float, float, float]:  # pragma: no cover - compiled
    """``Log`` of one 3×3 rotation (Shepperd's quaternion, then the angle in [0, π])."""
    m00, m01, m02 = M[0, 0], M[0, 1], M[0, 2]
    m10, m11, m12 = M[1, 0], M[1, 1], M[1, 2]
    m20, m21, m22 = M[2, 0], M[2, 1], M[2, 2]
    trace = m00 + m11 + m22
    i = 0 if m00 >= m11 else 1
    largest = m00 if i == 0 else m11
    if m22 > largest:
        i, largest = 2, m22
    if trace >= largest:
        w = 0.5 * math.sqrt(max(1.0 + trace, 0.0))
        s = 0.25 / w
        x, y, z = (m21 - m12) * s, (m02 - m20) * s, (m10 - m01) * s
    elif i == 0:
        v = 0.5 * math.sqrt(max(1.0 + m00 - m11 - m22, 0.0))
        s = 0.25 / v
        w, x, y, z = (m21 - m12) * s, v, (m10 + m01) * s, (m20 + m02) * s
    elif i == 1:
        v = 0.5 * math.sqrt(max(1.0 + m11 - m22 - m00, 0.0))
        s = 0.25 / v
        w, x, y, z = (m02 - m20) * s, (m01 + m10) * s, v, (m21 + m12) * s
    else:
        v = 0.5 * math.sqrt(max(1.0 + m22 - m00 - m11, 0.0))
        s = 0.25 / v
        w, x, y, z = (m10 - m01) * s, (m02 + m20) * s, (m12 + m21) * s, v
    if w < 0.0:
        w, x, y, z = -w, -x, -y, -z
    scale = 1.0 / math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w * scale, x * scale, y * scale, z * scale
    s = math.sqrt(x * x + y * y + z * z)
    if s < _SMALL_ANGLE:
        return 2.0 * x, 2.0 * y, 2.0 * z
    factor = 2.0 * math.atan2(s, w) / s
    return factor * x, factor * y, factor * z


@njit(cache=True, error_model="numpy")
def exp_so3_kernel(w0: float, w1: float, w2: float, out: np.ndarray) -> None:  # pragma: no cover
    """``Exp`` of one rotation vector (Rodrigues) into ``out`` (3×3)."""
    theta = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    if theta < _SMALL_ANGLE:
        a, b = 1.0, 0.5
    else:
        a, b = math.sin(theta) / theta, (1.0 - math.cos(theta)) / (theta * theta)
    # K = hat(w); K² = w wᵀ − |w|² I, written per entry.
    out[0, 0] = 1.0 + b * (-(w1 * w1) - w2 * w2)
    out[1, 1] = 1.0 + b * (-(w0 * w0) - w2 * w2)
    out[2, 2] = 1.0 + b * (-(w0 * w0) - w1 * w1)
    out[0, 1] = -a * w2 + b * (w0 * w1)
    out[1, 0] = a * w2 + b * (w0 * w1)
    out[0, 2] = a * w1 + b * (w0 * w2)
    out[2, 0] = -a * w1 + b * (w0 * w2)
    out[1, 2] = -a * w0 + b * (w1 * w2)
    out[2, 1] = a * w0 + b * (w1 * w2)


@njit(cache=True, error_model="numpy")
def matmul3_kernel(A: np.ndarray, B: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover
    """``out = A B`` for 3×3 (summed in index order)."""
    for i in range(3):
        for j in range(3):
            out[i, j] = A[i, 0] * B[0, j] + A[i, 1] * B[1, j] + A[i, 2] * B[2, j]


@njit(cache=True, error_model="numpy")
def _command(
    R_desired: np.ndarray, R_WB: np.ndarray, time_step: float, max_rate: float, scratch: np.ndarray
) -> tuple[float, float, float]:  # pragma: no cover - compiled
    """``Log(R̄ Rᵀ)/t``, scaled down to norm ``max_rate`` (``inf``: no limit)."""
    for i in range(3):
        for j in range(3):
            scratch[i, j] = (
                R_desired[i, 0] * R_WB[j, 0]
                + R_desired[i, 1] * R_WB[j, 1]
                + R_desired[i, 2] * R_WB[j, 2]
            )
    r0, r1, r2 = log_so3_kernel(scratch)
    r0, r1, r2 = r0 / time_step, r1 / time_step, r2 / time_step
    rate_norm = math.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
    if rate_norm > max_rate:  # this run's limit: a mask, the others are untouched
        scale = max_rate / rate_norm
        r0, r1, r2 = r0 * scale, r1 * scale, r2 * scale
    return r0, r1, r2


@njit(cache=True, error_model="numpy")
def _commands(
    R_desired: np.ndarray, R_WB: np.ndarray, time_step: float, max_rate: float
) -> np.ndarray:  # pragma: no cover - compiled
    runs = R_WB.shape[0]
    shared = R_desired.shape[0] == 1
    out = np.empty((runs, 3))
    scratch = np.empty((3, 3))
    for i in range(runs):
        desired = R_desired[0] if shared else R_desired[i]
        out[i, 0], out[i, 1], out[i, 2] = _command(desired, R_WB[i], time_step, max_rate, scratch)
    return out


@njit(cache=True, error_model="numpy")
def _plans(
    R_desired: np.ndarray,
    R_desired_next: np.ndarray,
    R_WB: np.ndarray,
    time_step: float,
    max_rate: float,
) -> np.ndarray:  # pragma: no cover - compiled
    runs = R_WB.shape[0]
    shared = R_desired.shape[0] == 1
    known_next = R_desired_next.shape[0] > 0
    shared_next = R_desired_next.shape[0] == 1
    out = np.empty((runs, 2, 3, 3))
    scratch = np.empty((3, 3))
    turn = np.empty((3, 3))
    for i in range(runs):
        desired = R_desired[0] if shared else R_desired[i]
        r0, r1, r2 = _command(desired, R_WB[i], time_step, max_rate, scratch)
        exp_so3_kernel(r0 * time_step, r1 * time_step, r2 * time_step, turn)
        matmul3_kernel(turn, R_WB[i], out[i, 0])
        if known_next:
            desired = R_desired_next[0] if shared_next else R_desired_next[i]
            r0, r1, r2 = _command(desired, out[i, 0], time_step, max_rate, scratch)
            exp_so3_kernel(r0 * time_step, r1 * time_step, r2 * time_step, turn)
            matmul3_kernel(turn, out[i, 0], out[i, 1])
        else:
            out[i, 1] = out[i, 0]
    return out.reshape(runs, 18)


@njit(cache=True, error_model="numpy")
def _quaternion_attitudes(noise: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    runs = noise.shape[0]
    out = np.empty((runs, 3, 3))
    for i in range(runs):
        w, x, y, z = noise[i, 0], noise[i, 1], noise[i, 2], noise[i, 3]
        scale = math.sqrt(w * w + x * x + y * y + z * z)
        w, x, y, z = w / scale, x / scale, y / scale, z / scale
        R = out[i]
        R[0, 0], R[0, 1], R[0, 2] = (
            1 - 2 * (y * y + z * z),
            2 * (x * y - w * z),
            2 * (x * z + w * y),
        )
        R[1, 0], R[1, 1], R[1, 2] = (
            2 * (x * y + w * z),
            1 - 2 * (x * x + z * z),
            2 * (y * z - w * x),
        )
        R[2, 0], R[2, 1], R[2, 2] = (
            2 * (x * z - w * y),
            2 * (y * z + w * x),
            1 - 2 * (x * x + y * y),
        )
    return out


# ------------------------------------------------------------------- over a batch of runs


def _rate_limit(max_rate: float | None) -> float:
    return math.inf if max_rate is None else float(max_rate)


def _matrices(R: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(R, dtype=float).reshape(-1, 3, 3)


def attitude_commands(
    R_desired: np.ndarray, R_WB: np.ndarray, time_step: float, max_rate: float | None
) -> np.ndarray:
    """``u2 = Log(R̄ Rᵀ) / t`` [rad/s, world frame] per run, ``(B, 3)``.

    ``R_WB`` holds B attitudes (``(B, 3, 3)`` or ``B·9`` row-major); ``R_desired`` one per run
    or one for all (``(1, 3, 3)`` or ``(3, 3)``). A run whose command exceeds ``max_rate``
    (None: no limit) is scaled down to that norm: its attitude moves towards ``R̄`` along the
    same geodesic without reaching it.
    """
    return _commands(_matrices(R_desired), _matrices(R_WB), float(time_step), _rate_limit(max_rate))


def planned_attitudes(
    R_desired: np.ndarray,
    R_desired_next: np.ndarray | None,
    R_WB: np.ndarray,
    time_step: float,
    max_rate: float | None,
) -> np.ndarray:
    """``[R(k+1), R(k+2)]`` per run, ``(B, 18)`` row-major: ``R(k+1) = Exp(u2(k) t) R(k)``
    with :func:`attitude_commands`' u2, and ``R(k+2)`` the same law applied towards
    ``R_desired_next`` (``R̄(k+1)``; None: not known at k, the plan holds ``R(k+1)``).
    ``R_desired`` and ``R_desired_next`` are one per run or one for all runs."""
    following = np.empty((0, 3, 3)) if R_desired_next is None else _matrices(R_desired_next)
    return _plans(
        _matrices(R_desired), following, _matrices(R_WB), float(time_step), _rate_limit(max_rate)
    )


def attitude_command(
    R_desired: np.ndarray, R_WB: np.ndarray, time_step: float, max_rate: float | None
) -> np.ndarray:
    """:func:`attitude_commands` of one run: ``u2`` (3)."""
    return attitude_commands(R_desired, R_WB, time_step, max_rate)[0]


def quaternion_attitudes(noise: np.ndarray) -> np.ndarray:
    """The rotation of each normalised 4-vector ``[w, x, y, z]`` (``(B, 4)`` → ``(B, 3, 3)``):
    a standard-normal 4-vector gives a uniformly random rotation."""
    return _quaternion_attitudes(np.ascontiguousarray(noise, dtype=float).reshape(-1, 4))
