"""Tracking laws on the relative double integrator, as plain numpy (the gains, the paper's
law, the LQR gain and the reference feed-forward).

Every law here acts on the filtered relative state ``x̂ = [q̂, ϑ̂]`` (world frame) and
produces a world acceleration ``a = R u1``; written as ``a = a_ff − K (x̂ − x_ref)`` its gain
``K`` (3×6) fixes the closed-loop eigenvalues of ``A − B K``
(:func:`closed_loop_eigenvalues`).
"""

import math

import numpy as np
from numba import njit
from pydrake.systems.controllers import DiscreteTimeLinearQuadraticRegulator

from drake_uuv.models.motion import double_integrator

#: Frames the desired relative position q* may be fixed in: the body (the paper's), the
#: world, or the body's heading (yaw only).
REFERENCE_FRAMES = ("body", "world", "heading")


def heading_rotations(R_WB: np.ndarray) -> np.ndarray:
    """``R_z(ψ)`` (…×3×3) for attitudes ``R_WB`` (…×3×3): the rotation about world z by the
    body's heading ψ (the yaw of its x axis).

    ψ = atan2(R₁₀, R₀₀), the Z-Y-X yaw; where the body's x axis is vertical (no heading), the
    heading of its y axis stands in: ψ = atan2(−R₀₁, R₁₁). Each attitude takes its own branch
    (a compiled loop over them), so one attitude's value never depends on the others'.
    """
    R = np.asarray(R_WB, dtype=float)
    out = np.zeros(R.shape)
    _heading_kernel(np.ascontiguousarray(R).reshape(-1, 3, 3), out.reshape(-1, 3, 3))
    return out


@njit(cache=True)
def _heading_kernel(R: np.ndarray, out: np.ndarray) -> None:
    for n in range(R.shape[0]):
        c, s = R[n, 0, 0], R[n, 1, 0]
        if math.hypot(c, s) < 1e-9:
            c, s = R[n, 1, 1], -R[n, 0, 1]
        h = math.hypot(c, s)
        c, s = c / h, s / h
        out[n, 0, 0] = c
        out[n, 0, 1] = -s
        out[n, 1, 0] = s
        out[n, 1, 1] = c
        out[n, 2, 2] = 1.0


def heading_rotation(R_WB: np.ndarray) -> np.ndarray:
    """``R_z(ψ)`` (3×3) of one attitude (:func:`heading_rotations`)."""
    return heading_rotations(np.asarray(R_WB, dtype=float).reshape(1, 3, 3))[0]


def _check_frame(frame: str) -> None:
    if frame not in REFERENCE_FRAMES:
        raise ValueError(
            f"reference_frame: must be one of {', '.join(REFERENCE_FRAMES)}, got {frame!r}"
        )


def reference_rotations(R_WB: np.ndarray, frame: str) -> np.ndarray:
    """``R_WF`` (…×3×3): the rotation from the frame F that q* is fixed in to the world, at
    each attitude ``R_WB`` (…×3×3); the desired relative position is then ``r = R_WF q*``."""
    _check_frame(frame)
    R = np.asarray(R_WB, dtype=float)
    if frame == "body":
        return R
    if frame == "world":
        return np.broadcast_to(np.eye(3), R.shape)
    return heading_rotations(R)


def reference_rotation(R_WB: np.ndarray, frame: str) -> np.ndarray:
    """``R_WF`` (3×3) at one attitude ``R_WB`` (:func:`reference_rotations`)."""
    return reference_rotations(np.asarray(R_WB, dtype=float).reshape(3, 3), frame)


def desired_relative_positions(R_WB: np.ndarray, q_star: np.ndarray, frame: str) -> np.ndarray:
    """``r = R_WF q*`` (…×3, world frame) at each attitude ``R_WB`` (…×3×3; a flat N×9 stack
    is read as N×3×3)."""
    R = np.asarray(R_WB, dtype=float)
    if R.shape[-2:] != (3, 3):
        R = R.reshape(*R.shape[:-1], 3, 3)
    q_star = np.asarray(q_star, dtype=float)
    return rotate(reference_rotations(R, frame), q_star)


