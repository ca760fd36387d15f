"""An attitude generator that turns the sonar baseline toward what the filter knows least."""

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import (
    BasicVector,
    Context,
    DiscreteValues,
    LeafSystem,
    ValueProducer,
)

from drake_uuv.models.information import InformationSeekingPlanner, PlanStep
from drake_uuv.scenario import Scenario


class InformationSeekingAttitude(LeafSystem):
    """``u2(k) = Log(R(k+1) R(k)ᵀ) / t`` with ``R(k+1)`` chosen by an information criterion.

    Each step the :class:`~drake_uuv.models.information.InformationSeekingPlanner` scores the
    candidate attitudes within its rotation budget by the information the next measurement(s)
    would give the estimator, under the excitation floor and the optional reference limit,
    and this system commands the best one: ``R(k+1) = Exp(u2_W t) R(k)`` exactly (the plant's
    eq. 2, ``u2`` a world-frame rate). It is a pure function of its inputs and its discrete
    state, so a run is reproducible without any random input.

    Which estimate it reads, and why: the *filtered* ``x̂(k|k)``, ``P(k|k)`` (``x_TU_hat``,
    ``P_TU``). The attitude chosen at step k sets the measurement of step k+1, whose prior is
    ``P(k+1|k) = A P(k|k) Aᵀ + Q``; the filtered estimate already holds step k's measurement,
    which the prediction ``x_TU_prior``/``P_TU_prior`` (``P(k|k−1)``) lacks. Reading it makes no
    algebraic loop: the estimator computes its filtered outputs from the sonar and its own
    state, never from the applied acceleration ``u1_W``, and this system reads neither
    ``u1_W`` nor anything computed from it (the LQR tracking law reads ``R_WB_plan`` and
    produces ``u1_W``; a planner reading ``u1_W`` would close the loop through it). The
    planner's covariance propagation needs no control at all; where the planned-for model
    needs a relative position it assumes one without ``u1_W`` (see ``position_prediction`` in
    :mod:`drake_uuv.models.information`). Only ports are read, never the estimator itself.

    The plan ``R_WB_plan`` holds ``R(k+1)`` (exact) and a prediction of ``R(k+2)``: the
    planner run once more from ``R(k+1)``, the planner's own ``P(k+1|k+1)`` and the history
    with ``q_s(k)`` appended. For the paper's KF that covariance is exact up to ``Γ`` (which
    the filter computes from the measured rather than the predicted ranges), so the
    prediction is usually the next step's choice.

    Sonar beam: the pan-tilt sonars (``sonar.beam_half_angle_deg``) point at the estimator's
    predicted target whatever the attitude, so the attitude does not decide visibility; it
    only moves each sonar by ``±½ q_s`` about the body origin, which changes the pointing error
    ``|q − q̂(k|k−1)|`` seen from a sonar by the ratio of the ranges (at most
    ``(|q| + ½|b|)/(|q| − ½|b|)``, 1.7 at the paper's ``|q*| = 2.8 m``). No attitude constraint
    is needed for the beam.

    Discrete state, updated at the tick: group 0, the world baselines ``q_s`` of the last
    ``N − 2`` steps up to k (oldest first, ``N = pe_window``) followed by how many are filled;
    group 1, ``R(k)`` row-major followed by 1 once it is set (``R(k−1)`` for the next step's
    reference limit); group 2, 1 once a raw-range estimator has left its linear start (the
    planner's mirror of its hand-over, from ``P_TU``; the hand-over is one-way).

    .. pydrake_system::

        name: InformationSeekingAttitude
        input_ports:
        - R_WB
        - x_TU_hat
        - P_TU
        output_ports:
        - u2_W
        - R_WB_plan

    - ``R_WB`` (9, row-major): the current attitude ``R(k)``.
    - ``x_TU_hat`` (6): the filtered relative state ``[q̂, ϑ̂]`` at k (world frame,
      ``q = p_WU − p_WT``).
    - ``P_TU`` (36): its covariance ``P(k|k)``, row-major.
    - ``u2_W`` (3): the angular velocity command [rad/s], world frame.
    - ``R_WB_plan`` (18): the planned ``R(k+1)`` and ``R(k+2)``, each row-major.
    """

    def __init__(self, planner: InformationSeekingPlanner) -> None:
        super().__init__()
        if not isinstance(planner, InformationSeekingPlanner):
            raise ValueError(f"planner: must be an InformationSeekingPlanner, got {planner!r}")
        self._planner = planner
        self._time_step = planner.time_step
        self._history = planner.history_length
        self._attitude_port = self.DeclareVectorInputPort("R_WB", 9)
        self._estimate_port = self.DeclareVectorInputPort("x_TU_hat", 6)
        self._covariance_port = self.DeclareVectorInputPort("P_TU", 36)
        self._history_index = self.DeclareDiscreteState(3 * self._history + 1)
        self._previous_index = self.DeclareDiscreteState(10)
        self._handed_over_index = self.DeclareDiscreteState(1)
        self._step = self.DeclareCacheEntry(
            "plan of step k",
            ValueProducer(allocate=AbstractValue.Make(object()).Clone, calc=self._calc_step),
            {self.all_input_ports_ticket(), self.xd_ticket()},
        )
        self._next_step = self.DeclareCacheEntry(
            "plan of step k+1",
            ValueProducer(allocate=AbstractValue.Make(object()).Clone, calc=self._calc_next),
            {self._step.ticket(), self.all_input_ports_ticket(), self.xd_ticket()},
        )
        self.DeclareVectorOutputPort("u2_W", 3, self._calc_rate, {self._step.ticket()})
        self.DeclareVectorOutputPort(
            "R_WB_plan", 18, self._calc_plan, {self._step.ticket(), self._next_step.ticket()}
        )
        self.DeclarePeriodicDiscreteUpdateEvent(self._time_step, 0.0, self._update)

    @classmethod
    def from_scenario(cls, scenario: Scenario) -> "InformationSeekingAttitude":
        """The planner of ``scenario.attitude`` (an :class:`~drake_uuv.scenario.
        InformationSeeking`), planning for the scenario's estimator and tracking law.

        The measurement it scores is the estimator's (``planning_model()``: the paper's Y
        for ``!PaperKf``, the raw ranges for the others), and it mirrors a raw-range filter's
        linear start (``linear_start_position_variance``, unless ``linear_start_max_steps``
        is 0). The turning reference ``R q*`` is q* in the body frame (the paper's): with q*
        fixed in the world or the heading there is none, and ``auto`` assumes a held
        position; it lags the attitude by a step unless the LQR law feeds the plan forward.
        """
        a, e, tracking = scenario.attitude, scenario.estimator, scenario.tracking
        model = e.planning_model()
        measurement = model.measurement.value
        body_reference = tracking.reference_frame == "body"
        prediction = a.position_prediction
        if prediction == "auto":
            prediction = "reference" if measurement == "ranges" and body_reference else "hold"
        linear_start = model.linear_start_position_variance
        planner = InformationSeekingPlanner(
            scenario.time_step,
            np.asarray(scenario.sonar.baseline),
            np.asarray(scenario.target.acceleration_covariance),
            np.asarray(scenario.sonar.noise_variances),
            scenario.sonar.samples_per_step,
            measurement_model=measurement,
            criterion=a.criterion,
            block=a.block,
            horizon=a.horizon,
            max_angle_per_step=a.max_angle_per_step,
            pe_window=scenario.analysis.pe_window,
            excitation_floor=a.excitation_floor,
            pe_lead=a.pe_lead,
            desired_relative_position=(
                np.asarray(tracking.desired_relative_position) if body_reference else None
            ),
            max_reference_acceleration=a.max_reference_acceleration if body_reference else None,
            position_prediction=prediction,
            reference_lag=0 if getattr(tracking, "feedforward", False) else 1,
            linear_start_position_variance=linear_start,
        )
        return cls(planner)

    @property
    def planner(self) -> InformationSeekingPlanner:
        return self._planner

    def history_state_index(self) -> int:
        """The discrete-state group of the baseline history (see the class notes)."""
        return self._history_index

    def previous_attitude_state_index(self) -> int:
        """The discrete-state group ``[R(k) row-major, set]``."""
        return self._previous_index

    def handed_over_state_index(self) -> int:
        """The discrete-state group ``[1 once the raw-range filter left its linear start]``."""
        return self._handed_over_index

    def _linear_start(self, context: Context, P: np.ndarray) -> bool:
        """Whether the estimator's update at k+1 is still its linear start's (mirrored)."""
        if context.get_discrete_state(self._handed_over_index).get_value()[0] > 0.0:
            return False
        return not self._planner.hands_over(P)

    def _stored(self, context: Context) -> tuple[np.ndarray, np.ndarray | None]:
        """``(previous baselines (m×3, oldest first), R(k−1) or None)`` from the state."""
        state = context.get_discrete_state(self._history_index).get_value()
        filled = int(state[-1])
        history = state[:-1].reshape(self._history, 3)[self._history - filled :]
        previous = context.get_discrete_state(self._previous_index).get_value()
        return history, (previous[:9].reshape(3, 3) if previous[9] > 0.0 else None)

    def _inputs(self, context: Context) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        R_WB = self._attitude_port.Eval(context).reshape(3, 3)
        x_hat = self._estimate_port.Eval(context)
        P = self._covariance_port.Eval(context).reshape(6, 6)
        return R_WB, x_hat, P

    def _calc_step(self, context: Context, value: AbstractValue) -> None:
        R_WB, x_hat, P = self._inputs(context)
        history, R_previous = self._stored(context)
        linear = self._linear_start(context, P)
        value.set_value(self._planner.plan(x_hat, P, R_WB, history, R_previous, linear))

    def _calc_next(self, context: Context, value: AbstractValue) -> None:
        step: PlanStep = self._step.Eval(context)
        R_WB, x_hat, _ = self._inputs(context)
        history, _ = self._stored(context)
        history = np.vstack([history, R_WB @ self._planner.baseline_B])[-self._history :]
        if self._planner.position_prediction == "coast":
            x_hat = self._planner.A @ x_hat
        linear = self._linear_start(context, step.P_next) and self._linear_start(
            context, self._inputs(context)[2]
        )
        value.set_value(self._planner.plan(x_hat, step.P_next, step.R_next, history, R_WB, linear))

    def _calc_rate(self, context: Context, output: BasicVector) -> None:
        step: PlanStep = self._step.Eval(context)
        output.set_value(step.rotation_vector / self._time_step)

    def _calc_plan(self, context: Context, output: BasicVector) -> None:
        R_next = self._step.Eval(context).R_next
        R_after = self._next_step.Eval(context).R_next
        output.set_value(np.concatenate([R_next.ravel(), R_after.ravel()]))

    def _update(self, context: Context, discrete_state: DiscreteValues) -> None:
        R_WB = self._attitude_port.Eval(context).reshape(3, 3)
        state = context.get_discrete_state(self._history_index).get_value()
        history = np.concatenate([state[3:-1], R_WB @ self._planner.baseline_B])
        filled = min(int(state[-1]) + 1, self._history)
        discrete_state.set_value(self._history_index, np.append(history, filled))
        discrete_state.set_value(self._previous_index, np.append(R_WB.ravel(), 1.0))
        P = self._covariance_port.Eval(context).reshape(6, 6)
        discrete_state.set_value(
            self._handed_over_index, [0.0 if self._linear_start(context, P) else 1.0]
        )
