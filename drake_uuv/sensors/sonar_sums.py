"""The sums of the dual sonar's kernels in numpy's order, compiled with numba.

A 3-vector dot product as the fused multiply-add chain of the BLAS ``ddot`` that ``p @ p``
calls (OpenBLAS's kernel on an FMA CPU; :func:`dot3`), a sum of f values as numpy's pairwise
summation (:func:`_pairwise_sum`), ``np.maximum(x, 0.0)`` (:func:`_clip_at_zero`): with them
:mod:`drake_uuv.sensors.sonar_kernels` gives the bits of the single-run numpy of before.

numba's cache keys a compiled kernel on its own file's source only: after changing this file,
delete the cache of ``sonar_kernels.py`` and ``sonar_geometry.py``, whose kernels call these
(``drake_uuv/sensors/__pycache__/sonar_*.nb[ci]``), or they keep the old code.
"""

import numpy as np
from numba import njit, types
from numba.extending import intrinsic

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
