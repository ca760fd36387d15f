"""The dual-sonar measurement model of the relative state, as pure numpy (no Drake).

Conventions, fixed for every estimator in this package:

* Relative state ``x = [q, ϑ] ∈ R⁶``, ``q = p_uuv − p_target`` and ``ϑ = v_uuv − v_target``,
  both in the world frame.
* The motion model is :mod:`drake_uuv.models.motion`.
* World sonar baseline ``q_s = R b``; sonar s1 sits at ``p_uuv + ½ q_s``, s2 at
  ``p_uuv − ½ q_s``. True ranges ``d1 = |q + ½ q_s|``, ``d2 = |q − ½ q_s|``.
* Each sonar returns ``f`` samples ``d_i^j = d_i + v_i^j``, ``v ~ N(0, η_i)`` (``η`` is a
  variance). The per-sonar sample mean is sufficient, with variance ``η_i / f``.
* The paper's linear measurement ``Y = ½(d1² − d2²) = q_sᵀ q + v̄``, ``C = [q_sᵀ, 0]``.
"""

from __future__ import annotations

import numpy as np

#: Ranges below this are clamped when a unit vector is formed (a sonar on the target).
MIN_RANGE = 1e-9

# A step's measurement status: per sonar, whether its return arrived (the sonar's
# ``sonar_status``), and for the whole update (the estimator's ``measurement_status``),
# which adds GATED: rejected by the NIS gate.
# NO_ARRIVAL: no range of a sonar reached the estimator at this tick (its pings are late).
VALID, DROPPED, OUT_OF_BEAM, OUT_OF_RANGE, GATED, NO_ARRIVAL = 0, 1, 2, 3, 4, 5
STATUS_NAMES = {VALID: "valid", DROPPED: "dropped", OUT_OF_BEAM: "out of beam",
                OUT_OF_RANGE: "out of range", GATED: "gated",
                NO_ARRIVAL: "no arrival"}  # fmt: skip


def range_measurement(x: np.ndarray, q_s: np.ndarray) -> np.ndarray:
    """Return the true ranges ``[d1, d2] = [|q + ½ q_s|, |q − ½ q_s|]`` (shape ``(2,)``).

    ``x`` is the relative state (6,) (only ``q = x[:3]`` is used), ``q_s`` the world baseline (3,).
    """
    q = np.asarray(x, dtype=float)[:3]
    half = 0.5 * np.asarray(q_s, dtype=float).reshape(3)
    return np.array([np.linalg.norm(q + half), np.linalg.norm(q - half)])


