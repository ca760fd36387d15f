"""The estimator slot's contract and what every estimator shares: ports, prediction, gating.

An estimator is a :class:`RelativeStateEstimator`. It is built as
``SomeEstimator(config, setting=EstimatorSetting(...))``: ``config`` its own variant dataclass
(``drake_uuv/scenario/estimators.py``), ``setting`` what it needs from the rest of the
scenario. A variant supplies one hook, :meth:`RelativeStateEstimator.measurement_update`, and
may override :meth:`RelativeStateEstimator.advance` for state of its own; it reads and writes
the shared estimate only through the public accessors (:meth:`~RelativeStateEstimator.prior`,
:meth:`~RelativeStateEstimator.predicted`, :meth:`~RelativeStateEstimator.write_prediction`).
"""

import math

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import (
    BasicVector,
    Context,
    DiscreteValues,
    InputPort,
    LeafSystem,
    ValueProducer,
)

from drake_uuv.estimators.contract import (
    Estimate,
    EstimatorSetting,
    FilteredEstimate,
    MeasurementUpdate,
    Ranges,
)
from drake_uuv.estimators.error_model import ErrorModel, ideal_model
from drake_uuv.estimators.ping_window import PingWindow
from drake_uuv.estimators.timed_step import StepOutcome, gaussian_step
from drake_uuv.estimators.vehicle_motion import VEHICLE_MOTIONS
from drake_uuv.models.filters import predict
from drake_uuv.models.measurement import GATED, NO_ARRIVAL, VALID
from drake_uuv.models.motion import double_integrator, process_noise_covariance
from drake_uuv.models.statistics import chi2_ppf
from drake_uuv.scenario.estimators import EstimatorOptions


