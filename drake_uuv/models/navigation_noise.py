"""What navigation errors and the sound speed do to the relative state's bound.

Pure numpy, for the extended PCRLB (:mod:`drake_uuv.models.pcrlb_timed`). The navigation
model is the ``!InertialNavigation`` one: roll-pitch-yaw of the truth (Drake's
``RollPitchYaw``, ``R = Rz(yaw) Ry(pitch) Rx(roll)``) plus white noise ``n ~ N(0,
diag(σ²))`` each step and a per-run heading bias ``b_ψ ~ N(0, σ_ψ²)``; the DVL's body-frame
velocity with white noise ``σ_v`` and a per-run bias ``σ_b`` per axis.

Noise, which the bound's recursion takes in
-------------------------------------------
* Attitude noise as range noise. To first order ``R(rpy + n) = Exp(θ) R(rpy)`` with the world
  rotation vector ``θ = E n`` (:func:`euler_rate_jacobian`), so ``Σ_θ = E diag(σ²) Eᵀ``
  (:func:`rotation_vector_covariance`). The vehicle's baseline is then ``Exp(θ) q_s``; the
  ranges it predicts, ``|q ± ½ Exp(θ) q_s|``, differ from the true ones by ``J θ``
  (:func:`range_attitude_jacobian`, both sonars: the one ``θ`` of a step makes the two range
  errors correlated), an extra range-noise covariance ``J Σ_θ Jᵀ``. Linear in ``θ``: exact
  for the Gaussian ``θ`` only to first order (errors of degrees: a relative error ≈ θ²).
* Attitude noise in the commanded acceleration. The vehicle believes it applies
  ``R_nav u1 = Exp(θ) R u1``; its true world acceleration ``R u1`` is the believed ``a``
  less ``θ × a``, an unknown acceleration like the target's: ``W`` gains ``[a]× Σ_θ [a]×ᵀ``
  for that step (:func:`commanded_acceleration_noise`). The ``θ`` of a step's ranges and of
  its acceleration are the same draw; the bound treats the two as independent.

Error floors of the biases: what no estimator can see
-----------------------------------------------------
* Heading bias (:func:`heading_bias_floor`). Yaw is Drake's outermost rotation, so
  ``R(rpy + [0, 0, b_ψ]) = Rz(b_ψ) R`` exactly: the vehicle's whole world is turned about z.
  Everything it takes in is turned alike (its baseline ``Rz q_s``, its commanded acceleration
  ``Rz a``, its navigated velocity ``Rz v``), and ranges are invariant under a common
  rotation, ``|Rz q ± ½ Rz q_s| = |q ± ½ q_s|``: the data are exactly those of the turned
  relative state ``x' = blkdiag(Rz, Rz) x`` (driven by ``Rz ū``, of covariance ``Rz W Rzᵀ``:
  ``W`` itself when it is isotropic in x-y, near it otherwise). The estimate can then at best
  find ``x'``; its error is ``(x̂ − x') + (x' − x)``. The first is bounded by the PCRLB (the
  same information, turned); the second is ``(Rz(b_ψ) − I) x = b_ψ g + O(b_ψ²)`` with
  ``g = [e_z × q, e_z × ϑ]``. The data carry nothing about ``b_ψ`` (``E[b_ψ | data] = 0``),
  so the cross term vanishes to first order and the mean-square error gains
  ``E[b_ψ²] g gᵀ = σ_ψ² g gᵀ``: trace ``σ_ψ² |q_xy|²`` in position and ``σ_ψ² |ϑ_xy|²`` in
  velocity (``|e_z × q|² = q_x² + q_y²``). The prior ``P(0|−1)`` is in the true frame and
  so does inform ``b_ψ``, by ``|q_xy|²/P0`` rad⁻² (5 rad⁻² for the paper's start and
  ``P0 = I``, a σ of 25°): nothing beside degrees of compass bias.
* Sound speed (:func:`sound_speed_floor`). Every range is measured as ``(1 + ε) d_i``. To
  first order the ranges of ``q + δ`` are ``d_i + u_iᵀ δ``, and ``δ = ε q`` gives
  ``u_iᵀ ε q = ε d_i ∓ ½ ε u_iᵀ q_s`` (from ``u_iᵀ (q ± ½ q_s) = d_i``): the scaled ranges
  are those of ``(1 + ε) q`` up to a fraction ``|q_s| / (2 d_i)`` of the bias, along the
  baseline. Ranges fix the scale of ``q`` only through themselves, so an estimator that
  does not know ``ε`` settles at ``(1 + ε) q``: a position error ``ε q`` whose second moment
  is ``ε² q qᵀ`` (ε is a given number, not drawn: a squared bias), trace ``ε² |q|²``. This
  is the leading term in ``|q_s| / |q|``: a two-range fix across the line of sight
  (``q_s ⊥ q``) is off by ``ε (1 + |q_s|²/(4|q|²)) q``, 1.13 times this floor in square at
  the paper's ``|q| = 2√2``, ``|q_s| = √2`` m. It is a floor only as far as the dynamics
  cannot tell ``(1 + ε) q`` from ``q``: that trajectory would need the vehicle's known
  acceleration ``a`` scaled too, a mismatch ``ε a`` per step which the recursion would see
  against ``√W`` when ``ε |a|`` is not small beside it (the paper's vehicle commands
  hundreds of m/s²). The same argument would scale the velocity by ``ε ϑ``; this floor
  counts the position only.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from drake_uuv.models.measurement import MIN_RANGE
from drake_uuv.models.so3 import cross_runs


@dataclass(frozen=True)
class NavigationErrors:
    """The navigation's error figures, in SI units, for a model of them (an estimator's error
    model, the extended bound): σ of the white attitude noise (roll, pitch, yaw) [rad], σ of
    the per-run heading bias [rad], σ of the white DVL noise and of the per-run DVL bias per
    body axis [m/s]."""

    attitude_noise: np.ndarray = field(default_factory=lambda: np.zeros(3))
    heading_bias: float = 0.0
    velocity_noise: float = 0.0
    velocity_bias: float = 0.0

    @property
    def any(self) -> bool:
        """Whether any figure is non-zero."""
        return bool(
            np.any(self.attitude_noise > 0.0)
            or self.heading_bias > 0.0
            or self.velocity_noise > 0.0
            or self.velocity_bias > 0.0
        )


def euler_rate_jacobian(R: np.ndarray) -> np.ndarray:
    """``E`` (…×3×3) with ``R(rpy + δ) = Exp(E δ) R(rpy) + O(δ²)`` for Drake's roll-pitch-yaw.

    ``R = Rz(y) Ry(p) Rx(r)`` (…×3×3), so the world rotation of small angle increments is
    ``E = [Rz Ry e_x, Rz e_y, e_z]``, whose first column is ``R e_x`` (``Rx e_x = e_x``). Away
    from pitch ±90° (where roll and yaw turn about one axis and ``E`` is singular).
    """
    R = np.asarray(R, dtype=float)
    E = np.zeros(R.shape)
    E[..., :, 0] = R[..., :, 0]
    yaw = np.arctan2(R[..., 1, 0], R[..., 0, 0])
    E[..., 0, 1] = -np.sin(yaw)
    E[..., 1, 1] = np.cos(yaw)
    E[..., 2, 2] = 1.0
    return E


def rotation_vector_covariance(R: np.ndarray, attitude_noise: np.ndarray) -> np.ndarray:
    """``Σ_θ = E diag(σ²) Eᵀ`` (…×3×3): the world rotation-vector covariance of roll-pitch-yaw
    noise of σ ``attitude_noise`` (3,) [rad] at the attitudes ``R`` (…×3×3)."""
    E = euler_rate_jacobian(R)
    variances = np.asarray(attitude_noise, dtype=float).reshape(3) ** 2
    return (E * variances) @ np.swapaxes(E, -1, -2)


def range_attitude_jacobian(p_TS: np.ndarray, q_s: np.ndarray) -> np.ndarray:
    """``J = ∂[d1, d2]/∂θ`` (…×2×3) for the baseline turned ``q_s → Exp(θ) q_s``, at θ = 0.

    ``p_TS`` (…×2×3) are the sonars relative to the target, ``q ± ½ q_s`` (sonar 1 at ``+``);
    ``q_s`` (…×3, or …×2×3 for each sonar's baseline at its own ping) the world baseline.
    ``∂(Exp(θ) q_s)/∂θ = −[q_s]×``, so row i is ``±½ u_iᵀ (−[q_s]×) = ±½ (q_s × u_i)ᵀ`` with
    ``u_i`` the unit line of sight.
    """
    p_TS = np.asarray(p_TS, dtype=float)
    u = p_TS / np.maximum(np.linalg.norm(p_TS, axis=-1, keepdims=True), MIN_RANGE)
    q_s = np.asarray(q_s, dtype=float)
    if q_s.ndim < p_TS.ndim:
        q_s = q_s[..., np.newaxis, :]
    return np.array([0.5, -0.5])[:, np.newaxis] * cross_runs(q_s, u)


def commanded_acceleration_noise(acceleration: np.ndarray, Sigma: np.ndarray) -> np.ndarray:
    """``[a]× Σ_θ [a]×ᵀ`` (…×3×3): the covariance of ``θ × a`` for ``θ ~ N(0, Σ_θ)``, the
    error of a commanded world acceleration ``a`` (…×3) turned by the attitude's error."""
    a = np.asarray(acceleration, dtype=float)
    skew = np.zeros(a.shape + (3,))
    skew[..., 0, 1], skew[..., 0, 2], skew[..., 1, 2] = -a[..., 2], a[..., 1], -a[..., 0]
    skew -= np.swapaxes(skew, -1, -2)
    return skew @ Sigma @ np.swapaxes(skew, -1, -2)


def navigated_velocity_covariance(
    velocity: np.ndarray, Sigma: np.ndarray | None, velocity_noise: float, velocity_bias: float
) -> np.ndarray:
    """``Σ_ev = (σ_v² + σ_b²) I + [v]× Σ_θ [v]×ᵀ`` (…×3×3): the error of a navigated velocity
    ``R_WB_nav v_B`` at the world velocity ``v`` (…×3), from the DVL's white noise σ_v and bias
    σ_b per axis and the attitude noise ``Σ_θ`` turning it (``θ × v``, the same cross product
    as :func:`commanded_acceleration_noise`; none when ``Sigma`` is None)."""
    covariance = (velocity_noise**2 + velocity_bias**2) * np.eye(3)
    if Sigma is None:
        return covariance
    return covariance + commanded_acceleration_noise(velocity, Sigma)


def heading_bias_floor(q: np.ndarray, velocity: np.ndarray, heading_bias: float) -> np.ndarray:
    """``σ_ψ² g gᵀ`` (N×6×6), ``g = [e_z × q, e_z × ϑ]``: the error a heading bias of σ
    ``heading_bias`` [rad] leaves at the true relative positions ``q`` and velocities ``ϑ``
    (N×3 each); trace ``σ_ψ² (|q_xy|² + |ϑ_xy|²)`` (see the module docstring)."""
    x = np.concatenate([np.asarray(q, dtype=float), np.asarray(velocity, dtype=float)], axis=1)
    g = np.stack([-x[:, 1], x[:, 0], np.zeros(len(x)), -x[:, 4], x[:, 3], np.zeros(len(x))], 1)
    return heading_bias**2 * g[:, :, None] * g[:, None, :]


def sound_speed_floor(q: np.ndarray, epsilon: float) -> np.ndarray:
    """``ε² q qᵀ`` in the position block (N×6×6): the error of ranges scaled by ``1 + ε`` at
    the true relative positions ``q`` (N×3); trace ``ε² |q|²`` (see the module docstring)."""
    q = np.asarray(q, dtype=float)
    floor = np.zeros((len(q), 6, 6))
    floor[:, :3, :3] = epsilon**2 * q[:, :, None] * q[:, None, :]
    return floor


def range_attitude_covariance(q: np.ndarray, q_s: np.ndarray, Sigma: np.ndarray) -> np.ndarray:
    """``J Σ_θ Jᵀ`` (…×2×2): the extra noise of the two ranges ``|q ± ½ q_s|`` that a filter
    predicts with a baseline turned by the attitude error (:func:`range_attitude_jacobian`);
    ``q`` (…×3, or a relative state …×6), ``q_s`` (…×3), ``Sigma`` (…×3×3)."""
    q = np.asarray(q, dtype=float)[..., :3]
    half = 0.5 * np.asarray(q_s, dtype=float)
    J = range_attitude_jacobian(np.stack([q + half, q - half], axis=-2), q_s)
    return J @ Sigma @ np.swapaxes(J, -1, -2)


def difference_attitude_variance(
    q: np.ndarray, q_s: np.ndarray, Sigma: np.ndarray
) -> float | np.ndarray:
    """``(q_s × q)ᵀ Σ_θ (q_s × q)``: the extra variance of the paper's ``Y = q_sᵀ q`` that a
    filter predicts with the turned baseline ``Exp(θ) q_s`` (``(θ × q_s)ᵀ q = θ · (q_s × q)``);
    over leading axes of ``q`` (…×3 or …×6), ``q_s`` (…×3), ``Sigma`` (…×3×3)."""
    g = cross_runs(q_s, np.asarray(q, dtype=float)[..., :3])
    value = (g[..., np.newaxis, :] @ Sigma @ g[..., :, np.newaxis])[..., 0, 0]
    return float(value) if np.ndim(value) == 0 else value
