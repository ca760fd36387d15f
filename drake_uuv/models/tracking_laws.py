"""Tracking laws on the relative double integrator, as plain numpy (the gains, the paper's
law, the LQR gain and the reference feed-forward).

Every law here acts on the filtered relative state ``x̂ = [q̂, ϑ̂]`` (world frame) and
produces a world acceleration ``a = R u1``; written as ``a = a_ff − K (x̂ − x_ref)`` its gain
``K`` (3×6) fixes the closed-loop eigenvalues of ``A − B K``
(:func:`closed_loop_eigenvalues`).
"""

import math

import numpy as np
from pydrake.systems.controllers import DiscreteTimeLinearQuadraticRegulator

from drake_uuv.models.motion import double_integrator

#: Frames the desired relative position q* may be fixed in: the body (the paper's), the
#: world, or the body's heading (yaw only).
REFERENCE_FRAMES = ("body", "world", "heading")


def heading_rotation(R_WB: np.ndarray) -> np.ndarray:
    """``R_z(ψ)``, the rotation about world z by the body's heading ψ (the yaw of its x axis).

    ψ = atan2(R₁₀, R₀₀), the Z-Y-X yaw; when the body's x axis is vertical (no heading), the
    heading of its y axis stands in: ψ = atan2(−R₀₁, R₁₁).
    """
    R = np.asarray(R_WB, dtype=float).reshape(3, 3)
    c, s = R[0, 0], R[1, 0]
    if math.hypot(c, s) < 1e-9:
        c, s = R[1, 1], -R[0, 1]
    h = math.hypot(c, s)
    c, s = c / h, s / h
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def reference_rotation(R_WB: np.ndarray, frame: str) -> np.ndarray:
    """``R_WF``: the rotation from the frame F that q* is fixed in to the world, at attitude
    ``R_WB``; the desired relative position is then ``r = R_WF q*`` (world frame)."""
    if frame == "body":
        return np.asarray(R_WB, dtype=float).reshape(3, 3)
    if frame == "world":
        return np.eye(3)
    if frame == "heading":
        return heading_rotation(R_WB)
    raise ValueError(
        f"reference_frame: must be one of {', '.join(REFERENCE_FRAMES)}, got {frame!r}"
    )


def desired_relative_positions(R_WB: np.ndarray, q_star: np.ndarray, frame: str) -> np.ndarray:
    """``r(k) = R_WF(k) q*`` for a stack of attitudes ``R_WB`` (N×3×3): N×3, world frame."""
    R_WB = np.asarray(R_WB, dtype=float).reshape(-1, 3, 3)
    q_star = np.asarray(q_star, dtype=float)
    if frame == "body":
        return R_WB @ q_star
    return np.stack([reference_rotation(R, frame) @ q_star for R in R_WB])


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
    """The paper's law (§III-B): ``u1 = −k_p (Rᵀ q̂ − q*) − k_v Rᵀ ϑ̂`` (body frame).

    ``q_star_B`` is the desired relative position in the body frame: the paper's q* itself,
    or ``Rᵀ R_WF q*`` for a q* fixed in another frame (:func:`reference_rotation`).

    Substituting it into the model gives ``ϑ(k+1) = −ϑ(k) + …``: the position error contracts
    for α in (1 − 1/√2, 1 + 1/√2) (and in fact for 0 < α < 2), but the relative velocity is
    never damped and flips sign every step.
    """
    R_BW = R_WB.T
    # The products stay numpy (BLAS); the element-wise rest, in the same order, on floats.
    position = (R_BW @ x_hat[:3]).tolist()
    velocity = (R_BW @ x_hat[3:]).tolist()
    r = q_star_B.tolist()
    return np.array([-k_p * (position[i] - r[i]) - k_v * velocity[i] for i in range(3)])


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
    """``([r0; ν], a_ff)`` of the reference through ``r0, r1, r2`` under one constant
    acceleration: ``ν = (−3 r0 + 4 r1 − r2)/(2t)``, ``a_ff = (r0 − 2 r1 + r2)/t²`` (see
    :mod:`drake_uuv.tracking.lqr_tracking` for the derivation and its residual)."""
    t = time_step
    nu = (-3.0 * r0 + 4.0 * r1 - r2) / (2.0 * t)
    a_ff = (r0 - 2.0 * r1 + r2) / (t * t)
    return np.concatenate([r0, nu]), a_ff


def saturate_norm(a: np.ndarray, limit: float | None) -> np.ndarray:
    """``a`` scaled down to norm ``limit`` if longer (direction kept); unchanged if None."""
    if limit is None:
        return a
    a_norm = float(np.sqrt(a @ a))
    return a * (limit / a_norm) if a_norm > limit else a


def closed_loop_eigenvalues(time_step: float, K: np.ndarray) -> np.ndarray:
    """Eigenvalues of ``A − B K`` of the relative double integrator, largest modulus first.

    Without saturation and with perfect state knowledge they govern the tracking error. The
    paper's law gives ``1 − α`` (three times) and ``−1`` (three times, the undamped velocity).
    """
    A, B = double_integrator(time_step)
    eigenvalues = np.linalg.eigvals(A - B @ K)
    return eigenvalues[np.argsort(-np.abs(eigenvalues), kind="stable")]
