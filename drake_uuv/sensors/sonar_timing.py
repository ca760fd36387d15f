"""When each sonar pings, when its range arrives, and what a ping saw: the sonar's timing.

Sonar i pings at ``t_k + τ_i`` in step k (``sonar.ping_offsets``) and its range reaches the
estimator ``L`` later (``sonar.latency``): at the first tick at or after ``t_k + τ_i + L``,
``k + d_i`` with ``d_i = ⌈(τ_i + L)/t⌉`` (:func:`arrival_delays`). ``d_i = 0`` only when
``τ_i = L = 0``: the paper's ping at the tick, read at once.

A ping between ticks k and k+1 is known at tick k+1: the sonar interpolates the geometry of
the two ticks (:func:`~drake_uuv.sensors.sonar_kernels.measure`, as
:mod:`drake_uuv.models.ping_geometry`), keeping the previous one as :class:`TickGeometry` in
its discrete state, and a ping that arrives later waits in a FIFO of slots
(:func:`entry_size`), also discrete state, per run.
"""

import math
from dataclasses import dataclass
from typing import Self

import numpy as np

from drake_uuv.models.measurement import NO_ARRIVAL

#: A delay ``(τ + L)/t`` within this of an integer counts as that integer (``0.3 + 0.2``
#: seconds of a 0.5 s step is one step, not two).
DELAY_TOLERANCE = 1e-9


def arrival_delays(
    ping_offsets: tuple[float, float], latency: float, time_step: float
) -> tuple[int, int]:
    """``(d_1, d_2)``: the ticks from each sonar's step to the arrival of its range.

    Raises ``ValueError`` naming the field for an offset outside ``[0, time_step)`` or a
    negative latency (the scenario checks the same; a sonar built by hand is checked here).
    """
    for tau in ping_offsets:
        if not 0.0 <= tau < time_step:
            raise ValueError(
                f"sonar.ping_offsets: must be in [0, time_step = {time_step:g}) each, "
                f"got {list(ping_offsets)!r}"
            )
    if not (math.isfinite(latency) and latency >= 0.0):
        raise ValueError(f"sonar.latency: must be ≥ 0, got {latency!r}")
    delays = []
    for tau in ping_offsets:
        total = tau + latency
        # A ping after the tick is known at the next tick at the earliest.
        delays.append(0 if total == 0.0 else max(1, math.ceil(total / time_step - DELAY_TOLERANCE)))
    return delays[0], delays[1]


@dataclass(frozen=True)
class TickGeometry:
    """What the sonar keeps of a tick to compute, at the next, the pings between the two.

    The truth (``p_WU``, ``v_WU``, ``R_WB``, ``p_WT``, ``v_WT``) and what the pan-tilts point
    at in that step: the estimator's prediction ``q_prior`` of the tick's relative position,
    the radius of the region they scan (NaN without a beam), and the attitude the vehicle
    believes it has (``R_WB_nav``), by which it turns that prediction into pan and tilt.
    ``time`` is NaN before the first tick.
    """

    time: float
    p_WU: np.ndarray
    v_WU: np.ndarray
    R_WB: np.ndarray  # 3×3
    p_WT: np.ndarray
    v_WT: np.ndarray
    q_prior: np.ndarray
    search_radius: float
    R_WB_nav: np.ndarray  # 3×3

    #: The length of :meth:`to_vector`.
    SIZE = 35

    def to_vector(self) -> np.ndarray:
        """The discrete-state layout: time, p_WU, v_WU, R_WB (row-major), p_WT, v_WT,
        q_prior, search radius, R_WB_nav (row-major)."""
        return np.concatenate(
            (
                [self.time],
                self.p_WU,
                self.v_WU,
                self.R_WB.ravel(),
                self.p_WT,
                self.v_WT,
                self.q_prior,
                [self.search_radius],
                self.R_WB_nav.ravel(),
            )
        )

    @classmethod
    def from_vector(cls, vector: np.ndarray) -> Self:
        v = np.asarray(vector, dtype=float)
        return cls(
            float(v[0]), v[1:4], v[4:7], v[7:16].reshape(3, 3), v[16:19], v[19:22], v[22:25],
            float(v[25]), v[26:35].reshape(3, 3),
        )  # fmt: skip

    @classmethod
    def before_start(cls) -> Self:
        """The state before the first tick: nothing known (every entry NaN)."""
        nan3, nan33 = np.full(3, math.nan), np.full((3, 3), math.nan)
        return cls(math.nan, nan3, nan3, nan33, nan3, nan3, nan3, math.nan, nan33)


def entry_size(samples_per_step: int) -> int:
    """The length of one sonar's ping as a FIFO slot holds it: its f samples, status,
    multipath, ping time and ``p_TS_W`` (the sonar from the target at the ping, W)."""
    return samples_per_step + 6


def no_arrival_entry(samples_per_step: int) -> np.ndarray:
    """A FIFO slot with nothing in it: NaN samples, NO_ARRIVAL, no multipath, NaN time and
    geometry."""
    entry = np.full(entry_size(samples_per_step), math.nan)
    entry[samples_per_step : samples_per_step + 2] = NO_ARRIVAL, 0.0
    return entry
