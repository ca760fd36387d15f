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

from drake_uuv.attitude.base import AttitudeSetting
from drake_uuv.models.information import PlannedMeasurement
from drake_uuv.models.information_planner import InformationSeekingPlanner, PlanSteps
from drake_uuv.primitives.batch import batch_size_field, per_run
from drake_uuv.scenario.attitude import InformationSeeking


class InformationSeekingAttitude(LeafSystem):
    """``u2(k) = Log(R(k+1) R(k)ᵀ) / t`` with ``R(k+1)`` chosen by an information criterion.

    Each step the :class:`~drake_uuv.models.information_planner.InformationSeekingPlanner`
    (:attr:`planner`) scores the
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
    :mod:`drake_uuv.models.information_planner`). Only ports are read, never the estimator
    itself.

    The plan ``R_WB_plan`` holds ``R(k+1)`` (exact) and a prediction of ``R(k+2)``: the
    planner run once more from ``R(k+1)``, the planner's own ``P(k+1|k+1)`` and the history
    with ``q_s(k)`` appended. For the paper's KF that covariance is exact up to ``Γ`` (which
    the filter computes from the measured rather than the predicted ranges), so the
    prediction is usually the next step's choice. Both plans of every run come from one call
    (:meth:`~drake_uuv.models.information_planner.InformationSeekingPlanner.plan_pair_runs`),
    cached for the step (:meth:`plans`).

    Sonar beam: the pan-tilt sonars (``sonar.beam_half_angle_deg``) point at the estimator's
    predicted target whatever the attitude, so the attitude does not decide visibility; it
    only moves each sonar by ``±½ q_s`` about the body origin, which changes the pointing error
    ``|q − q̂(k|k−1)|`` seen from a sonar by the ratio of the ranges (at most
    ``(|q| + ½|b|)/(|q| − ½|b|)``, 1.7 at the paper's ``|q*| = 2.8 m``). No attitude constraint
    is needed for the beam.

    Discrete state, updated at the tick: group 0, the world baselines ``q_s`` of the last
    ``N − 2`` steps up to k (oldest first, ``N = excitation_window``) followed by how many are
    filled;
    group 1, ``R(k)`` row-major followed by 1 once it is set (``R(k−1)`` for the next step's
    reference limit); group 2, 1 once a raw-range estimator has left its linear start (the
    planner's mirror of its hand-over, from ``P_TU``; the hand-over is one-way).

    Sizes are per run: with ``batch_size`` B every port and state group holds B runs
    row-major (:mod:`drake_uuv.primitives.batch`). Each run is planned on its own
    (:meth:`~drake_uuv.models.information_planner.InformationSeekingPlanner.plan_runs`): its
    candidates, scores, floor, reference limit and linear start, whatever the other runs do.

    .. pydrake_system::

        name: InformationSeekingAttitude
        input_ports:
        - R_WB_nav
        - x_TU_hat
        - P_TU
        output_ports:
        - u2_W
        - R_WB_plan

    - ``R_WB_nav`` (9, row-major): the current attitude ``R(k)``, as the navigation knows it.
    - ``x_TU_hat`` (6): the filtered relative state ``[q̂, ϑ̂]`` at k (world frame,
      ``q = p_WU − p_WT``).
    - ``P_TU`` (36): its covariance ``P(k|k)``, row-major.
    - ``u2_W`` (3): the angular velocity command [rad/s], world frame.
    - ``R_WB_plan`` (18): the planned ``R(k+1)`` and ``R(k+2)``, each row-major.

    ``config`` (:class:`~drake_uuv.scenario.InformationSeeking`) gives the criterion, the
    budget, the horizon, the excitation floor and the reference limit. The ``setting`` gives
    the period, the sonars and the target's W, and what is planned for: the estimator's
    measurement (the paper's ``Y`` for its KF, the raw ranges after a linear start the
    planner mirrors for the others) and the tracking law's reference, ``R q*`` with q* in
    the body frame (with q* fixed in the world or the heading there is none, and the
    reference limit is off), lagging the attitude by a step unless the law feeds the plan
    forward. ``position_prediction: auto`` plans at the reference for a raw-range estimator
    tracking a body-frame q*, at the held position otherwise.
    """

    def __init__(
        self, config: InformationSeeking, *, setting: AttitudeSetting, batch_size: int = 1
    ) -> None:
        super().__init__()
        planner = information_planner(config, setting)
        self.batch_size = B = batch_size_field(batch_size)
        self._planner = planner
        self._time_step = planner.time_step
        self._history = planner.history_length
        self._attitude_port = self.DeclareVectorInputPort("R_WB_nav", 9 * B)
        self._estimate_port = self.DeclareVectorInputPort("x_TU_hat", 6 * B)
        self._covariance_port = self.DeclareVectorInputPort("P_TU", 36 * B)
        self._history_index = self.DeclareDiscreteState(B * (3 * self._history + 1))
        self._previous_index = self.DeclareDiscreteState(B * 10)
        self._handed_over_index = self.DeclareDiscreteState(B)
        self._plans = self.DeclareCacheEntry(
            "plans of steps k and k+1",
            ValueProducer(allocate=AbstractValue.Make(object()).Clone, calc=self._calc_plans),
            {self.all_input_ports_ticket(), self.xd_ticket()},
        )
        self.DeclareVectorOutputPort("u2_W", 3 * B, self._calc_rate, {self._plans.ticket()})
        self.DeclareVectorOutputPort("R_WB_plan", 18 * B, self._calc_plan, {self._plans.ticket()})
        self.DeclarePeriodicDiscreteUpdateEvent(self._time_step, 0.0, self._update)

    @property
    def planner(self) -> InformationSeekingPlanner:
        return self._planner

    def _linear_start(self, context: Context, P: np.ndarray) -> np.ndarray:
        """Per run (``P`` (B, 6, 6)): whether the estimator's update at k+1 is still its linear
        start's (mirrored), as 1.0 or 0.0."""
        handed_over = context.get_discrete_state(self._handed_over_index).get_value() > 0.0
        return (~handed_over & ~self._planner.hands_over_runs(P)).astype(float)

    def _stored(self, context: Context) -> tuple[np.ndarray, ...]:
        """``(history (B, N − 2, 3), filled (B), R(k−1) (B, 3, 3), R(k−1) set (B))`` from the
        state: each run's last ``filled`` baselines are its known ones (oldest first)."""
        B = self.batch_size
        state = per_run(context.get_discrete_state(self._history_index).get_value(), B)
        previous = per_run(context.get_discrete_state(self._previous_index).get_value(), B)
        history = state[:, :-1].reshape(B, self._history, 3)
        return history, state[:, -1], previous[:, :9], previous[:, 9]

    def _inputs(self, context: Context) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        B = self.batch_size
        R_WB = per_run(self._attitude_port.Eval(context), B, 3, 3)
        x_hat = per_run(self._estimate_port.Eval(context), B)
        P = per_run(self._covariance_port.Eval(context), B, 6, 6)
        return R_WB, x_hat, P

    def _baselines(self, R_WB: np.ndarray) -> np.ndarray:
        """Each run's world baseline ``R b`` (B, 3), summed in index order."""
        b = self._planner.baseline_B
        return R_WB[:, :, 0] * b[0] + R_WB[:, :, 1] * b[1] + R_WB[:, :, 2] * b[2]

    def plans(self, context: Context) -> tuple[PlanSteps, PlanSteps]:
        """Each run's plan of step k (the command) and of step k+1 (the plan's ``R(k+2)``)."""
        return self._plans.Eval(context)

    def _calc_plans(self, context: Context, value: AbstractValue) -> None:
        R_WB, x_hat, P = self._inputs(context)
        history, filled, R_previous, has_previous = self._stored(context)
        linear = self._linear_start(context, P)
        value.set_value(
            self._planner.plan_pair_runs(
                x_hat, P, R_WB, history, filled, R_previous, has_previous, linear
            )
        )

    def _calc_rate(self, context: Context, output: BasicVector) -> None:
        step = self.plans(context)[0]
        output.set_value((step.rotation_vector / self._time_step).ravel())

    def _calc_plan(self, context: Context, output: BasicVector) -> None:
        B = self.batch_size
        step, following = self.plans(context)
        plan = np.concatenate([step.R_next.reshape(B, 9), following.R_next.reshape(B, 9)], 1)
        output.set_value(plan.ravel())

    def _update(self, context: Context, discrete_state: DiscreteValues) -> None:
        B = self.batch_size
        R_WB, _, P = self._inputs(context)
        state = per_run(context.get_discrete_state(self._history_index).get_value(), B)
        filled = np.minimum(state[:, -1:] + 1.0, self._history)
        history = np.concatenate([state[:, 3:-1], self._baselines(R_WB), filled], axis=1)
        discrete_state.set_value(self._history_index, history.ravel())
        previous = np.concatenate([R_WB.reshape(B, 9), np.ones((B, 1))], axis=1)
        discrete_state.set_value(self._previous_index, previous.ravel())
        discrete_state.set_value(self._handed_over_index, 1.0 - self._linear_start(context, P))


