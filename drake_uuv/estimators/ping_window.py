"""The last steps of an estimator whose ranges come late: their arrived ranges and the motion.

A component of :class:`~drake_uuv.estimators.base.RelativeStateEstimator` when the sonars'
schedule is not the paper's (``PingSchedule.window = D ≥ 1``: a ping at ``t_k + τ``, a range
that arrives ``L`` later). The estimator keeps its belief at the anchor ``t_{j−D}`` (discrete
groups 0 and 1: every range of earlier steps taken) and, declared here on it, the ranges that
have arrived of the steps ``j−D .. j−1`` with each range's ping offset, and the navigation of
those steps: the navigated attitude at each tick (for the baseline at a ping, interpolated
along the step's geodesic: :mod:`drake_uuv.models.ping_geometry`), and the commanded world
acceleration of each step (``vehicle_motion: commanded``) or the navigated state at each tick
(``navigation``). Each tick the estimator steps the anchor through those steps
(:mod:`drake_uuv.models.timing`) and the periodic update moves the anchor one step on.

A range's step and offset come from the sonar's ``ping_time`` (the ping's time stamp): step
``⌊ping_time / t⌋``, offset the rest. With the host's ``batch_size`` B every value holds B
runs (a leading run axis; the state and ports B runs row-major).
"""

from dataclasses import dataclass

import numpy as np
from numba import njit
from pydrake.systems.framework import Context, DiscreteValues, InputPort, LeafSystem

from drake_uuv.models.measurement import NO_ARRIVAL, VALID
from drake_uuv.models.ping_geometry import (
    interpolate_attitude,
    interpolate_attitude_runs,
    interpolate_position,
    interpolate_velocity,
)
from drake_uuv.models.timing import PingSchedule
from drake_uuv.primitives.batch import per_run, tiled

_TOLERANCE = 1e-9


@dataclass(frozen=True)
class StepRanges:
    """One past step of one run: its arrived ranges, and the vehicle's navigation over it.

    ``step`` k; per sonar ``tau`` (ping offset), ``samples`` (2×f; NaN without a range),
    ``status`` (NO_ARRIVAL when not arrived yet), ``new`` (arrived at this tick);
    ``acceleration`` the commanded world acceleration of the step (commanded motion);
    ``start``, ``end`` the navigated state ``[p, v]`` at ``t_k`` and ``t_{k+1}`` (navigated
    motion); ``R_start``, ``R_end`` the navigated attitudes there.
    """

    step: int
    tau: np.ndarray
    samples: np.ndarray
    status: np.ndarray
    new: np.ndarray
    acceleration: np.ndarray
    start: np.ndarray
    end: np.ndarray
    R_start: np.ndarray
    R_end: np.ndarray

    def valid(self, sonar: int) -> bool:
        return bool(self.status[sonar] == VALID and np.all(np.isfinite(self.samples[sonar])))

    def attitude(self, tau: float, time_step: float) -> np.ndarray:
        """The navigated attitude at ``t_k + τ``."""
        return interpolate_attitude(self.R_start, self.R_end, tau / time_step)

    def vehicle(self, tau: float, time_step: float) -> np.ndarray:
        """The navigated state ``[p, v]`` at ``t_k + τ`` (navigated motion)."""
        return _navigated_state(self.start, self.end, tau / time_step, time_step)


@dataclass(frozen=True)
class StepBatch:
    """One past step of a batch of runs (:class:`StepRanges`' fields with a leading run axis:
    ``tau``, ``status``, ``new`` (B, 2), ``samples`` (B, 2, f), ``acceleration`` (B, 3),
    ``start``, ``end`` (B, 6), ``R_start``, ``R_end`` (B, 3, 3))."""

    step: int
    tau: np.ndarray
    samples: np.ndarray
    status: np.ndarray
    new: np.ndarray
    acceleration: np.ndarray
    start: np.ndarray
    end: np.ndarray
    R_start: np.ndarray
    R_end: np.ndarray

    def valid(self) -> np.ndarray:
        """Which sonars' ranges of each run are usable (B, 2)."""
        return (self.status == VALID) & np.isfinite(self.samples).all(axis=2)

    def attitude(self, tau: np.ndarray, time_step: float) -> np.ndarray:
        """The navigated attitudes at ``t_k + τ`` of each run (τ (B))."""
        return interpolate_attitude_runs(self.R_start, self.R_end, tau / time_step)

    def vehicle(self, tau: np.ndarray, time_step: float) -> np.ndarray:
        """The navigated states ``[p, v]`` (B, 6) at ``t_k + τ`` (navigated motion)."""
        return _navigated_state(self.start, self.end, (tau / time_step)[:, np.newaxis], time_step)

    def run(self, i: int) -> StepRanges:
        """Run i's step."""
        return StepRanges(
            self.step, self.tau[i], self.samples[i], self.status[i], self.new[i],
            self.acceleration[i], self.start[i], self.end[i], self.R_start[i], self.R_end[i],
        )  # fmt: skip


