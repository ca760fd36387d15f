"""Ranges at their own ping times: the schedule, and the exact Gaussian step between ticks.

Schedule. Sonar i pings at ``t_k + τ_i`` in step k (``0 ≤ τ_i < t``) and its range reaches the
estimator ``L`` later, at tick ``k + d_i`` with ``d_i = ⌈(τ_i + L)/t⌉`` (:class:`PingSchedule`).
``d_i = 0`` only when ``τ_i = L = 0``: the paper's timing. An estimate published at tick j is
of the state at ``t_j`` from every range that has arrived by then: the ranges of the last
``D = max d_i`` steps are partly still in flight, so an estimator keeps its belief at
``t_{j−D}`` (an *anchor*: all ranges of earlier steps taken) and steps it through the last D
steps with the ranges that have arrived, every tick.

The step. The paper's model holds each step's accelerations constant: the vehicle's commanded
``a_k = R u1`` and the target's ``ū_k ~ N(0, W)``. The relative state at ``t_k + τ`` is then
exactly ``x(τ) = Φ(τ) x_k + B(τ)(a_k − ū_k)``, a linear function ``G(τ) z + B(τ) a_k`` of the
step's augmented state ``z = [x_k, ū_k]`` (prior ``N([x̂_k, 0], blkdiag(P_k, W))``) with
``G(τ) = [Φ(τ), −B(τ)]``. A range at τ informs ``z`` through ``y = x(τ)``: any Gaussian update
of ``y`` (EKF, UKF, the paper's KF, …) carries over to ``z`` by conditioning,
``m_z ← m_z + K (m_y⁺ − m_y)``, ``P_z ← P_z − K (P_y − P_y⁺) Kᵀ``, ``K = P_z Gᵀ P_y⁻¹``
(computed as ``(I − K G) P_z (I − K G)ᵀ + K P_y⁺ Kᵀ``, the same matrix, which stays positive
semi-definite under rounding)
(:func:`update_through`), exact for a linear measurement and the same as the update of z
itself for a linearised one. The step ends with ``x_{k+1} = G(t) z + B(t) a_k``. Treating
the sub-intervals as independent (``Q(τ₂ − τ₁)`` between two pings of one step) would
forget that both pings see the same ``ū_k``.

The paper's KF needs both ranges of a step at one instant (its ``Y = ½(d1² − d2²)``). With
the pings at ``τ₁ ≠ τ₂`` it carries the earlier range to the later ping time by the change
its own estimate predicts, ``h₁(x̂(τ₂)) − h₁(x̂(τ₁))``, and adds that prediction's variance
``g P_z gᵀ`` to the range's noise (:func:`carried_range`).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from drake_uuv.models.measurement import MIN_RANGE, range_jacobian, range_measurement

_TOLERANCE = 1e-9


@dataclass(frozen=True)
class PingSchedule:
    """When each sonar pings within a step and when its range arrives (see the module notes)."""

    time_step: float
    offsets: tuple[float, float] = (0.0, 0.0)
    latency: float = 0.0

    def __post_init__(self) -> None:
        t = self.time_step
        if not (math.isfinite(t) and t > 0.0):
            raise ValueError(f"time_step: must be > 0, got {t!r}")
        offsets = tuple(float(o) for o in self.offsets)
        if len(offsets) != 2 or not all(0.0 <= o < t for o in offsets):
            raise ValueError(
                f"ping_offsets: must be two numbers in [0, {t:g}), got {self.offsets!r}"
            )
        if not (math.isfinite(self.latency) and 0.0 <= self.latency <= 10.0 * t):
            raise ValueError(f"latency: must be in [0, {10.0 * t:g}], got {self.latency!r}")
        object.__setattr__(self, "offsets", offsets)

    @property
    def delays(self) -> tuple[int, int]:
        """``d_i``: ticks from a ping's step to its arrival, per sonar."""
        return tuple(
            max(0, math.ceil((tau + self.latency) / self.time_step - _TOLERANCE))
            for tau in self.offsets
        )  # type: ignore[return-value]

    @property
    def window(self) -> int:
        """``D = max d_i``: how many past steps may still hold ranges in flight."""
        return max(self.delays)

    @property
    def immediate(self) -> bool:
        """The paper's timing: both sonars at the tick, their ranges at once."""
        return self.window == 0

    def ping_time(self, step: int, sonar: int) -> float:
        """``t_k + τ_i`` of sonar ``sonar``'s ping in step ``step``."""
        return step * self.time_step + self.offsets[sonar]


def sub_step(tau: float) -> tuple[np.ndarray, np.ndarray]:
    """``(Φ(τ), B(τ))`` of the double integrator over ``τ ≥ 0`` (``(I, 0)`` at τ = 0)."""
    Phi = np.eye(6)
    Phi[:3, 3:] = tau * np.eye(3)
    B = np.vstack([0.5 * tau * tau * np.eye(3), tau * np.eye(3)])
    return Phi, B


