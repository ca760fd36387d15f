"""The base estimator's steps with late ranges: its ping window and the beliefs stepped through it.

A base of :class:`~drake_uuv.estimators.base.RelativeStateEstimator` (its second concern, kept
here): with a ping schedule that is not immediate, the estimator holds a
:class:`~drake_uuv.estimators.ping_window.PingWindow`, its state is the belief at the window's
anchor, and two cache entries step that anchor through the window's arrived ranges (with this
tick's, and without). The methods read the estimator's ports and state (``_samples_port``,
``_status_port``, ``_attitude_port``, ``_f``, ``_error_model``, ``vehicle_motion``, …), which
the base declares before it calls :meth:`LateRanges._declare_window`.
"""

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, Context, DiscreteValues, ValueProducer

from drake_uuv.estimators.contract import FilteredEstimate, MeasurementUpdate
from drake_uuv.estimators.ping_window import PingWindow
from drake_uuv.estimators.timed_step import NO_UPDATE, StepOutcome
from drake_uuv.models.measurement import GATED, NO_ARRIVAL, VALID
from drake_uuv.primitives.batch import per_run


class LateRanges:
    """The late-range part of :class:`~drake_uuv.estimators.base.RelativeStateEstimator` (see
    the module notes); with the paper's timing its window is None and nothing here runs."""

    def _declare_window(self, navigated: bool) -> PingWindow | None:
        """The ping window of the error model's schedule and its two cache entries (the
        anchors stepped through the ranges arrived by this tick, and before it), or None
        with the paper's timing."""
        if self._error_model.schedule.immediate:
            return None
        self._window = PingWindow(
            self, self._error_model.schedule, self._f, self._attitude_port,
            self.vehicle_motion.state_ports or [self.vehicle_motion.acceleration_port],
            navigated,
        )  # fmt: skip
        self._stepped = self._declare_window_cache("ranges arrived by this tick", True)
        self._stepped_before = self._declare_window_cache("ranges arrived before", False)
        return self._window

    def anchor_advance(self, context: Context) -> StepOutcome | None:
        """The window's anchor moved one step on: its oldest step, whose ranges have all
        arrived (None until the window is full)."""
        _, _, outcomes = self._stepped.Eval(context)
        if self._window.tick(context) < self._window.schedule.window:
            return None
        return outcomes[0]

    def _with_window_updates(
        self, context: Context, estimate: FilteredEstimate, update: MeasurementUpdate | None
    ) -> None:
        """Status and NIS of each run at a tick with late ranges: of the ranges that arrived at
        it (the window's instants that hold one, and this tick's own)."""
        B = self.batch_size
        updated_now = np.zeros(B, dtype=bool) if update is None else update.updated
        _, _, outcomes = self._stepped.Eval(context)
        applied_nis, applied = np.zeros(B), np.zeros(B, dtype=bool)
        news_nis, news = np.zeros(B), np.zeros(B, dtype=bool)
        news_dof = np.zeros(B)
        for u in (u for o in outcomes for u in o.updates):
            present = u.new & (u.status != NO_UPDATE)
            valid = present & (u.status == VALID)
            applied_nis = applied_nis + np.where(valid, u.nis, 0.0)
            applied |= valid
            news_nis = news_nis + np.where(present, u.nis, 0.0)
            news_dof = news_dof + np.where(present, u.dof, 0)
            news |= present
        # Every range that arrived at this tick, applied or gated, and this tick's own.
        estimate.innovation_nis = estimate.innovation_nis + news_nis
        estimate.innovation_dof = estimate.innovation_dof + news_dof
        now = (estimate.status == VALID) & updated_now
        applied_nis = applied_nis + np.where(now, estimate.nis, 0.0)
        applied |= now
        waiting = (estimate.status == VALID) & ~updated_now
        status = np.where(waiting, self.arrival_status(context), estimate.status)
        status = np.where(news, float(GATED), status)
        estimate.status = np.where(applied, float(VALID), status)
        nis = np.where(news, news_nis, estimate.nis)
        estimate.nis = np.where(applied, applied_nis, nis)

    def arrival_status(self, context: Context) -> np.ndarray:
        """Each run's status of a tick without an update (B): the first code of the sonars
        whose range arrived unusable, or NO_ARRIVAL when none arrived."""
        status = per_run(self._status_port.Eval(context), self.batch_size)
        invalid = (status != NO_ARRIVAL) & (status != VALID)
        later = np.where(invalid[:, 1], status[:, 1], float(NO_ARRIVAL))
        return np.where(invalid[:, 0], status[:, 0], later)

    def window_outcomes(self, context: Context) -> list[StepOutcome]:
        """The window steps' outcomes at this tick (empty with the paper's timing)."""
        return [] if self._window is None else self._stepped.Eval(context)[2]

    def _declare_window_cache(self, description: str, include_now: bool):
        ports = [
            self._attitude_port, *self.vehicle_motion.state_ports,
            *(self._window.input_ports if include_now else []),
            *([self._samples_port, self._status_port] if include_now else []),
        ]  # fmt: skip
        return self.DeclareCacheEntry(
            description,
            ValueProducer(
                allocate=AbstractValue.Make((np.zeros(0), np.zeros(0), [])).Clone,
                calc=lambda context, value: value.set_value(
                    self._step_window(context, include_now)
                ),
            ),
            self._tickets(ports) | {self.xd_ticket()},
        )

    def _step_window(self, context: Context, include_now: bool) -> tuple:
        """``(x, P, outcomes)``: the anchors stepped through the window (stored frame)."""
        B, f = self.batch_size, self._f
        if include_now:
            samples = per_run(self._samples_port.Eval(context), B, 2, f)
            status = per_run(self._status_port.Eval(context), B)
        else:
            samples, status = np.full((B, 2, f), np.nan), np.full((B, 2), float(NO_ARRIVAL))
        steps, _ = self._window.steps(context, samples, status)
        anchor = self.anchor(context)
        x, P = anchor.x, anchor.P
        outcomes = []
        for step in steps:
            outcome = self.step_belief(context, x, P, step)
            x, P = outcome.x, outcome.P
            outcomes.append(outcome)
        return x, P, outcomes

    def _calc_prior_before(self, context: Context, output: BasicVector) -> None:
        x, _, _ = self._stepped_before.Eval(context)
        output.set_value(self.vehicle_motion.prior(context, x).ravel())

    def _calc_P_prior_before(self, context: Context, output: BasicVector) -> None:
        output.set_value(self._stepped_before.Eval(context)[1].ravel())

    def _record_window(self, context: Context, discrete_state: DiscreteValues) -> None:
        """The periodic update's part of the window: records this tick's ranges in it."""
        B = self.batch_size
        samples = per_run(self._samples_port.Eval(context), B, 2, self._f)
        status = per_run(self._status_port.Eval(context), B)
        self._window.record(context, discrete_state, samples, status)
