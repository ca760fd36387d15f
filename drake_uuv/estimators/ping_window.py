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
``⌊ping_time / t⌋``, offset the rest.
"""

import math
from dataclasses import dataclass

import numpy as np
from pydrake.systems.framework import Context, DiscreteValues, InputPort, LeafSystem

from drake_uuv.models.measurement import NO_ARRIVAL, VALID
from drake_uuv.models.ping_geometry import (
    interpolate_attitude,
    interpolate_position,
    interpolate_velocity,
)
from drake_uuv.models.timing import PingSchedule

_TOLERANCE = 1e-9


@dataclass(frozen=True)
class StepRanges:
    """One past step: its arrived ranges, and the vehicle's navigation over it.

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
        s = tau / time_step
        p0, v0, p1, v1 = self.start[:3], self.start[3:], self.end[:3], self.end[3:]
        return np.concatenate(
            [
                interpolate_position(p0, v0, p1, v1, s, time_step),
                interpolate_velocity(p0, v0, p1, v1, s, time_step),
            ]
        )


class PingWindow:
    """The arrived ranges and the navigation of the last ``D`` steps, declared on ``host``.

    State (three groups): per step slot (oldest first) ``[status (2), τ (2), samples (2f)]``;
    the navigated attitude at each slot's tick (9 each); the slot's motion (3: the commanded
    acceleration, or 6: the navigated state at its tick).
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
        self._navigated = navigated
        self._motion_size = 6 if navigated else 3
        self._slot = 4 + 2 * self._f
        slots = np.zeros((self._D, self._slot))
        slots[:, :2] = NO_ARRIVAL
        slots[:, 4:] = np.nan
        self._slots_index = host.DeclareDiscreteState(slots.ravel())
        self._attitudes_index = host.DeclareDiscreteState(np.tile(np.eye(3).ravel(), self._D))
        self._motion_index = host.DeclareDiscreteState(np.zeros(self._D * self._motion_size))
        self._ping_time_port = host.DeclareVectorInputPort("ping_time", 2)
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
        slots = state(self._slots_index).get_value().reshape(self._D, self._slot).copy()
        attitudes = state(self._attitudes_index).get_value().reshape(self._D, 3, 3)
        motion = state(self._motion_index).get_value().reshape(self._D, self._motion_size)
        return slots, attitudes, motion

    def _arrivals(
        self, context: Context, samples: np.ndarray, status: np.ndarray
    ) -> list[tuple[int, int, float]]:
        """``(sonar, step, τ)`` of each range arriving at this tick."""
        ping_time = self._ping_time_port.Eval(context)
        out = []
        for i in range(2):
            if status[i] == NO_ARRIVAL or not math.isfinite(ping_time[i]):
                continue
            step = math.floor(ping_time[i] / self._t + _TOLERANCE)
            out.append((i, step, max(ping_time[i] - step * self._t, 0.0)))
        return out

    def _fill(
        self,
        slots: np.ndarray,
        first: int,
        arrivals: list[tuple[int, int, float]],
        samples: np.ndarray,
        status: np.ndarray,
    ) -> np.ndarray:
        """Marks which slot entries are new, writing the arrivals into ``slots`` (whose first
        slot is step ``first``); arrivals of step j (no slot) are left out."""
        new = np.zeros((self._D, 2), dtype=bool)
        for sonar, step, tau in arrivals:
            index = step - first
            if 0 <= index < self._D:
                slots[index, sonar] = status[sonar]
                slots[index, 2 + sonar] = tau
                slots[index, 4 + sonar * self._f : 4 + (sonar + 1) * self._f] = samples[sonar]
                new[index, sonar] = True
        return new

    def steps(
        self, context: Context, samples: np.ndarray, status: np.ndarray
    ) -> tuple[list[StepRanges], np.ndarray]:
        """The window's steps with their ranges arrived by this tick (steps before 0 left
        out), and the mask of this tick's ranges that belong to the current step (τ = 0,
        no latency)."""
        j = self.tick(context)
        first = j - self._D
        slots, attitudes, motion = self._stored(context)
        arrivals = self._arrivals(context, samples, status)
        new = self._fill(slots, first, arrivals, samples, status)
        current = np.zeros(2, dtype=bool)
        for sonar, step, _ in arrivals:
            current[sonar] = step == j
        R_now = self._attitude_port.Eval(context).reshape(3, 3)
        X_now = self._navigated_state(context)
        out = []
        for index in range(self._D):
            step = first + index
            if step < 0:
                continue
            last = index == self._D - 1
            out.append(
                StepRanges(
                    step=step,
                    tau=slots[index, 2:4],
                    samples=slots[index, 4:].reshape(2, self._f),
                    status=slots[index, :2],
                    new=new[index],
                    acceleration=motion[index] if not self._navigated else np.zeros(3),
                    start=motion[index] if self._navigated else np.zeros(6),
                    end=(X_now if last else motion[index + 1]) if self._navigated else np.zeros(6),
                    R_start=attitudes[index],
                    R_end=R_now if last else attitudes[index + 1],
                )
            )
        return out, current

    def _navigated_state(self, context: Context) -> np.ndarray:
        if not self._navigated:
            return np.zeros(6)
        p, v = (port.Eval(context) for port in self._motion_ports)
        return np.concatenate([p, v])

    def record(
        self,
        context: Context,
        discrete_state: DiscreteValues,
        samples: np.ndarray,
        status: np.ndarray,
    ) -> None:
        """The periodic update: the window moves one step on, keeping this tick's arrivals,
        attitude and motion."""
        j = self.tick(context)
        slots, attitudes, motion = self._stored(context)
        slots = np.vstack([slots[1:], np.full((1, self._slot), np.nan)])
        slots[-1, :2] = NO_ARRIVAL
        slots[-1, 2:4] = 0.0
        self._fill(
            slots, j + 1 - self._D, self._arrivals(context, samples, status), samples, status
        )
        R_now = self._attitude_port.Eval(context).reshape(3, 3)
        attitudes = np.concatenate([attitudes[1:], R_now[np.newaxis]])
        if self._navigated:
            now = self._navigated_state(context)
        else:
            now = self._motion_ports[0].Eval(context)
        motion = np.vstack([motion[1:], now[np.newaxis]])
        discrete_state.set_value(self._slots_index, slots.ravel())
        discrete_state.set_value(self._attitudes_index, attitudes.ravel())
        discrete_state.set_value(self._motion_index, motion.ravel())
