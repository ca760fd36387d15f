"""Scoring the information-seeking planner's candidates over its horizon: numba kernels.

The kernels of :class:`~drake_uuv.models.information_planner.InformationSeekingPlanner`
(its module notes state the model, the criteria and the horizon): :func:`scores_kernel`
scores every candidate of each run, and :mod:`drake_uuv.models.information_choice`'s plan
kernel calls :func:`_score_candidates` before it constrains and chooses. The covariance
propagation is written out for the double integrator ``A = [[I, tI], [0, I]]``; the 3×3
eigenvalues (the excitation, E-optimality of the position block) are in closed form
(Smith's), 6×6 ones by cyclic Jacobi. The options and parameters by position, below, are
both modules' layout.

numba's cache keys a compiled kernel on its own file's source only (a change in a function it
calls from another file goes unnoticed): after changing this file, delete the cache of
``information_choice.py`` too (``drake_uuv/models/__pycache__/information_choice.*.nb[ci]``).
"""

import math

import numpy as np
from numba import njit

from drake_uuv.models.measurement import MIN_RANGE

# One loop over runs, and in it over candidates: run i's numbers are the same whatever the
# batch. Scalar code on small stack-like buffers, because at one run numpy's cost per call
# (dozens of calls on n×6×6 stacks per horizon step) dominated the planner's step, and at a
# thousand runs its passes over (B, n, 6, 6) temporaries did. ``error_model="numpy"``: a run
# holding NaN or inf gives NaN (and some candidate), never an exception.

# Integer options (``_options``) and float parameters (``_parameters``) by position.
_MEASUREMENT, _CRITERION, _BLOCK, _PREDICTION, _LAG, _SCORED, _WINDOW, _CAP = range(8)
_THRESHOLD_SET = 8
_T, _NORM, _ETA, _ETA_F, _FLOOR, _MAX_REFERENCE, _EPSILON, _THRESHOLD = 0, 1, 2, 4, 6, 7, 8, 9
_RANGE_DIFFERENCE, _RANGES = 0, 1
_D_OPTIMAL, _A_OPTIMAL, _E_OPTIMAL = 0, 1, 2
_HOLD, _COAST, _REFERENCE = 0, 1, 2
_TINY = 1e-12  # attitude_candidates' guard of a zero rotation's axis
_TIE = 1e-10  # relative difference of two objectives below which they tie
_MIN_RANGE = MIN_RANGE


@njit(cache=True, error_model="numpy")
def _rotate(p0, p1, p2, v0, v1, v2):  # pragma: no cover - compiled
    """``Exp(φ) v`` (Rodrigues, as ``attitude_candidates.rotate_vectors``)."""
    angle = math.sqrt(p0 * p0 + p1 * p1 + p2 * p2)
    d = angle if angle > _TINY else _TINY
    a0, a1, a2 = p0 / d, p1 / d, p2 / d
    c, s = math.cos(angle), math.sin(angle)
    dot = a0 * v0 + a1 * v1 + a2 * v2
    k = 1.0 - c
    return (
        v0 * c + (a1 * v2 - a2 * v1) * s + a0 * dot * k,
        v1 * c + (a2 * v0 - a0 * v2) * s + a1 * dot * k,
        v2 * c + (a0 * v1 - a1 * v0) * s + a2 * dot * k,
    )


@njit(cache=True, error_model="numpy")
def _symmetric_eigen_3(a00, a01, a02, a11, a12, a22):  # pragma: no cover - compiled
    """Smallest and largest eigenvalue of a symmetric 3×3 (closed form, Smith 1961)."""
    p1 = a01 * a01 + a02 * a02 + a12 * a12
    q = (a00 + a11 + a22) / 3.0
    b00, b11, b22 = a00 - q, a11 - q, a22 - q
    p = math.sqrt((b00 * b00 + b11 * b11 + b22 * b22 + 2.0 * p1) / 6.0)
    if p == 0.0:
        return q, q
    c00, c11, c22 = b00 / p, b11 / p, b22 / p
    c01, c02, c12 = a01 / p, a02 / p, a12 / p
    r = 0.5 * (c00 * (c11 * c22 - c12 * c12) - c01 * (c01 * c22 - c12 * c02)
               + c02 * (c01 * c12 - c11 * c02))  # fmt: skip
    r = -1.0 if r < -1.0 else (1.0 if r > 1.0 else r)
    phi = math.acos(r) / 3.0
    return q + 2.0 * p * math.cos(phi + 2.0 * math.pi / 3.0), q + 2.0 * p * math.cos(phi)


