"""The paper's attitude plans and the attitude command, as plain numpy.

* :func:`zeta` and :func:`trajectory_attitude`: Algorithm 2's desired baseline direction
  ``ζ(k)`` and the attitude ``R̄(k)`` that takes the body baseline ``b`` along it.
* :func:`attitude_command`: ``u2 = Log(R̄ Rᵀ)/t`` (so that ``R(k+1) = Exp(u2 t) R(k) = R̄``),
  scaled down to a rate limit if one is set.
"""

import math

import numpy as np

from drake_uuv.models.so3 import log_so3, minimal_rotation, norm


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


def attitude_command(
    R_desired: np.ndarray, R_WB: np.ndarray, time_step: float, max_rate: float | None
) -> np.ndarray:
    """``u2 = Log(R̄ Rᵀ) / t`` [rad/s, world frame], scaled down to norm ``max_rate`` if set.

    Scaled, the attitude moves towards ``R̄`` along the same geodesic without reaching it.
    """
    rate = log_so3(R_desired @ R_WB.T) / time_step
    if max_rate is not None:
        rate_norm = norm(rate)
        if rate_norm > max_rate:
            rate *= max_rate / rate_norm
    return rate
