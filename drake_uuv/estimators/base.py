"""The estimator slot's contract and what every estimator shares: ports, prediction, gating.

An estimator is a :class:`RelativeStateEstimator`. It is built as
``SomeEstimator(config, setting=EstimatorSetting(...))``: ``config`` its own variant dataclass
(``drake_uuv/scenario/estimators.py``), ``setting`` what it needs from the rest of the
scenario. A variant supplies one hook, :meth:`RelativeStateEstimator.measurement_update`, and
may override :meth:`RelativeStateEstimator.advance` for state of its own; it reads and writes
the shared estimate only through the public accessors (:meth:`~RelativeStateEstimator.prior`,
:meth:`~RelativeStateEstimator.predicted`, :meth:`~RelativeStateEstimator.write_prediction`).
Its steps with late ranges (the ping window) are its base :mod:`~drake_uuv.estimators.late_ranges`.
"""

import math

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import (
    Context,
    DiscreteValues,
    InputPort,
    LeafSystem,
    State,
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
from drake_uuv.estimators.late_ranges import LateRanges
from drake_uuv.estimators.outputs import EstimatorOutputs
from drake_uuv.estimators.ping_window import PingWindow
from drake_uuv.estimators.timed_step import StepOutcome, gaussian_step
from drake_uuv.estimators.vehicle_motion import VEHICLE_MOTIONS
from drake_uuv.models.filter_runs import predict_runs
from drake_uuv.models.measurement import GATED, NO_ARRIVAL, VALID
from drake_uuv.models.motion import double_integrator, process_noise_covariance
from drake_uuv.models.statistics import chi2_ppf
from drake_uuv.primitives.batch import batch_size_field, per_run, tiled
from drake_uuv.scenario.estimators import EstimatorOptions


class RelativeStateEstimator(LateRanges, EstimatorOutputs, LeafSystem):
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
      A variant with abstract state passes ``abstract_state=True`` and overrides
      :meth:`advance_state` (its outputs are then published: :mod:`.outputs`).
    - :meth:`prior`, :meth:`ranges`, :meth:`filtered`: this step's prior, ranges and filtered
      estimate; :meth:`predicted` and :meth:`write_prediction`: a prediction in the frame the
      state stores (see :mod:`~drake_uuv.estimators.vehicle_motion`) and writing it.
    - :attr:`vehicle_motion`: the strategy's ``offset`` and ``acceleration`` of this step.
    - :meth:`navigation_process_noise`: what the modelled navigation errors add to this
      step's Q (:meth:`predicted` adds it; a sampling variant draws it, as the particle cloud
      does).
    - :meth:`depends_on_measurement`: the tickets of everything the step's ranges and prior
      depend on, for a cache entry of your own.

    Batch: with ``batch_size`` B the estimator steps B independent runs at once (B = 1: one
    run, through the same code). Every port and discrete-state group holds B runs row-major
    (a per-run size n is B·n entries, run i's at ``[i·n, (i + 1)·n)``), and every accessor
    and hook takes and gives arrays with a leading run axis (:mod:`.contract`). A run's
    phase of the computation (updated, gated, only predicted) is a mask, never a branch for
    the batch.

    Ports (declared here, sizes per run; a variant may declare more inputs, e.g. random ones,
    which the filtered estimate must then not depend on):

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

    def __init__(
        self,
        config: EstimatorOptions,
        *,
        setting: EstimatorSetting,
        batch_size: int = 1,
        abstract_state: bool = False,
    ) -> None:
        super().__init__()
        if not isinstance(config, EstimatorOptions):
            raise ValueError(f"config: must be an estimator's dataclass, got {config!r}")
        if not isinstance(setting, EstimatorSetting):
            raise ValueError(f"setting: must be an EstimatorSetting, got {setting!r}")
        config.validate("estimator")
        self.batch_size = B = batch_size_field(batch_size)
        self._setting = setting
        self._time_step = float(setting.time_step)
        self._A, self._B = double_integrator(self._time_step)
        self._W = W = config.filter_acceleration_covariance(setting.acceleration_covariance)
        self._Q = process_noise_covariance(W, self._time_step)
        self._gate_probability = config.gate_probability
        self._gate_thresholds: dict[int, float] = {}
        # The gate of an update of each innovation dimension (0: none), indexed by run.
        self._gate_table = np.array([self.gate_threshold(dof) for dof in range(3)])
        self._gate_table[0] = math.inf
        self._f = setting.samples_per_step
        self._b = setting.baseline_B
        x0 = np.asarray(config.initial_estimate, dtype=float)
        P0 = np.asarray(config.initial_covariance, dtype=float)
        self._initial = Estimate(x0, P0)
        self._declare_published(abstract_state)
        self._x_index = self.DeclareDiscreteState(tiled(x0, B))
        self._P_index = self.DeclareDiscreteState(tiled(P0, B))

        self._samples_port = self.DeclareVectorInputPort("range_samples", B * 2 * self._f)
        self._status_port = self.DeclareVectorInputPort("sonar_status", B * 2)
        self._attitude_port = self.DeclareVectorInputPort("R_WB_nav", B * 9)
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
        # Σ_θ (B, 3, 3) at the tick's navigated attitudes (None without attitude noise),
        # computed once a tick: the ranges, the process noise and the published floor use it.
        self._sigma_theta = self.DeclareCacheEntry(
            "attitude noise covariance",
            ValueProducer(allocate=AbstractValue.Make(np.eye(3)).Clone, calc=self._calc_sigma),
            {self._attitude_port.ticket()},
        )
        # This tick's ranges, read by the update and again by a variant's periodic update.
        empty_ranges = Ranges(*(np.zeros(0),) * 5)
        self._ranges_entry = self.DeclareCacheEntry(
            "ranges",
            ValueProducer(
                allocate=AbstractValue.Make(empty_ranges).Clone,
                calc=lambda context, value: value.set_value(self._read_ranges(context)),
            ),
            self._tickets([self._samples_port, self._status_port, self._attitude_port]),
        )
        self._window = self._declare_window(navigated)
        empty = FilteredEstimate(
            np.zeros((B, 6)), np.zeros((B, 6, 6)), np.zeros(B), np.full(B, np.nan)
        )
        self._filtered = self.DeclareCacheEntry(
            "filtered estimate",
            ValueProducer(allocate=AbstractValue.Make(empty).Clone, calc=self._calc_filtered),
            self.depends_on_measurement(),
        )
        self._declare_outputs()
        self._declare_update(self._update)

    # ------------------------------------------------------------------ hooks for a variant

    def measurement_update(
        self, context: Context, prior: Estimate, ranges: Ranges
    ) -> MeasurementUpdate | None:
        """The posteriors of the runs with ranges to use (``updated``), or None if none has."""
        raise NotImplementedError(f"{type(self).__name__} must define measurement_update")

    def advance(
        self, context: Context, filtered: FilteredEstimate, discrete_state: DiscreteValues
    ) -> None:
        """The periodic update at the tick: writes the prediction of ``filtered``.

        ``filtered`` is this step's filtered estimate (``filtered.applied``: the runs whose
        update was applied). Override it to advance state of your own; call
        ``super().advance`` (or :meth:`write_prediction`) for groups 0 and 1. With late ranges
        the state is the belief at the window's anchor instead, moved one step on
        (:meth:`~drake_uuv.estimators.late_ranges.LateRanges.anchor_advance`).
        """
        if self._window is None:
            prediction = self.predicted(context, filtered.x, filtered.P)
            self.write_prediction(discrete_state, *prediction)
            return
        outcome = self.anchor_advance(context)
        if outcome is not None:
            self.write_prediction(discrete_state, outcome.x, outcome.P)

    def advance_state(self, context: Context, filtered: FilteredEstimate, state: State) -> None:
        """The periodic update of a variant that declares abstract state (``abstract_state``):
        the default is :meth:`advance` on the discrete state; override it to write the
        abstract state too."""
        self.advance(context, filtered, state.get_mutable_discrete_state())

    def filtered_estimate(self, context: Context) -> FilteredEstimate | None:
        """A variant's own filtered estimate of this tick, or None for the base's (the
        measurement update of the prior). The particles with late ranges use it."""
        return None

    def needs_both_ranges(self, context: Context) -> np.ndarray | bool:
        """Per run (B) or for all, whether this step's update needs both ranges at one
        instant (the paper's ``Y``): then, with the pings at different times, the earlier
        range is carried to the later ping time. The default: no."""
        return False

    def step_belief(self, context: Context, x: np.ndarray, P: np.ndarray, step) -> StepOutcome:
        """The beliefs ``N(x, P)`` ((B, 6), (B, 6, 6)) at a window step's tick (stored frame),
        stepped through the step's arrived ranges at their ping times to the next tick
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
        """``Υ̂(0|−1)`` (6) and ``P(0|−1)`` (6×6) of the config, each run's."""
        return self._initial

    def prior(self, context: Context) -> Estimate:
        """This step's predictions ``Υ̂(k|k−1)`` (B, 6), ``P(k|k−1)`` (B, 6, 6) (relative
        state): with late ranges, the anchor stepped through the window with every range
        arrived by now."""
        if self._window is not None:
            x, P, _ = self._stepped.Eval(context)
            return Estimate(self.vehicle_motion.prior(context, x), P)
        anchor = self.anchor(context)
        return Estimate(self.vehicle_motion.prior(context, anchor.x), anchor.P)

    def anchor(self, context: Context) -> Estimate:
        """The stored beliefs (the predictions, or the window's anchor), stored frame:
        (B, 6), (B, 6, 6), views of the state."""
        B = self.batch_size
        x = per_run(context.get_discrete_state(self._x_index).get_value(), B)
        P = per_run(context.get_discrete_state(self._P_index).get_value(), B, 6, 6)
        return Estimate(x, P)

    def set_prior(self, context: Context, x: np.ndarray, P: np.ndarray) -> None:
        """Sets this step's predictions ``Υ̂(k|k−1)`` ((B, 6); (6) for every run) and
        ``P(k|k−1)`` ((B, 6, 6) or (6, 6)) in ``context`` (e.g. to start a test or a run from a
        chosen prior); the vehicle inputs must be connected or fixed with
        ``vehicle_motion: navigation``."""
        B = self.batch_size
        x = np.broadcast_to(np.asarray(x, dtype=float), (B, 6))
        P = np.broadcast_to(np.asarray(P, dtype=float), (B, 6, 6))
        stored = x - self.vehicle_motion.offset(context)
        context.SetDiscreteState(self._x_index, stored.ravel())
        context.SetDiscreteState(self._P_index, P.ravel())

    def ranges(self, context: Context) -> Ranges:
        """This tick's ranges of every run, their means, the world baselines and the error
        model's noise (:class:`~drake_uuv.estimators.contract.Ranges`).

        With late ranges, only those of this tick's own pings (at the tick, no latency); the
        others are the window's."""
        if self._window is None:
            return self._ranges_entry.Eval(context)
        return self._read_ranges(context)

    def _read_ranges(self, context: Context) -> Ranges:
        B, f = self.batch_size, self._f
        samples = per_run(self._samples_port.Eval(context), B, 2, f)
        status = per_run(self._status_port.Eval(context), B)
        if self._window is not None:
            _, current = self._window.steps(context, samples, status)
            samples = np.where(current[:, :, np.newaxis], samples, np.nan)
            status = np.where(current, status, NO_ARRIVAL)
        valid = (status == VALID) & np.isfinite(samples).all(axis=2)
        R_WB = per_run(self._attitude_port.Eval(context), B, 3, 3)
        q_s = (R_WB * self._b).sum(axis=2)
        z = samples.sum(axis=2) / f  # samples.mean(axis=2)'s arithmetic, without its wrapper
        if not self._model_active:
            return Ranges(samples, z, valid, status, q_s)
        sigma_theta, sound = self._sigma_theta.Eval(context), self._error_model.range_variance(z)
        return Ranges(samples, z, valid, status, q_s, sigma_theta, sound)

    def filtered(self, context: Context) -> FilteredEstimate:
        """This step's filtered estimates (the cache entry behind ``x_TU_hat`` and ``P_TU``):
        ``x`` (B, 6), ``P`` and ``published_P`` (B, 6, 6), ``status`` and ``nis`` (B)."""
        return self._filtered.Eval(context)

    def predicted(
        self, context: Context, x: np.ndarray, P: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """``(A (x − offset) + B acceleration, A P Aᵀ + Q)``: the predictions of relative
        estimates (B, 6), (B, 6, 6), in the frame the state stores (see
        :attr:`vehicle_motion`)."""
        motion = self.vehicle_motion
        extra = self.navigation_process_noise(context)
        Q = self._Q if extra is None else self._Q + extra
        return predict_runs(
            motion.stored(context, x), P, motion.acceleration(context), self._A, self._B, Q
        )

    def navigation_process_noise(self, context: Context) -> np.ndarray | None:
        """What the modelled navigation errors add to the step's Q from this tick ((B, 6, 6);
        None when the model adds nothing):
        :meth:`~drake_uuv.estimators.error_model.ErrorModel.process_noise` at this tick's
        commanded accelerations, navigated attitudes and navigated velocities."""
        if not self._model_active:
            return None
        motion, sigma_theta = self.vehicle_motion, self._sigma_theta.Eval(context)
        return self._error_model.process_noise(
            self._time_step,
            motion.acceleration(context),
            sigma_theta,
            motion.offset(context)[:, 3:],
        )

    def _calc_sigma(self, context: Context, value: AbstractValue) -> None:
        R_WB_nav = per_run(self._attitude_port.Eval(context), self.batch_size, 3, 3)
        value.set_value(self._error_model.attitude_covariance(R_WB_nav))

    def write_prediction(
        self,
        discrete_state: DiscreteValues,
        x: np.ndarray,
        P: np.ndarray,
        runs: np.ndarray | None = None,
    ) -> None:
        """Writes the next step's predictions (groups 0 and 1), ``x`` (B, 6) in the stored
        frame and ``P`` (B, 6, 6): of every run, or of those in the mask ``runs`` (B) only."""
        if runs is None:
            discrete_state.set_value(self._x_index, np.asarray(x).ravel())
            discrete_state.set_value(self._P_index, np.asarray(P).ravel())
            return
        B = self.batch_size
        x_state = per_run(discrete_state.get_mutable_value(self._x_index), B)
        P_state = per_run(discrete_state.get_mutable_value(self._P_index), B, 6, 6)
        x_state[runs] = np.reshape(x, (B, 6))[runs]
        P_state[runs] = np.reshape(P, (B, 6, 6))[runs]

    def depends_on_measurement(self) -> set:
        """Tickets of the step's ranges, prior and discrete state (not of ``u1_W``)."""
        ports = [
            self._samples_port, self._status_port, self._attitude_port,
            *self.vehicle_motion.state_ports,
            *(self._window.input_ports if self._window is not None else []),
        ]  # fmt: skip
        tickets = self._tickets(ports) | {self.xd_ticket()}
        return tickets | {self.xa_ticket()} if self._abstract else tickets

    def gate_thresholds(self, dof: np.ndarray) -> np.ndarray:
        """Each run's gate (B) for its update's innovation dimension ``dof`` (B; 0: none)."""
        return self._gate_table[dof]

    def gate_threshold(self, dof: int) -> float:
        """The NIS above which an update is rejected (``inf`` without a gate)."""
        if self._gate_probability is None or dof == 0:
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
        x0 = per_run(context.get_discrete_state(self._x_index).get_value(), self.batch_size)
        stored = x0 - self.vehicle_motion.offset(context)
        discrete_state.set_value(self._x_index, stored.ravel())

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
        """``Σ_ev`` (B, 3, 3) of the navigated velocity at this tick (navigated motion only)."""
        if not self._error_model.navigated_motion:
            return None
        return self._error_model.velocity_covariance(
            self.vehicle_motion.offset(context)[:, 3:], self._sigma_theta.Eval(context)
        )

    def _filtered_by_update(self, context: Context) -> FilteredEstimate:
        prior = self.prior(context)
        ranges = self.ranges(context)
        update = self.measurement_update(context, prior, ranges)
        estimate = self.gated(prior, update, self._no_update(ranges))
        if self._window is not None:
            self._with_window_updates(context, estimate, update)
        return estimate

    def gated(
        self, prior: Estimate, update: MeasurementUpdate | None, no_update: np.ndarray
    ) -> FilteredEstimate:
        """The filtered estimates of a step from its ``prior``, the variant's ``update`` and
        the status ``no_update`` (B) of a run without one: a run updated with a NIS above its
        gate keeps its prior (status GATED), a run not updated keeps it with ``no_update``."""
        if update is None:  # no innovation: NaN NIS, none counted
            none = np.zeros(len(prior.x))
            x, P = prior.x.copy(), prior.P.copy()
            return FilteredEstimate(x, P, no_update, none + np.nan, None, none, none)
        updated = update.updated
        gated = updated & (update.nis > self._gate_table[update.dof])
        accept = updated & ~gated
        if gated.any():
            x = np.where(accept[:, np.newaxis], update.x, prior.x)
            P = np.where(accept[:, np.newaxis, np.newaxis], update.P, prior.P)
        else:  # a run not updated holds its prior in the update already
            x, P = update.x, update.P
        status = np.where(accept, float(VALID), np.where(gated, float(GATED), no_update))
        nis = np.where(updated, update.nis, np.nan)
        counted = np.where(updated, update.nis, 0.0), np.where(updated, update.dof, 0.0)
        return FilteredEstimate(x, P, status, nis, None, *counted)

    @staticmethod
    def _no_update(ranges: Ranges) -> np.ndarray:
        """Each run's status without an update: the first sonar's code that is not VALID."""
        first = ranges.status[:, 0]
        return np.where(first != VALID, first, ranges.status[:, 1])

    def _update(self, context: Context, discrete_state: DiscreteValues) -> None:
        self.advance(context, self._filtered.Eval(context), discrete_state)
        if self._window is not None:
            self._record_window(context, discrete_state)