@njit(cache=True, error_model="numpy")
def _largest_eigenvalue(M, n, work):  # pragma: no cover - compiled
    """Largest eigenvalue of the symmetric leading n×n block of M (cyclic Jacobi)."""
    for i in range(n):
        for j in range(n):
            work[i, j] = M[i, j]
    for _ in range(60):
        off = 0.0
        scale = 0.0
        for i in range(n):
            scale += work[i, i] * work[i, i]
            for j in range(i + 1, n):
                off += work[i, j] * work[i, j]
        if not off > 1e-30 * scale:  # converged (or NaN)
            break
        for p in range(n):
            for q in range(p + 1, n):
                apq = work[p, q]
                if apq == 0.0:
                    continue
                theta = (work[q, q] - work[p, p]) / (2.0 * apq)
                t = (1.0 if theta >= 0.0 else -1.0) / (abs(theta) + math.sqrt(theta * theta + 1.0))
                c = 1.0 / math.sqrt(t * t + 1.0)
                s = t * c
                for k in range(n):
                    akp, akq = work[k, p], work[k, q]
                    work[k, p], work[k, q] = c * akp - s * akq, s * akp + c * akq
                for k in range(n):
                    apk, aqk = work[p, k], work[q, k]
                    work[p, k], work[q, k] = c * apk - s * aqk, s * apk + c * aqk
    largest = work[0, 0]
    for i in range(1, n):
        if work[i, i] > largest or work[i, i] != work[i, i]:
            largest = work[i, i]
    return largest


@njit(cache=True, error_model="numpy")
def _criterion(P, criterion, n, work):  # pragma: no cover - compiled
    """The criterion of the leading n×n block of a covariance (higher is better)."""
    if criterion == _A_OPTIMAL:
        trace = P[0, 0]
        for i in range(1, n):
            trace += P[i, i]
        return -trace
    if criterion == _E_OPTIMAL:
        if n == 3:
            return 1.0 / _symmetric_eigen_3(P[0, 0], P[0, 1], P[0, 2], P[1, 1], P[1, 2], P[2, 2])[1]
        return 1.0 / _largest_eigenvalue(P, n, work)
    # D-optimal: −log|det|, by Gaussian elimination with partial pivoting (as slogdet).
    for i in range(n):
        for j in range(n):
            work[i, j] = P[i, j]
    log_det = 0.0
    for k in range(n):
        pivot = k
        for i in range(k + 1, n):
            if abs(work[i, k]) > abs(work[pivot, k]):
                pivot = i
        if pivot != k:
            for j in range(n):
                work[k, j], work[pivot, j] = work[pivot, j], work[k, j]
        log_det += math.log(abs(work[k, k]))
        for i in range(k + 1, n):
            factor = work[i, k] / work[k, k]
            for j in range(k + 1, n):
                work[i, j] -= factor * work[k, j]
    return -log_det


@njit(cache=True, error_model="numpy")
def _predict(P, t, Q, AP, out):  # pragma: no cover - compiled
    """``A P Aᵀ + Q`` for the double integrator ``A = [[I, tI], [0, I]]``, written out."""
    for i in range(6):
        for k in range(6):
            AP[i, k] = P[i, k] + t * P[i + 3, k] if i < 3 else P[i, k]
    for i in range(6):
        for k in range(6):
            out[i, k] = (AP[i, k] + t * AP[i, k + 3] if k < 3 else AP[i, k]) + Q[i, k]


