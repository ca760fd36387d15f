"""Rotations as 9-tuples (row-major) for the vehicle's kernels, compiled with numba.

``Exp`` (Rodrigues) and ``Log`` (from the skew part up to a quarter turn, via Shepperd's
quaternion beyond), and the 3×3 products ``A B`` and ``A Bᵀ``, on Python floats as
:mod:`drake_uuv.models.vehicle_kernels` calls them: the operations of the Python-float code
they took over, in the same order; where that code called numpy's dot (the rotation logarithm
beyond a quarter turn), ``_dot_self`` repeats what OpenBLAS computes on this machine's CPU
(fused multiply-adds). ``error_model="numpy"``: NaN in, NaN out, never an exception.

numba's cache keys a compiled kernel on its own file's source only: after changing this file,
delete the cache of ``vehicle_kernels.py``, whose kernels call these
(``drake_uuv/models/__pycache__/vehicle_kernels.*.nb[ci]``), or they keep the old code.
"""

import math

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic

_SMALL_ANGLE = 1e-9


@intrinsic
def _fma(typingctx, a, b, c):
    """``a b + c`` rounded once (LLVM's ``fma``, exact in software where the CPU has none)."""
    signature = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, sig, args):
        double = ir.DoubleType()
        function = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(double, [double] * 3), "llvm.fma.f64"
        )
        return builder.call(function, args)

    return signature, codegen


@njit(cache=True, error_model="numpy")
def _dot_self(q: np.ndarray, start: int) -> float:
    """``q[start:] @ q[start:]`` as numpy's dot of a short vector computes it here (OpenBLAS:
    a chain of fused multiply-adds), so the rare branch that called it keeps its bits."""
    total = q[start] * q[start]
    for i in range(start + 1, q.shape[0]):
        total = _fma(q[i], q[i], total)
    return total


@njit(cache=True, error_model="numpy")
def exp_rotation(w0: float, w1: float, w2: float):
    """``Exp(w)`` (Rodrigues), 9 floats row-major: ``I + a K + b K²``, ``K² = w wᵀ − θ² I``."""
    squared = w0 * w0 + w1 * w1 + w2 * w2
    theta = math.sqrt(squared)
    if theta < _SMALL_ANGLE:
        a, b = 1.0, 0.5
    else:
        a, b = math.sin(theta) / theta, (1.0 - math.cos(theta)) / squared
    c = 1.0 - b * squared
    return (
        c + b * w0 * w0, b * w0 * w1 - a * w2, b * w0 * w2 + a * w1,
        b * w0 * w1 + a * w2, c + b * w1 * w1, b * w1 * w2 - a * w0,
        b * w0 * w2 - a * w1, b * w1 * w2 + a * w0, c + b * w2 * w2,
    )  # fmt: skip


@njit(cache=True, error_model="numpy")
def _times3(A, B):
    """``A B`` for two 3×3 matrices as 9-tuples, row-major."""
    a00, a01, a02, a10, a11, a12, a20, a21, a22 = A
    b00, b01, b02, b10, b11, b12, b20, b21, b22 = B
    return (
        a00 * b00 + a01 * b10 + a02 * b20, a00 * b01 + a01 * b11 + a02 * b21,
        a00 * b02 + a01 * b12 + a02 * b22,
        a10 * b00 + a11 * b10 + a12 * b20, a10 * b01 + a11 * b11 + a12 * b21,
        a10 * b02 + a11 * b12 + a12 * b22,
        a20 * b00 + a21 * b10 + a22 * b20, a20 * b01 + a21 * b11 + a22 * b21,
        a20 * b02 + a21 * b12 + a22 * b22,
    )  # fmt: skip


@njit(cache=True, error_model="numpy")
def _times_transpose3(A, B):
    """``A Bᵀ`` for two 3×3 matrices as 9-tuples (the products of ``_times3``, in its order)."""
    b00, b01, b02, b10, b11, b12, b20, b21, b22 = B
    return _times3(A, (b00, b10, b20, b01, b11, b21, b02, b12, b22))


@njit(cache=True, error_model="numpy")
def _log_via_quaternion(E):
    """``Log(E)`` through Shepperd's quaternion (``so3.log_so3``): any angle up to π."""
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = E
    d0, d1, d2 = m00, m11, m22
    trace = d0 + d1 + d2
    if d0 != d0:  # NaN: the first NaN on the diagonal, as np.argmax
        i = 0
    elif d1 != d1:
        i = 1
    elif d2 != d2:
        i = 2
    else:
        i = 0 if d0 >= d1 else 1
        if d2 > (d0 if i == 0 else d1):
            i = 2
    largest = d0 if i == 0 else d1 if i == 1 else d2
    q = np.empty(4)
    if trace >= largest:
        arg = 1.0 + trace
        w = 0.5 * math.sqrt(0.0 if 0.0 > arg else arg)
        s = 0.25 / w
        q[0], q[1], q[2], q[3] = w, (m21 - m12) * s, (m02 - m20) * s, (m10 - m01) * s
    else:
        M = ((m00, m01, m02), (m10, m11, m12), (m20, m21, m22))
        j, k = (i + 1) % 3, (i + 2) % 3
        arg = 1.0 + M[i][i] - M[j][j] - M[k][k]
        v = 0.5 * math.sqrt(0.0 if 0.0 > arg else arg)
        s = 0.25 / v
        q[0] = (M[k][j] - M[j][k]) * s
        q[1 + i] = v
        q[1 + j] = (M[j][i] + M[i][j]) * s
        q[1 + k] = (M[k][i] + M[i][k]) * s
    if q[0] < 0.0:
        for c in range(4):
            q[c] = -q[c]
    length = math.sqrt(_dot_self(q, 0))
    for c in range(4):
        q[c] = q[c] / length
    s = math.sqrt(_dot_self(q, 1))
    if s < _SMALL_ANGLE:
        return 2.0 * q[1], 2.0 * q[2], 2.0 * q[3]
    k = 2.0 * math.atan2(s, q[0]) / s
    return k * q[1], k * q[2], k * q[3]


@njit(cache=True, error_model="numpy")
def log_rotation(E):
    """``Log(E)`` (9-tuple, row-major), the rotation vector of angle in [0, π].

    Up to a quarter turn (the attitude errors of a tracking loop) from the skew part
    ``sin θ n`` and the trace ``1 + 2 cos θ``, ``θ = atan2(sin θ, cos θ)``; beyond, where
    ``sin θ`` loses its digits toward a half turn, via the quaternion.
    """
    e00, e01, e02, e10, e11, e12, e20, e21, e22 = E
    cosine = 0.5 * (e00 + e11 + e22 - 1.0)
    if cosine < 0.0:
        return _log_via_quaternion(E)
    v0, v1, v2 = 0.5 * (e21 - e12), 0.5 * (e02 - e20), 0.5 * (e10 - e01)
    sine = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    if sine < _SMALL_ANGLE:
        return v0, v1, v2
    k = math.atan2(sine, cosine) / sine
    return k * v0, k * v1, k * v2