def _navigated_state(
    start: np.ndarray, end: np.ndarray, s: float | np.ndarray, time_step: float
) -> np.ndarray:
    """``[p, v]`` at fraction ``s`` of a step between the navigated states ``start`` and
    ``end`` (``[p, v]`` each, one run's (6) or a batch's (B, 6) with ``s`` (B, 1))."""
    p0, v0, p1, v1 = start[..., :3], start[..., 3:], end[..., :3], end[..., 3:]
    return np.concatenate(
        [
            interpolate_position(p0, v0, p1, v1, s, time_step),
            interpolate_velocity(p0, v0, p1, v1, s, time_step),
        ],
        axis=-1,
    )


class PingWindow:
    """The arrived ranges and the navigation of the last ``D`` steps of B runs, declared on
    ``host`` (``host.batch_size`` runs).

    State (three groups, per run, B runs row-major): per step slot (oldest first)
    ``[status (2), τ (2), samples (2f)]``; the navigated attitude at each slot's tick (9
    each); the slot's motion (3: the commanded acceleration, or 6: the navigated state at its
    tick). Input ``ping_time`` (2 a run): each sonar's ping time stamp.
    """

    def __init__(
        self,
        host: LeafSystem,
        schedule: PingSchedule,
        samples_per_step: int,
        attitude_port: InputPort,
        motion_ports: list[InputPort],
        navigated: bool,
    ) -> None:
        self._schedule = schedule
        self._t = schedule.time_step
        self._D = schedule.window
        self._f = samples_per_step
        self._B = B = host.batch_size
        self._navigated = navigated
        self._motion_size = 6 if navigated else 3
        self._slot = 4 + 2 * self._f
        slots = np.zeros((self._D, self._slot))
        slots[:, :2] = NO_ARRIVAL
        slots[:, 4:] = np.nan
        self._slots_index = host.DeclareDiscreteState(tiled(slots, B))
        self._attitudes_index = host.DeclareDiscreteState(
            tiled(np.tile(np.eye(3).ravel(), self._D), B)
        )
        self._motion_index = host.DeclareDiscreteState(np.zeros(B * self._D * self._motion_size))
        self._ping_time_port = host.DeclareVectorInputPort("ping_time", 2 * B)
        self._attitude_port = attitude_port
        self._motion_ports = motion_ports

    @property
    def schedule(self) -> PingSchedule:
        return self._schedule

    @property
    def input_ports(self) -> list[InputPort]:
        return [self._ping_time_port]

    def tick(self, context: Context) -> int:
        return round(context.get_time() / self._t)

    def _stored(self, context: Context) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        state = context.get_discrete_state
        B, D = self._B, self._D
        slots = per_run(state(self._slots_index).get_value(), B, D, self._slot).copy()
        attitudes = per_run(state(self._attitudes_index).get_value(), B, D, 3, 3)
        motion = per_run(state(self._motion_index).get_value(), B, D, self._motion_size)
        return slots, attitudes, motion

    def _take_arrivals(
        self,
        context: Context,
        slots: np.ndarray,
        first: int,
        samples: np.ndarray,
        status: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Writes the ranges arriving at this tick into ``slots`` (B, D, slot; the first slot
        is step ``first``; arrivals of later steps are left out) and returns which slot entries
        are new (B, D, 2) and which arrivals are of the current step (B, 2)."""
        ping_time = per_run(self._ping_time_port.Eval(context), self._B)
        new = np.zeros((self._B, self._D, 2), dtype=bool)
        current = np.zeros((self._B, 2), dtype=bool)
        _arrive(
            slots, first, self.tick(context), ping_time, status, samples, self._t, self._f,
            new, current,
        )  # fmt: skip
        return new, current

    def steps(
        self, context: Context, samples: np.ndarray, status: np.ndarray
    ) -> tuple[list[StepBatch], np.ndarray]:
        """The window's steps with their ranges arrived by this tick (steps before 0 left
        out), and the mask (B, 2) of this tick's ranges that belong to the current step
        (τ = 0, no latency). ``samples`` (B, 2, f), ``status`` (B, 2)."""
        j = self.tick(context)
        first = j - self._D
        slots, attitudes, motion = self._stored(context)
        new, current = self._take_arrivals(context, slots, first, samples, status)
        R_now = per_run(self._attitude_port.Eval(context), self._B, 3, 3)
        X_now = self._navigated_state(context)
        zeros3, zeros6 = np.zeros((self._B, 3)), np.zeros((self._B, 6))
        out = []
        for index in range(self._D):
            step = first + index
            if step < 0:
                continue
            last = index == self._D - 1
            navigated = self._navigated
            out.append(
                StepBatch(
                    step=step,
                    tau=slots[:, index, 2:4],
                    samples=slots[:, index, 4:].reshape(self._B, 2, self._f),
                    status=slots[:, index, :2],
                    new=new[:, index],
                    acceleration=motion[:, index] if not navigated else zeros3,
                    start=motion[:, index] if navigated else zeros6,
                    end=(X_now if last else motion[:, index + 1]) if navigated else zeros6,
                    R_start=attitudes[:, index],
                    R_end=R_now if last else attitudes[:, index + 1],
                )
            )
        return out, current

    def _navigated_state(self, context: Context) -> np.ndarray:
        if not self._navigated:
            return np.zeros((self._B, 6))
        p, v = (per_run(port.Eval(context), self._B) for port in self._motion_ports)
        return np.concatenate([p, v], axis=1)

    def record(
        self,
        context: Context,
        discrete_state: DiscreteValues,
        samples: np.ndarray,
        status: np.ndarray,
    ) -> None:
        """The periodic update: the window moves one step on, keeping this tick's arrivals,
        attitude and motion (``samples`` (B, 2, f), ``status`` (B, 2))."""
        j = self.tick(context)
        slots, attitudes, motion = self._stored(context)
        slots = np.concatenate([slots[:, 1:], np.full((self._B, 1, self._slot), np.nan)], axis=1)
        slots[:, -1, :2] = NO_ARRIVAL
        slots[:, -1, 2:4] = 0.0
        self._take_arrivals(context, slots, j + 1 - self._D, samples, status)
        R_now = per_run(self._attitude_port.Eval(context), self._B, 3, 3)
        attitudes = np.concatenate([attitudes[:, 1:], R_now[:, np.newaxis]], axis=1)
        if self._navigated:
            now = self._navigated_state(context)
        else:
            now = per_run(self._motion_ports[0].Eval(context), self._B)
        motion = np.concatenate([motion[:, 1:], now[:, np.newaxis]], axis=1)
        discrete_state.set_value(self._slots_index, slots.ravel())
        discrete_state.set_value(self._attitudes_index, attitudes.ravel())
        discrete_state.set_value(self._motion_index, motion.ravel())


@njit(cache=True, error_model="numpy")
def _arrive(slots, first, tick, ping_time, status, samples, t, f, new, current):
    """Each run's arrivals (status not NO_ARRIVAL, a finite ping time) into its slots: step
    ``⌊ping_time / t⌋``, offset the rest."""
    D = slots.shape[1]
    for r in range(slots.shape[0]):
        for sonar in range(2):
            stamp = ping_time[r, sonar]
            if status[r, sonar] == NO_ARRIVAL or not np.isfinite(stamp):
                continue
            step = np.floor(stamp / t + _TOLERANCE)
            current[r, sonar] = step == tick
            index = int(step) - first
            if 0 <= index < D:
                slots[r, index, sonar] = status[r, sonar]
                slots[r, index, 2 + sonar] = max(stamp - step * t, 0.0)
                for k in range(f):
                    slots[r, index, 4 + sonar * f + k] = samples[r, sonar, k]
                new[r, index, sonar] = True