@njit(cache=True, error_model="numpy")
def _update(prior, rows, r, noise, PHt, gain, out):  # pragma: no cover - compiled
    """``P − P Hᵀ (H P Hᵀ + R)⁻¹ H P``, symmetrised, for ``r`` rows ``H = [rows, 0]`` (the
    measurements see the position only) and ``R = diag(noise)``."""
    for i in range(6):
        for m in range(r):
            PHt[i, m] = (
                prior[i, 0] * rows[m, 0] + prior[i, 1] * rows[m, 1] + prior[i, 2] * rows[m, 2]
            )
    if r == 1:
        S = rows[0, 0] * PHt[0, 0] + rows[0, 1] * PHt[1, 0] + rows[0, 2] * PHt[2, 0] + noise[0]
        for i in range(6):
            gain[i, 0] = PHt[i, 0] / S
    else:
        S00 = rows[0, 0] * PHt[0, 0] + rows[0, 1] * PHt[1, 0] + rows[0, 2] * PHt[2, 0] + noise[0]
        S01 = rows[0, 0] * PHt[0, 1] + rows[0, 1] * PHt[1, 1] + rows[0, 2] * PHt[2, 1]
        S10 = rows[1, 0] * PHt[0, 0] + rows[1, 1] * PHt[1, 0] + rows[1, 2] * PHt[2, 0]
        S11 = rows[1, 0] * PHt[0, 1] + rows[1, 1] * PHt[1, 1] + rows[1, 2] * PHt[2, 1] + noise[1]
        det = S00 * S11 - S01 * S10
        for i in range(6):  # gain = (S⁻¹ (P Hᵀ)ᵀ)ᵀ
            gain[i, 0] = (S11 * PHt[i, 0] - S01 * PHt[i, 1]) / det
            gain[i, 1] = (S00 * PHt[i, 1] - S10 * PHt[i, 0]) / det
    for i in range(6):
        for k in range(i, 6):
            a = prior[i, k] - gain[i, 0] * PHt[k, 0]
            b = prior[k, i] - gain[k, 0] * PHt[i, 0]
            if r == 2:
                a -= gain[i, 1] * PHt[k, 1]
                b -= gain[k, 1] * PHt[i, 1]
            out[i, k] = out[k, i] = 0.5 * (a + b)


@njit(cache=True, error_model="numpy")
def _rows(q, q_s, ranges, eta, rows, noise):  # pragma: no cover - compiled
    """The planned-for measurement at position ``q`` and world baseline ``q_s``: the paper's
    ``Y`` (one row ``q_s``, variance Γ of the derived model at the true ranges) or the two
    ranges (unit lines of sight from each sonar, variances η); returns the row count."""
    h0, h1, h2 = 0.5 * q_s[0], 0.5 * q_s[1], 0.5 * q_s[2]
    if not ranges:
        rows[0, 0], rows[0, 1], rows[0, 2] = q_s[0], q_s[1], q_s[2]
        d0, d1, d2 = q[0] + h0, q[1] + h1, q[2] + h2
        true_0 = (d0 * d0 + d1 * d1 + d2 * d2 + eta[0]) - eta[0]  # as range_difference_noise
        d0, d1, d2 = q[0] - h0, q[1] - h1, q[2] - h2
        true_1 = (d0 * d0 + d1 * d1 + d2 * d2 + eta[1]) - eta[1]
        true_0 = 0.0 if true_0 < 0.0 else true_0
        true_1 = 0.0 if true_1 < 0.0 else true_1
        noise[0] = eta[0] * true_0 + eta[1] * true_1 + 0.5 * (eta[0] ** 2 + eta[1] ** 2)
        return 1
    for m in range(2):
        sign = 1.0 if m == 0 else -1.0
        d0, d1, d2 = q[0] + sign * h0, q[1] + sign * h1, q[2] + sign * h2
        length = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        length = length if length > _MIN_RANGE else _MIN_RANGE
        rows[m, 0], rows[m, 1], rows[m, 2] = d0 / length, d1 / length, d2 / length
        noise[m] = eta[m]
    return 2