def augment(x: np.ndarray, P: np.ndarray, W: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The step's augmented prior ``z = [x_k, ū_k] ~ N([x, 0], blkdiag(P, W))`` (9)."""
    z = np.concatenate([x, np.zeros(3)])
    P_z = np.zeros((9, 9))
    P_z[:6, :6] = P
    P_z[6:, 6:] = W
    return z, P_z


@functools.lru_cache(maxsize=64)
def transition(tau: float) -> tuple[np.ndarray, np.ndarray]:
    """``(G(τ), B(τ))``: ``x(τ) = G(τ) z + B(τ) a`` with ``G = [Φ(τ), −B(τ)]`` (6×9).

    Formed once per ``τ`` and shared, read-only: a step's few ping times repeat every step,
    and the late-range particle window asked for them tens of thousands of times a study."""
    Phi, B = sub_step(tau)
    G = np.hstack([Phi, -B])
    G.flags.writeable = B.flags.writeable = False
    return G, B


def update_through(
    z: np.ndarray,
    P_z: np.ndarray,
    G: np.ndarray,
    y_prior: np.ndarray,
    y_posterior: np.ndarray,
    P_y_posterior: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Conditions ``z`` on an update of ``y = G z + c`` (see the module notes).

    ``y_prior`` is ``G z + c`` (its covariance ``G P_z Gᵀ`` is recomputed here);
    ``y_posterior``, ``P_y_posterior`` the update's result. Returns ``(z⁺, P_z⁺)``, symmetric.
    """
    P_zy = P_z @ G.T
    P_y = G @ P_zy
    K = np.linalg.solve(P_y, P_zy.T).T  # P_z Gᵀ P_y⁻¹ (P_y symmetric)
    z_post = z + K @ (y_posterior - y_prior)
    # P_z − K P_y Kᵀ (z's covariance given y) as (I − K G) P_z (I − K G)ᵀ: the same matrix,
    # positive semi-definite under rounding; then K P_y⁺ Kᵀ of the updated y.
    I_KG = np.eye(len(z)) - K @ G
    P_post = I_KG @ P_z @ I_KG.T + K @ P_y_posterior @ K.T
    return z_post, 0.5 * (P_post + P_post.T)


def carried_range(
    z: np.ndarray,
    P_z: np.ndarray,
    sonar: int,
    early: tuple[np.ndarray, np.ndarray, np.ndarray],
    late: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> tuple[float, float]:
    """The change the estimate predicts in sonar ``sonar``'s range between two ping times, and
    the variance of that prediction: ``(Δ, g P_z gᵀ)``.

    ``early`` and ``late`` are ``(G, c, q_s)`` of each time: the state there is ``G z + c``
    (relative) and ``q_s`` the world baseline. ``Δ = hᵢ(y_late) − hᵢ(y_early)`` at the mean,
    ``g = ∂Δ/∂z = Hᵢ(y_late) G_late − Hᵢ(y_early) G_early``.
    """
    rows = []
    values = []
    for G, c, q_s in (early, late):
        y = G @ z + c
        values.append(range_measurement(y, q_s)[sonar])
        rows.append(range_jacobian(y, q_s)[sonar] @ G)
    g = rows[1] - rows[0]
    return float(values[1] - values[0]), float(g @ P_z @ g)


# ---------------------------------------------------------------------- a batch of runs


def transition_runs(tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`transition` of each run's ``τ`` (B): ``G`` (B, 6, 9), ``B(τ)`` (B, 6, 3)."""
    tau = np.asarray(tau, dtype=float)
    n = len(tau)
    eye = np.eye(3)
    B = np.zeros((n, 6, 3))
    B[:, :3] = (0.5 * tau * tau)[:, np.newaxis, np.newaxis] * eye
    B[:, 3:] = tau[:, np.newaxis, np.newaxis] * eye
    G = np.zeros((n, 6, 9))
    G[:, :, :6] = np.eye(6)
    G[:, :3, 3:6] = tau[:, np.newaxis, np.newaxis] * eye
    G[:, :, 6:] = -B
    return G, B


def carried_range_runs(
    z: np.ndarray,
    P_z: np.ndarray,
    sonar: np.ndarray,
    early: tuple[np.ndarray, np.ndarray, np.ndarray],
    late: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`carried_range` of each run: ``z`` (B, 9), ``P_z`` (B, 9, 9), ``sonar`` (B) the
    sonar carried, ``early``/``late`` ``(G (B, 6, 9), c (B, 6), q_s (B, 3))``; returns the
    changes and their variances (B each)."""
    sign = np.where(sonar == 0, 0.5, -0.5)[:, np.newaxis]
    values, rows = [], []
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        for G, c, q_s in (early, late):
            y = (G @ z[:, :, np.newaxis])[:, :, 0] + c
            v = y[:, :3] + sign * q_s
            d = np.sqrt((v * v).sum(axis=1))
            u = v / np.maximum(d, MIN_RANGE)[:, np.newaxis]
            values.append(d)
            rows.append((u[:, np.newaxis, :] @ G[:, :3, :])[:, 0, :])
        g = rows[1] - rows[0]
        variance = (g[:, np.newaxis, :] @ P_z @ g[:, :, np.newaxis])[:, 0, 0]
    return values[1] - values[0], variance