def batch_ranges(q: np.ndarray, q_s: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """The ranges ``[|q + ½ q_s|, |q − ½ q_s|]`` of many relative positions at once.

    ``q`` is 3×N (one position per column, e.g. particles or sigma points); returns 2×N (in
    ``out`` when given). From ``|q ± ½ q_s|² = |q|² ± q_sᵀ q + ¼|q_s|²``: one squared norm and
    one projection for both sonars.
    """
    q_s = np.asarray(q_s, dtype=float).reshape(3)
    squared = np.einsum("ij,ij->j", q, q)
    squared += 0.25 * float(q_s @ q_s)
    projection = q_s @ q
    if out is None:
        out = np.empty((2, squared.size))
    np.add(squared, projection, out=out[0])
    np.subtract(squared, projection, out=out[1])
    return np.sqrt(np.maximum(out, 0.0, out=out), out=out)


def range_jacobian(x: np.ndarray, q_s: np.ndarray) -> np.ndarray:
    """Return ``H = ∂[d1, d2]/∂x`` (shape ``(2, 6)``).

    Row i is ``[u_iᵀ, 0₁ₓ₃]`` with ``u_i`` the unit vector from sonar i to the target's
    negated position, i.e. ``u1 = (q + ½ q_s)/d1`` and ``u2 = (q − ½ q_s)/d2``; the ranges do
    not depend on the relative velocity. A range below :data:`MIN_RANGE` is clamped (the
    direction is then meaningless, but the result stays finite).
    """
    q = np.asarray(x, dtype=float)[:3]
    half = 0.5 * np.asarray(q_s, dtype=float).reshape(3)
    r1 = q + half
    r2 = q - half
    H = np.zeros((2, 6))
    H[0, :3] = r1 / max(float(np.linalg.norm(r1)), MIN_RANGE)
    H[1, :3] = r2 / max(float(np.linalg.norm(r2)), MIN_RANGE)
    return H


def range_difference_noise(
    noise_model: str, noise_variances: np.ndarray, mean_squared_ranges: np.ndarray
) -> tuple[float, float]:
    """Mean ``m`` and variance ``Γ`` of the noise of ``Y = ½(d1² − d2²)``.

    ``mean_squared_ranges`` holds ``mean_f(d_i²)`` per sonar.

    - ``derived`` (the exact moments of the paper's ``Y``): ``v̄ = d̄1 v1 − d̄2 v2 + ½(v1² − v2²)``, so
      ``m = ½(η1 − η2)`` and ``Γ = η1 d̄1² + η2 d̄2² + ½(η1² + η2²)`` with
      ``d̄i² ≈ max(mean_f(di²) − ηi, 0)``.
    - ``paper_printed``: the paper's ``m = η1 + η2`` and
      ``Γ = 2η1² + 2η2² + 4(mean(d1²) − η1)η1 + 4(mean(d2²) − η2)η2``, kept to measure the
      difference; it is not consistent with the paper's own ``Y``.
    """
    eta1, eta2 = noise_variances
    if noise_model == "derived":
        true_squared = np.maximum(mean_squared_ranges - noise_variances, 0.0)
        m = 0.5 * (eta1 - eta2)
        gamma = eta1 * true_squared[0] + eta2 * true_squared[1] + 0.5 * (eta1**2 + eta2**2)
        return m, gamma
    if noise_model == "paper_printed":
        m = eta1 + eta2
        gamma = (
            2 * eta1**2
            + 2 * eta2**2
            + 4 * (mean_squared_ranges[0] - eta1) * eta1
            + 4 * (mean_squared_ranges[1] - eta2) * eta2
        )
        return m, gamma
    raise ValueError(
        f"estimator.noise_model: must be derived or paper_printed, got {noise_model!r}"
    )


def _clip_at_zero(x: float) -> float:
    """``max(x, 0)`` for a float, NaN staying NaN."""
    return x if x > 0.0 or x != x else 0.0


def paper_measurement(
    samples: np.ndarray, noise_variances: np.ndarray, noise_model: str = "derived"
) -> tuple[float, float, float]:
    """The paper's ``(Y, m, Γ)`` from one step's range samples (2×f, sonar 1's row first).

    ``Y = ½(d1² − d2²)`` of each sonar's *first* sample; ``m`` and ``Γ`` from
    :func:`range_difference_noise` with ``mean_f(dᵢ²)`` over all ``f`` samples. NaN samples (no
    return) give NaN. With one sample and the derived model the arithmetic runs on Python
    floats (the same operations, without a dozen numpy calls).
    """
    eta = np.asarray(noise_variances, dtype=float)
    if samples.shape[1] == 1 and noise_model == "derived":
        d1, d2 = samples.ravel().tolist()
        eta1, eta2 = float(eta[0]), float(eta[1])
        gamma = (
            eta1 * _clip_at_zero(d1 * d1 - eta1)
            + eta2 * _clip_at_zero(d2 * d2 - eta2)
            + float(0.5 * (eta[0] ** 2 + eta[1] ** 2))
        )
        return 0.5 * (d1 * d1 - d2 * d2), float(0.5 * (eta[0] - eta[1])), gamma
    d1, d2 = samples[:, 0]
    mean_squares = (samples * samples).sum(axis=1) / samples.shape[1]
    m, gamma = range_difference_noise(noise_model, eta, mean_squares)
    return 0.5 * (d1 * d1 - d2 * d2), m, gamma
