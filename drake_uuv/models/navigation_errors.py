"""What navigation errors do to the ranges, the relative motion and the estimate, as numpy.

An AHRS reports roll, pitch and yaw with white noise of σ_roll, σ_pitch, σ_yaw (and a
compass's constant heading bias on yaw). With Drake's roll-pitch-yaw (``R = R_z(y) R_y(p)
R_x(r)``) a small error ``δ = [δr, δp, δy]`` is the world rotation vector ``θ = E δ`` with
``E = [R e_x, R_z(y) e_y, e_z]`` (the roll, pitch and yaw axes in the world), so the attitude
noise is ``θ ~ N(0, Σ_θ)``, ``Σ_θ = E diag(σ²) Eᵀ`` (:func:`attitude_covariance`). The
estimator believes ``R_nav = Exp(θ) R``:

- **Ranges**: it places the sonars at ``±½ q_s,nav = ±½ Exp(θ) q_s``, so its model of a range
  ``|q ± ½ q_s|`` is off by ``±½ uᵢᵀ (θ × q_s) = ±½ θ · (q_s × uᵢ)``: extra range noise
  ``J Σ_θ Jᵀ`` with rows ``±½ (q_s × uᵢ)ᵀ`` (:func:`range_attitude_jacobian`; the two
  sonars' errors are correlated). The paper's ``Y = q_sᵀ q`` is off by ``θ · (q_s × q)``
  (:func:`difference_attitude_variance`).
- **Commanded motion**: the applied world acceleration is ``R u1 = Exp(−θ) a_nav ≈ a_nav +
  a_nav × θ``, so a filter predicting with ``a_nav`` meets process noise ``[a]× Σ_θ [a]×ᵀ``
  (:func:`acceleration_attitude_covariance`): the paper's tracking law commands hundreds of
  m/s², which half a degree turns into metres per second squared.
- **A heading bias** ``b`` rotates the navigated world about z by ``b``, the vehicle's motion
  and the baseline alike: the ranges cannot see it, and the relative estimate is the truth
  rotated by ``b``. Its error ``b e_z × x`` is a floor: :func:`heading_jacobian`.
"""

from __future__ import annotations

import math

import numpy as np

from drake_uuv.models.so3 import hat

_EZ = np.array([0.0, 0.0, 1.0])


def euler_axes(R_WB: np.ndarray) -> np.ndarray:
    """``E``: the roll, pitch and yaw axes of ``R_WB`` in the world, as columns (3×3)."""
    yaw = math.atan2(R_WB[1, 0], R_WB[0, 0])
    return np.column_stack([R_WB[:, 0], [-math.sin(yaw), math.cos(yaw), 0.0], _EZ])


def attitude_covariance(R_WB: np.ndarray, sigma_rpy: np.ndarray) -> np.ndarray:
    """``Σ_θ = E diag(σ²) Eᵀ``: roll-pitch-yaw noise as a world rotation vector (3×3)."""
    E = euler_axes(R_WB)
    return (E * np.asarray(sigma_rpy, dtype=float) ** 2) @ E.T


def range_attitude_jacobian(q: np.ndarray, q_s: np.ndarray) -> np.ndarray:
    """``J = ∂[d1, d2]/∂θ`` (2×3) of the ranges ``|q ± ½ Exp(θ) q_s|`` at ``θ = 0``."""
    q = np.asarray(q, dtype=float)[:3]
    half = 0.5 * np.asarray(q_s, dtype=float)
    J = np.empty((2, 3))
    for i, sign in enumerate((1.0, -1.0)):
        r = q + sign * half
        u = r / max(float(np.linalg.norm(r)), 1e-9)
        J[i] = sign * np.cross(half, u)
    return J


def range_attitude_covariance(
    q: np.ndarray, q_s: np.ndarray, sigma_theta: np.ndarray
) -> np.ndarray:
    """``J Σ_θ Jᵀ`` (2×2): the ranges' extra noise from the baseline's attitude error."""
    J = range_attitude_jacobian(q, q_s)
    return J @ sigma_theta @ J.T


def difference_attitude_variance(q: np.ndarray, q_s: np.ndarray, sigma_theta: np.ndarray) -> float:
    """``(q_s × q)ᵀ Σ_θ (q_s × q)``: the extra variance of the paper's ``Y = q_sᵀ q``."""
    g = np.cross(np.asarray(q_s, dtype=float), np.asarray(q, dtype=float)[:3])
    return float(g @ sigma_theta @ g)


def acceleration_attitude_covariance(a_W: np.ndarray, sigma_theta: np.ndarray) -> np.ndarray:
    """``[a]× Σ_θ [a]×ᵀ`` (3×3): the error of a commanded world acceleration ``a`` that the
    attitude error turns."""
    A = hat(np.asarray(a_W, dtype=float))
    return A @ sigma_theta @ A.T


def heading_jacobian(x: np.ndarray) -> np.ndarray:
    """``∂(R_z(b) x)/∂b`` at ``b = 0`` for a relative state ``[q, ϑ]``: ``[e_z × q, e_z × ϑ]``."""
    x = np.asarray(x, dtype=float)
    return np.concatenate([np.cross(_EZ, x[:3]), np.cross(_EZ, x[3:])])