def rotate(R: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``R v`` (…×3) for matrices ``R`` (…×3×3) and vectors ``v`` (…×3) with the same leading
    axes (or ``v`` one 3-vector for all): a compiled loop, each product alone."""
    return _rotated(R, v, False)


def rotate_back(R: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``Rᵀ v`` (…×3), as :func:`rotate`."""
    return _rotated(R, v, True)


def _rotated(R: np.ndarray, v: np.ndarray, transpose: bool) -> np.ndarray:
    R = np.ascontiguousarray(R, dtype=float)
    v = np.ascontiguousarray(v, dtype=float)
    if v.size not in (3, R.size // 3):
        raise ValueError(f"v: must be one 3-vector or one per matrix, got shape {v.shape}")
    out = np.empty(R.shape[:-1])
    # One vector for every matrix is read in place (no broadcast copy).
    _rotate_kernel(R.reshape(-1, 3, 3), v.reshape(-1, 3), transpose, out.reshape(-1, 3))
    return out


@njit(cache=True)
def _rotate_kernel(R: np.ndarray, v: np.ndarray, transpose: bool, out: np.ndarray) -> None:
    shared = v.shape[0] == 1
    for n in range(R.shape[0]):
        m = 0 if shared else n
        for i in range(3):
            if transpose:
                out[n, i] = R[n, 0, i] * v[m, 0] + R[n, 1, i] * v[m, 1] + R[n, 2, i] * v[m, 2]
            else:
                out[n, i] = R[n, i, 0] * v[m, 0] + R[n, i, 1] * v[m, 1] + R[n, i, 2] * v[m, 2]


def paper_gains(time_step: float, alpha: float) -> tuple[float, float]:
    """``(k_p, k_v) = (2α/t², 2/t)`` of the paper's law ``u1 = −k_p (Rᵀ q̂ − q*) − k_v Rᵀ ϑ̂``."""
    t = float(time_step)
    return 2.0 * alpha / (t * t), 2.0 / t


def paper_gain_matrix(time_step: float, alpha: float) -> np.ndarray:
    """The paper's law as a world-frame gain ``K = [k_p I, k_v I]`` (its reference is
    ``[R q*, 0]`` and its feed-forward zero)."""
    k_p, k_v = paper_gains(time_step, alpha)
    return np.hstack([k_p * np.eye(3), k_v * np.eye(3)])


def paper_tracking_command(
    x_hat: np.ndarray, R_WB: np.ndarray, q_star_B: np.ndarray, k_p: float, k_v: float
) -> np.ndarray:
    """The paper's law (§III-B): ``u1 = −k_p (Rᵀ q̂ − q*) − k_v Rᵀ ϑ̂`` (body frame), for one
    run (``x_hat`` 6, ``R_WB`` 3×3, ``q_star_B`` 3 → 3) or a stack (…×6, …×3×3, …×3 → …×3).

    ``q_star_B`` is the desired relative position in the body frame: the paper's q* itself,
    or ``Rᵀ R_WF q*`` for a q* fixed in another frame (:func:`reference_rotation`).

    Substituting it into the model gives ``ϑ(k+1) = −ϑ(k) + …``: the position error contracts
    for α in (1 − 1/√2, 1 + 1/√2) (and in fact for 0 < α < 2), but the relative velocity is
    never damped and flips sign every step.
    """
    x_hat = np.ascontiguousarray(x_hat, dtype=float)
    R = np.ascontiguousarray(R_WB, dtype=float)
    q_star_B = np.ascontiguousarray(q_star_B, dtype=float)
    if x_hat.size // 6 != R.size // 9 or q_star_B.size not in (3, R.size // 3):
        raise ValueError(
            f"x_hat, R_WB, q_star_B: shapes {x_hat.shape}, {R.shape}, {q_star_B.shape} differ"
        )
    out = np.empty(R.shape[:-1])
    _paper_kernel(
        x_hat.reshape(-1, 6), R.reshape(-1, 3, 3), q_star_B.reshape(-1, 3), k_p, k_v,
        out.reshape(-1, 3),
    )  # fmt: skip
    return out


@njit(cache=True)
def _paper_kernel(
    x: np.ndarray, R: np.ndarray, q_star: np.ndarray, k_p: float, k_v: float, out: np.ndarray
) -> None:
    shared = q_star.shape[0] == 1
    for n in range(R.shape[0]):
        m = 0 if shared else n
        for i in range(3):
            position = R[n, 0, i] * x[n, 0] + R[n, 1, i] * x[n, 1] + R[n, 2, i] * x[n, 2]
            velocity = R[n, 0, i] * x[n, 3] + R[n, 1, i] * x[n, 4] + R[n, 2, i] * x[n, 5]
            out[n, i] = -k_p * (position - q_star[m, i]) - k_v * velocity


def lqr_gain(
    time_step: float, position_weight: float, velocity_weight: float, input_weight: float
) -> tuple[np.ndarray, np.ndarray]:
    """``(K, S)`` of Drake's discrete LQR on the relative double integrator.

    ``Q = diag(position_weight I₃, velocity_weight I₃)``, ``R = input_weight I₃``; ``K`` is 3×6
    with ``a = −K x`` minimising ``Σ xᵀ Q x + aᵀ R a``; ``S`` solves the DARE.
    """
    A, B = double_integrator(time_step)
    Q = np.diag([position_weight] * 3 + [velocity_weight] * 3)
    K, S = DiscreteTimeLinearQuadraticRegulator(A, B, Q, input_weight * np.eye(3))
    return K, S


def reference_feedforward(
    r0: np.ndarray, r1: np.ndarray, r2: np.ndarray, time_step: float
) -> tuple[np.ndarray, np.ndarray]:
    """``([r0; ν], a_ff)`` of the reference through ``r0, r1, r2`` (…×3 each) under one
    constant acceleration: ``ν = (−3 r0 + 4 r1 − r2)/(2t)``, ``a_ff = (r0 − 2 r1 + r2)/t²``
    (see :mod:`drake_uuv.tracking.lqr_tracking` for the derivation and its residual)."""
    t = time_step
    nu = (-3.0 * r0 + 4.0 * r1 - r2) / (2.0 * t)
    a_ff = (r0 - 2.0 * r1 + r2) / (t * t)
    return np.concatenate([r0, nu], axis=-1), a_ff


def saturate_norm(a: np.ndarray, limit: float | None) -> np.ndarray:
    """``a`` (…×3) scaled down to norm ``limit`` where longer (direction kept), each vector
    alone (a compiled loop over them); unchanged if None. A NaN vector stays NaN."""
    if limit is None:
        return a
    a = np.asarray(a, dtype=float)
    out = np.array(a)  # a copy, C-ordered
    _saturate_kernel(out.reshape(-1, a.shape[-1]), float(limit))
    return out


@njit(cache=True)
def _saturate_kernel(a: np.ndarray, limit: float) -> None:
    for n in range(a.shape[0]):
        squared = 0.0
        for i in range(a.shape[1]):
            squared += a[n, i] * a[n, i]
        norm = math.sqrt(squared)
        if norm > limit:
            scale = limit / norm
            for i in range(a.shape[1]):
                a[n, i] *= scale


#: How the cautious loop scales the law's feedback with the estimate's position covariance:
#: one factor from its trace, or one per world axis from its diagonal.
CAUTION_SCALINGS = ("trace", "axis")


def caution_scales(P: np.ndarray, position_std: float, scaling: str) -> np.ndarray:
    """The cautious loop's factors (B×3) on the world feedback, from the covariances ``P``
    (B×36 or B×6×6, world frame) and a reference σ = ``position_std`` [m].

    ``"trace"``: ``s = 1 / (1 + tr P_qq / σ²)`` on every axis; ``"axis"``:
    ``s_i = 1 / (1 + P_ii / σ²)`` along world axis i. Each is 1 for a known position and
    falls as 1/variance once the variance passes σ² (a certainty-equivalent law trusts an
    estimate whatever its spread). A negative variance (a broken covariance) counts as 0; a
    NaN one gives a NaN factor, for its run alone.
    """
    if scaling not in CAUTION_SCALINGS:
        raise ValueError(f"scaling: must be one of {', '.join(CAUTION_SCALINGS)}, got {scaling!r}")
    P = np.asarray(P, dtype=float).reshape(-1, 6, 6)
    variance = np.maximum(np.diagonal(P[:, :3, :3], axis1=1, axis2=2), 0.0)  # NaN stays NaN
    reference = float(position_std) ** 2
    if scaling == "axis":
        return 1.0 / (1.0 + variance / reference)
    # The trace summed term by term: each run's own three numbers, in one order.
    trace = variance[:, 0] + variance[:, 1] + variance[:, 2]
    return np.repeat((1.0 / (1.0 + trace / reference))[:, np.newaxis], 3, axis=1)


def speed_limited_acceleration(
    v: np.ndarray, a: np.ndarray, time_step: float, max_speed: float | None
) -> np.ndarray:
    """``a`` (…×3) limited so that ``|v + t a| ≤ max_speed`` for velocities ``v`` (…×3): where
    the next velocity would be faster, it is scaled onto the sphere (direction kept) and the
    acceleration is the one that reaches it, ``(v_max (v + t a)/|v + t a| − v) / t``. Each
    vector alone (a compiled loop); unchanged where slower, and everywhere if None. A NaN
    velocity or acceleration gives a NaN acceleration."""
    if max_speed is None:
        return a
    v = np.ascontiguousarray(v, dtype=float)
    out = np.array(a, dtype=float)  # a copy, C-ordered
    if v.shape != out.shape:
        raise ValueError(f"v, a: shapes {v.shape} and {out.shape} differ")
    _speed_kernel(v.reshape(-1, 3), out.reshape(-1, 3), float(time_step), float(max_speed))
    return out


@njit(cache=True)
def _speed_kernel(v: np.ndarray, a: np.ndarray, t: float, max_speed: float) -> None:
    for n in range(a.shape[0]):
        w0 = v[n, 0] + t * a[n, 0]
        w1 = v[n, 1] + t * a[n, 1]
        w2 = v[n, 2] + t * a[n, 2]
        norm = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
        if not norm <= max_speed:  # a NaN speed too: its acceleration is NaN
            scale = max_speed / norm
            a[n, 0] = (scale * w0 - v[n, 0]) / t
            a[n, 1] = (scale * w1 - v[n, 1]) / t
            a[n, 2] = (scale * w2 - v[n, 2]) / t


def closed_loop_eigenvalues(time_step: float, K: np.ndarray) -> np.ndarray:
    """Eigenvalues of ``A − B K`` of the relative double integrator, largest modulus first.

    Without saturation and with perfect state knowledge they govern the tracking error. The
    paper's law gives ``1 − α`` (three times) and ``−1`` (three times, the undamped velocity).
    """
    A, B = double_integrator(time_step)
    eigenvalues = np.linalg.eigvals(A - B @ K)
    return eigenvalues[np.argsort(-np.abs(eigenvalues), kind="stable")]