@njit(cache=True, error_model="numpy")
def _score_candidates(
    options, parameters, Q, x, P, baseline, r_q, rotation, baselines, first, count, linear,
    scores, firsts, buffers,
):  # pragma: no cover - compiled  # fmt: skip
    """The criterion summed over the scored horizon of candidates ``first`` to
    ``first + count − 1`` of one run (each rotation repeated every step of the horizon;
    ``baselines`` their first steps' world baselines), into ``scores``; with ``firsts`` of
    ``count`` rows, their ``P(k+1|k+1)`` too."""
    t = parameters[_T]
    ranges = options[_MEASUREMENT] == _RANGES and not linear
    first_eta = _ETA if options[_MEASUREMENT] == _RANGE_DIFFERENCE else _ETA_F
    eta = parameters[first_eta : first_eta + 2]
    prediction, lag, block = options[_PREDICTION], options[_LAG], options[_BLOCK]
    first_prior, prior, posterior, AP, work = (
        buffers[0], buffers[1], buffers[2], buffers[3], buffers[4]
    )  # fmt: skip
    PHt, gain = buffers[5, :, :2], buffers[5, :, 2:4]
    rows, noise = buffers[6, :2, :3], buffers[6, 2, :2]
    q, q_s = buffers[6, 3, :3], buffers[6, 4, :3]
    _predict(P, t, Q, AP, first_prior)  # the same prior for every candidate
    keep = firsts.shape[0] == count
    for c in range(first, first + count):
        p0, p1, p2 = rotation[c, 0], rotation[c, 1], rotation[c, 2]
        score = 0.0
        for j in range(1, options[_SCORED] + 1):
            if prediction == _HOLD:
                q[0], q[1], q[2] = x[0], x[1], x[2]
            elif prediction == _COAST:
                jt = j * t
                q[0], q[1], q[2] = x[0] + jt * x[3], x[1] + jt * x[4], x[2] + jt * x[5]
            elif j <= lag:  # the lagging reference has not turned yet: Exp(0) r = r
                q[0], q[1], q[2] = r_q[0], r_q[1], r_q[2]
            else:
                steps = float(j - lag)
                q[0], q[1], q[2] = _rotate(
                    steps * p0, steps * p1, steps * p2, r_q[0], r_q[1], r_q[2]
                )
            if j == 1:
                q_s[0], q_s[1], q_s[2] = baselines[c, 0], baselines[c, 1], baselines[c, 2]
            else:
                q_s[0], q_s[1], q_s[2] = _rotate(
                    j * p0, j * p1, j * p2, baseline[0], baseline[1], baseline[2]
                )
            m = _rows(q, q_s, ranges, eta, rows, noise)
            if j == 1:
                _update(first_prior, rows, m, noise, PHt, gain, posterior)
                if keep:
                    firsts[c - first] = posterior
            else:
                _predict(posterior, t, Q, AP, prior)
                _update(prior, rows, m, noise, PHt, gain, posterior)
            score += _criterion(posterior, options[_CRITERION], block, work)
        scores[c] = score


@njit(cache=True, error_model="numpy")
def _candidate_baselines(rotation, baseline, out):  # pragma: no cover - compiled
    """The world baseline after each candidate's first step, ``Exp(φ_c) R b``."""
    for c in range(rotation.shape[0]):
        out[c, 0], out[c, 1], out[c, 2] = _rotate(
            rotation[c, 0], rotation[c, 1], rotation[c, 2], baseline[0], baseline[1], baseline[2]
        )


@njit(cache=True, error_model="numpy")
def _buffers():  # pragma: no cover - compiled
    return np.empty((7, 6, 6))


@njit(cache=True, error_model="numpy")
def scores_kernel(
    options, parameters, b, q_star, Q, x_hat, P, R_WB, rotation, linear
):  # pragma: no cover - compiled
    runs, n = x_hat.shape[0], rotation.shape[1]
    scores = np.empty((runs, n))
    firsts = np.empty((runs, n, 6, 6))
    buffers = _buffers()
    baseline, r_q = np.empty(3), np.empty(3)
    baselines = np.empty((n, 3))
    for i in range(runs):
        R = R_WB[i]
        for a in range(3):
            baseline[a] = R[a, 0] * b[0] + R[a, 1] * b[1] + R[a, 2] * b[2]
            r_q[a] = R[a, 0] * q_star[0] + R[a, 1] * q_star[1] + R[a, 2] * q_star[2]
        _candidate_baselines(rotation[i], baseline, baselines)
        _score_candidates(options, parameters, Q, x_hat[i], P[i], baseline, r_q, rotation[i],
                          baselines, 0, n, linear[i] > 0.0, scores[i], firsts[i],
                          buffers)  # fmt: skip
    return scores, firsts