def information_planner(
    config: InformationSeeking, setting: AttitudeSetting
) -> InformationSeekingPlanner:
    """The planner of ``config`` for the estimator and the tracking law of ``setting``."""
    body_q_star = setting.tracking.desired_relative_position_B
    ranges = setting.estimator.measurement == PlannedMeasurement.RANGES
    prediction = config.position_prediction
    if prediction == "auto":
        prediction = "reference" if ranges and body_q_star is not None else "hold"
    return InformationSeekingPlanner(
        setting.time_step,
        setting.baseline_B,
        setting.acceleration_covariance,
        setting.noise_variances,
        setting.samples_per_step,
        measurement_model=setting.estimator.measurement.value,
        criterion=config.criterion,
        block=config.block,
        horizon=config.horizon,
        max_angle_per_step=config.max_angle_per_step,
        pe_window=config.excitation_window,
        excitation_floor=config.excitation_floor,
        pe_lead=config.pe_lead,
        desired_relative_position=None if body_q_star is None else np.asarray(body_q_star),
        max_reference_acceleration=(
            None if body_q_star is None else config.max_reference_acceleration
        ),
        position_prediction=prediction,
        reference_lag=setting.tracking.reference_lag,
        linear_start_position_variance=setting.estimator.linear_start_position_variance,
    )