class RelativeStateEstimator(LeafSystem):
    """Base of the estimators of ``Υ = [q, ϑ]``; a variant supplies the measurement update.

    Timing (the paper's): the filtered estimate ``Υ̂(k|k)`` of step k is a direct-feedthrough
    output of the step's ranges and the estimator's state only (never of ``u1_W``), so the
    controllers act on it in the same tick; the periodic update at the tick writes the
    prediction ``Υ̂(k+1|k)``, ``P(k+1|k) = A P Aᵀ + B W Bᵀ`` (discrete-state groups 0 and 1),
    where W is the target's acceleration covariance plus the config's
    ``added_acceleration_variance``. How the vehicle's own motion enters the prediction is
    ``config.vehicle_motion`` (:mod:`drake_uuv.estimators.vehicle_motion`: the commanded
    acceleration, or the vehicle's navigated state).

    A step whose sonars did not return only predicts, as the variant decides (its hook returns
    None). With ``gate_probability`` set, an update whose NIS exceeds the χ² quantile of that
    probability (for its innovation dimension) is rejected (status GATED).

    Hooks and accessors for a variant:

    - :meth:`measurement_update` (required): the step's posterior from its prior and ranges.
    - :meth:`advance` (optional): the periodic update; the default writes the Gaussian
      prediction of the filtered estimate. Override it for state of your own (declare your
      groups with ``DeclareDiscreteState`` in ``__init__``) and call ``super().advance``.
    - :meth:`prior`, :meth:`ranges`, :meth:`filtered`: this step's prior, ranges and filtered
      estimate; :meth:`predicted` and :meth:`write_prediction`: a prediction in the frame the
      state stores (see :mod:`~drake_uuv.estimators.vehicle_motion`) and writing it.
    - :attr:`vehicle_motion`: the strategy's ``offset`` and ``acceleration`` of this step.
    - :meth:`navigation_process_noise`: what the modelled navigation errors add to this
      step's Q (:meth:`predicted` adds it; a sampling variant draws it, as the particle cloud
      does).
    - :meth:`depends_on_measurement`: the tickets of everything the step's ranges and prior
      depend on, for a cache entry of your own.

    Ports (declared here; a variant may declare more inputs, e.g. random ones, which the
    filtered estimate must then not depend on):

    - input ``range_samples`` (2f): sonar 1's f samples, then sonar 2's [m]; NaN: no return.
    - input ``sonar_status`` (2): each sonar's return status (VALID, DROPPED, …).
    - input ``R_WB_nav`` (9, row-major): the navigated attitude, for ``q_s = R_WB_nav b``.
    - input ``u1_W`` (3): the vehicle's applied world acceleration ``R u1`` at step k
      (``vehicle_motion: commanded``), or inputs ``p_WU_nav``, ``v_WU_nav`` (3 each), the
      vehicle's navigated state (``navigation``).
    - output ``x_TU_hat`` (6): filtered ``Υ̂(k|k) = [q̂, ϑ̂]``, ``q = p_WU − p_WT`` (the
      vehicle's position from the target, world frame), ``ϑ = v_WU − v_WT``.
    - output ``P_TU`` (36): ``P(k|k)`` row-major.
    - outputs ``x_TU_prior`` (6), ``P_TU_prior`` (36): ``Υ̂(k|k−1)`` and ``P(k|k−1)`` (state
      only, so a sonar may point at the prediction without an algebraic loop).
    - output ``measurement_status`` (1): VALID, DROPPED, OUT_OF_BEAM, OUT_OF_RANGE or GATED.
    - output ``nis`` (1): the update's normalised innovation squared (NaN when none).
    """

    def __init__(self, config: EstimatorOptions, *, setting: EstimatorSetting) -> None:
        super().__init__()
        if not isinstance(config, EstimatorOptions):
            raise ValueError(f"config: must be an estimator's dataclass, got {config!r}")
        if not isinstance(setting, EstimatorSetting):
            raise ValueError(f"setting: must be an EstimatorSetting, got {setting!r}")
        config.validate("estimator")
        self._setting = setting
        self._time_step = float(setting.time_step)
        self._A, self._B = double_integrator(self._time_step)
        W = config.filter_acceleration_covariance(setting.acceleration_covariance)
        self._W = W
        self._Q = process_noise_covariance(W, self._time_step)
        self._gate_probability = config.gate_probability
        self._gate_thresholds: dict[int, float] = {}
        self._f = setting.samples_per_step
        self._b = setting.baseline_B
        x0 = np.asarray(config.initial_estimate, dtype=float)
        P0 = np.asarray(config.initial_covariance, dtype=float)
        self._initial = Estimate(x0, P0)
        self._x_index = self.DeclareDiscreteState(x0)
        self._P_index = self.DeclareDiscreteState(P0.ravel())

        self._samples_port = self.DeclareVectorInputPort("range_samples", 2 * self._f)
        self._status_port = self.DeclareVectorInputPort("sonar_status", 2)
        self._attitude_port = self.DeclareVectorInputPort("R_WB_nav", 9)
        self.vehicle_motion = VEHICLE_MOTIONS[config.vehicle_motion](self)
        if self.vehicle_motion.state_ports:
            self.DeclareInitializationDiscreteUpdateEvent(self._start_in_stored_frame)
        navigated = bool(self.vehicle_motion.state_ports)
        if config.error_model == "ideal":
            self._error_model = ideal_model(self._time_step)
        else:
            self._error_model = ErrorModel(
                setting.navigation_errors, setting.ping_schedule, setting.sound_speed_error,
                navigated,
            )  # fmt: skip
        # The model is frozen: whether it adds anything is known once, not asked every step.
        self._model_active = self._error_model.active
        # Σ_θ at the tick's navigated attitude (None without attitude noise), computed once a
        # tick: the ranges, the process noise and the published floor all use it.
        self._sigma_theta = self.DeclareCacheEntry(
            "attitude noise covariance",
            ValueProducer(allocate=AbstractValue.Make(np.eye(3)).Clone, calc=self._calc_sigma),
            {self._attitude_port.ticket()},
        )
        self._window = None
        if not self._error_model.schedule.immediate:
            self._window = PingWindow(
                self, self._error_model.schedule, self._f, self._attitude_port,
                self.vehicle_motion.state_ports or [self.vehicle_motion.acceleration_port],
                navigated,
            )  # fmt: skip
            self._stepped = self._declare_window_cache("ranges arrived by this tick", True)
            self._stepped_before = self._declare_window_cache("ranges arrived before", False)
        self._filtered = self.DeclareCacheEntry(
            "filtered estimate",
            ValueProducer(
                allocate=AbstractValue.Make(FilteredEstimate(np.zeros(6), np.eye(6))).Clone,
                calc=self._calc_filtered,
            ),
            self.depends_on_measurement(),
        )
        depends = {self._filtered.ticket()}
        self.DeclareVectorOutputPort("x_TU_hat", 6, self._calc_x_hat, depends)
        self.DeclareVectorOutputPort("P_TU", 36, self._calc_P, depends)
        if self._window is not None:  # the belief stepped through the window's earlier ranges
            before = {self._stepped_before.ticket()}
            self.DeclareVectorOutputPort("x_TU_prior", 6, self._calc_prior_before, before)
            self.DeclareVectorOutputPort("P_TU_prior", 36, self._calc_P_prior_before, before)
        elif self.vehicle_motion.state_ports:
            prior_tickets = {self.xd_ticket(), *self._tickets(self.vehicle_motion.state_ports)}
            self.DeclareVectorOutputPort("x_TU_prior", 6, self._calc_prior, prior_tickets)
            self.DeclareStateOutputPort("P_TU_prior", self._P_index)
        else:
            self.DeclareStateOutputPort("x_TU_prior", self._x_index)
            self.DeclareStateOutputPort("P_TU_prior", self._P_index)
        self.DeclareVectorOutputPort("measurement_status", 1, self._calc_status, depends)
        self.DeclareVectorOutputPort("nis", 1, self._calc_nis, depends)
        self.DeclarePeriodicDiscreteUpdateEvent(self._time_step, 0.0, self._update)

    # ------------------------------------------------------------------ hooks for a variant

    def measurement_update(
        self, context: Context, prior: Estimate, ranges: Ranges
    ) -> MeasurementUpdate | None:
        """The posterior from this step's ranges, or None when there is none to use."""
        raise NotImplementedError(f"{type(self).__name__} must define measurement_update")

    def advance(
        self, context: Context, filtered: FilteredEstimate, discrete_state: DiscreteValues
    ) -> None:
        """The periodic update at the tick: writes the prediction of ``filtered``.

        ``filtered`` is this step's filtered estimate (``filtered.applied`` when an update was
        applied). Override it to advance state of your own; call ``super().advance`` (or
        :meth:`write_prediction`) for groups 0 and 1. With late ranges the state is the belief
        at the window's anchor instead, moved one step on (:meth:`anchor_advance`).
        """
        if self._window is None:
            prediction = self.predicted(context, filtered.x, filtered.P)
            self.write_prediction(discrete_state, *prediction)
            return
        outcome = self.anchor_advance(context)
        if outcome is not None:
            self.write_prediction(discrete_state, outcome.x, outcome.P)

    def filtered_estimate(self, context: Context) -> FilteredEstimate | None:
        """A variant's own filtered estimate of this tick, or None for the base's (the
        measurement update of the prior). The particles with late ranges use it."""
        return None

    def needs_both_ranges(self, context: Context) -> bool:
        """Whether this step's update needs both ranges at one instant (the paper's ``Y``):
        then, with the pings at different times, the earlier range is carried to the later
        ping time. The default: no."""
        return False

    def step_belief(self, context: Context, x: np.ndarray, P: np.ndarray, step) -> StepOutcome:
        """The belief ``N(x, P)`` at a window step's tick (stored frame), stepped through the
        step's arrived ranges at their ping times to the next tick
        (:func:`~drake_uuv.estimators.timed_step.gaussian_step`)."""
        return gaussian_step(self, context, x, P, step)

    # ------------------------------------------------------------------------- accessors

    @property
    def setting(self) -> EstimatorSetting:
        return self._setting

    @property
    def time_step(self) -> float:
        return self._time_step

    @property
    def model(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(A, B, W)``: the double integrator of one step and the filter's acceleration
        covariance (the target's W plus the added variance)."""
        return self._A, self._B, self._W

    @property
    def baseline(self) -> np.ndarray:
        """``b`` in the body frame [m]."""
        return self._b

    @property
    def error_model(self) -> ErrorModel:
        """What this estimator believes of its navigation and sonars."""
        return self._error_model

    @property
    def window(self) -> PingWindow | None:
        """The window of late ranges (None with the paper's timing)."""
        return self._window

    @property
    def initial_estimate(self) -> Estimate:
        """``Υ̂(0|−1)`` and ``P(0|−1)`` of the config."""
        return self._initial

    def prior(self, context: Context) -> Estimate:
        """This step's prediction ``Υ̂(k|k−1)``, ``P(k|k−1)`` (relative state): with late
        ranges, the anchor stepped through the window with every range arrived by now."""
        if self._window is not None:
            x, P, _ = self._stepped.Eval(context)
            return Estimate(self.vehicle_motion.prior(context, x), P)
        stored = context.get_discrete_state(self._x_index).get_value()
        P = context.get_discrete_state(self._P_index).get_value().reshape(6, 6)
        return Estimate(self.vehicle_motion.prior(context, stored), P)

    def anchor(self, context: Context) -> Estimate:
        """The stored belief (the prediction, or the window's anchor), stored frame."""
        x = context.get_discrete_state(self._x_index).get_value()
        P = context.get_discrete_state(self._P_index).get_value().reshape(6, 6)
        return Estimate(x, P)

    def anchor_advance(self, context: Context) -> StepOutcome | None:
        """The window's anchor moved one step on: its oldest step, whose ranges have all
        arrived (None until the window is full)."""
        _, _, outcomes = self._stepped.Eval(context)
        if self._window.tick(context) < self._window.schedule.window:
            return None
        return outcomes[0]

    def set_prior(self, context: Context, x: np.ndarray, P: np.ndarray) -> None:
        """Sets this step's prediction ``Υ̂(k|k−1)``, ``P(k|k−1)`` in ``context`` (e.g. to start
        a test or a run from a chosen prior); the vehicle inputs must be connected or fixed
        with ``vehicle_motion: navigation``."""
        stored = np.asarray(x, dtype=float) - self.vehicle_motion.offset(context)
        context.SetDiscreteState(self._x_index, stored)
        context.SetDiscreteState(self._P_index, np.asarray(P, dtype=float).ravel())

    def ranges(self, context: Context) -> Ranges:
        """This tick's ranges, their means, the world baseline and the error model's noise.

        With late ranges, only those of this tick's own pings (at the tick, no latency); the
        others are the window's."""
        samples = self._samples_port.Eval(context).reshape(2, self._f)
        status = self._status_port.Eval(context)
        if self._window is not None:
            _, current = self._window.steps(context, samples, status)
            samples = np.where(current[:, np.newaxis], samples, np.nan)
            status = np.where(current, status, NO_ARRIVAL)
        valid = (status == VALID) & np.isfinite(samples).all(axis=1)
        R_WB = self._attitude_port.Eval(context).reshape(3, 3)
        q_s = R_WB @ self._b
        z = samples.sum(axis=1) / self._f  # samples.mean(axis=1)'s arithmetic, without its wrapper
        if not self._model_active:
            return Ranges(samples, z, valid, status, q_s)
        sigma_theta, sound = self._sigma_theta.Eval(context), self._error_model.range_variance(z)
        return Ranges(samples, z, valid, status, q_s, sigma_theta, sound)

    def filtered(self, context: Context) -> FilteredEstimate:
        """This step's filtered estimate (the cache entry behind ``x_TU_hat`` and ``P_TU``)."""
        return self._filtered.Eval(context)

    def predicted(
        self, context: Context, x: np.ndarray, P: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """``(A (x − offset) + B acceleration, A P Aᵀ + Q)``: the prediction of a relative
        estimate, in the frame the state stores (see :attr:`vehicle_motion`)."""
        motion = self.vehicle_motion
        extra = self.navigation_process_noise(context)
        Q = self._Q if extra is None else self._Q + extra
        return predict(
            motion.stored(context, x), P, motion.acceleration(context), self._A, self._B, Q
        )

    def navigation_process_noise(self, context: Context) -> np.ndarray | None:
        """What the modelled navigation errors add to the step's Q from this tick (6×6; None
        when nothing): :meth:`~drake_uuv.estimators.error_model.ErrorModel.process_noise` at
        this tick's commanded acceleration, navigated attitude and navigated velocity."""
        if not self._model_active:
            return None
        motion, sigma_theta = self.vehicle_motion, self._sigma_theta.Eval(context)
        return self._error_model.process_noise(
            self._time_step, motion.acceleration(context), sigma_theta, motion.offset(context)[3:]
        )

    def _calc_sigma(self, context: Context, value: AbstractValue) -> None:
        R_WB_nav = self._attitude_port.Eval(context).reshape(3, 3)
        value.set_value(self._error_model.attitude_covariance(R_WB_nav))

    def write_prediction(
        self, discrete_state: DiscreteValues, x: np.ndarray, P: np.ndarray
    ) -> None:
        """Writes the next step's prediction (groups 0 and 1), ``x`` in the stored frame."""
        discrete_state.set_value(self._x_index, x)
        discrete_state.set_value(self._P_index, np.asarray(P).ravel())

    def depends_on_measurement(self) -> set:
        """Tickets of the step's ranges, prior and discrete state (not of ``u1_W``)."""
        ports = [
            self._samples_port, self._status_port, self._attitude_port,
            *self.vehicle_motion.state_ports,
            *(self._window.input_ports if self._window is not None else []),
        ]  # fmt: skip
        return self._tickets(ports) | {self.xd_ticket()}

    def gate_threshold(self, dof: int) -> float:
        """The NIS above which an update is rejected (``inf`` without a gate)."""
        if self._gate_probability is None:
            return math.inf
        if dof not in self._gate_thresholds:
            self._gate_thresholds[dof] = chi2_ppf(self._gate_probability, dof)
        return self._gate_thresholds[dof]

    # ------------------------------------------------------------------------- internals

    @staticmethod
    def _tickets(ports: list[InputPort]) -> set:
        return {port.ticket() for port in ports}

    def _start_in_stored_frame(self, context: Context, discrete_state: DiscreteValues) -> None:
        """At initialization: group 0 becomes ``Υ̂(0|−1) − offset``."""
        x0 = context.get_discrete_state(self._x_index).get_value()
        discrete_state.set_value(self._x_index, x0 - self.vehicle_motion.offset(context))

    def _calc_filtered(self, context: Context, value: AbstractValue) -> None:
        estimate = self.filtered_estimate(context)
        if estimate is None:
            estimate = self._filtered_by_update(context)
        if self._model_active:
            estimate.floor = self._error_model.floor(estimate.x, self._velocity_covariance(context))
        else:
            estimate.floor = None
        value.set_value(estimate)

    def _velocity_covariance(self, context: Context) -> np.ndarray | None:
        """``Σ_ev`` of the navigated velocity at this tick (navigated motion only)."""
        if not self._error_model.navigated_motion:
            return None
        return self._error_model.velocity_covariance(
            self.vehicle_motion.offset(context)[3:], self._sigma_theta.Eval(context)
        )

    def _filtered_by_update(self, context: Context) -> FilteredEstimate:
        prior = self.prior(context)
        ranges = self.ranges(context)
        update = None
        if not self.needs_both_ranges(context) or ranges.valid.all():
            update = self.measurement_update(context, prior, ranges)
        if update is None:
            estimate = FilteredEstimate(prior.x.copy(), prior.P.copy(), self._no_update(ranges))
        elif update.nis > self.gate_threshold(update.dof):
            estimate = FilteredEstimate(prior.x.copy(), prior.P.copy(), GATED, update.nis)
        else:
            estimate = FilteredEstimate(update.x, update.P, VALID, update.nis)
        if self._window is not None:
            self._with_window_updates(context, estimate, update is not None)
        return estimate

    @staticmethod
    def _no_update(ranges: Ranges) -> int:
        invalid = ranges.status[ranges.status != VALID]
        return int(invalid[0]) if invalid.size else VALID

    def _with_window_updates(
        self, context: Context, estimate: FilteredEstimate, updated_now: bool
    ) -> None:
        """Status and NIS of a tick with late ranges: of the ranges that arrived at it (the
        window's instants that hold one, and this tick's own)."""
        _, _, outcomes = self._stepped.Eval(context)
        news = [u for o in outcomes for u in o.updates if u.new]
        applied = [u.nis for u in news if u.status == VALID]
        if estimate.status == VALID and updated_now:
            applied.append(estimate.nis)
        if applied:
            estimate.status, estimate.nis = VALID, float(sum(applied))
        elif news:
            estimate.status, estimate.nis = GATED, float(sum(u.nis for u in news))
        elif estimate.status == VALID and not updated_now:
            estimate.status = self.arrival_status(context)

    def arrival_status(self, context: Context) -> int:
        """The status of a tick without an update: the first code of the sonars whose range
        arrived unusable, or NO_ARRIVAL when none arrived."""
        status = self._status_port.Eval(context)
        arrived = status[status != NO_ARRIVAL]
        invalid = arrived[arrived != VALID]
        return int(invalid[0]) if invalid.size else NO_ARRIVAL

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
                allocate=AbstractValue.Make((np.zeros(6), np.eye(6), [])).Clone,
                calc=lambda context, value: value.set_value(
                    self._step_window(context, include_now)
                ),
            ),
            self._tickets(ports) | {self.xd_ticket()},
        )

    def _step_window(self, context: Context, include_now: bool) -> tuple:
        """``(x, P, outcomes)``: the anchor stepped through the window (stored frame)."""
        f = self._f
        if include_now:
            samples = self._samples_port.Eval(context).reshape(2, f)
            status = self._status_port.Eval(context)
        else:
            samples, status = np.full((2, f), np.nan), np.full(2, float(NO_ARRIVAL))
        steps, _ = self._window.steps(context, samples, status)
        anchor = self.anchor(context)
        x, P = anchor.x, anchor.P
        outcomes = []
        for step in steps:
            outcome = self.step_belief(context, x, P, step)
            x, P = outcome.x, outcome.P
            outcomes.append(outcome)
        return x, P, outcomes

    def _update(self, context: Context, discrete_state: DiscreteValues) -> None:
        self.advance(context, self._filtered.Eval(context), discrete_state)
        if self._window is not None:
            samples = self._samples_port.Eval(context).reshape(2, self._f)
            self._window.record(context, discrete_state, samples, self._status_port.Eval(context))

    def _calc_prior(self, context: Context, output: BasicVector) -> None:
        output.set_value(self.prior(context).x)

    def _calc_prior_before(self, context: Context, output: BasicVector) -> None:
        x, _, _ = self._stepped_before.Eval(context)
        output.set_value(self.vehicle_motion.prior(context, x))

    def _calc_P_prior_before(self, context: Context, output: BasicVector) -> None:
        output.set_value(self._stepped_before.Eval(context)[1].ravel())

    def _calc_x_hat(self, context: Context, output: BasicVector) -> None:
        output.set_value(self._filtered.Eval(context).x)

    def _calc_P(self, context: Context, output: BasicVector) -> None:
        output.set_value(self._filtered.Eval(context).published_P.ravel())

    def _calc_status(self, context: Context, output: BasicVector) -> None:
        output.SetAtIndex(0, self._filtered.Eval(context).status)

    def _calc_nis(self, context: Context, output: BasicVector) -> None:
        output.SetAtIndex(0, self._filtered.Eval(context).nis)
