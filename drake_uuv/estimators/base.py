"""What every relative-state estimator shares: prediction, gating, ports and status codes."""

import math
from dataclasses import dataclass

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

from drake_uuv.models.filters import predict
from drake_uuv.models.measurement import GATED, VALID
from drake_uuv.models.motion import double_integrator, process_noise_covariance
from drake_uuv.models.statistics import chi2_ppf

#: How the filter accounts for the vehicle's own motion (see RelativeStateEstimator).
VEHICLE_MOTIONS = ("commanded", "navigation")
_ZERO3 = np.zeros(3)


@dataclass
class MeasurementUpdate:
    """A subclass's proposed update: the posterior and its innovation statistic."""

    x: np.ndarray
    P: np.ndarray
    nis: float  # normalised innovation squared νᵀ S⁻¹ ν
    dof: int  # dimension of the innovation


@dataclass
class FilteredEstimate:
    """``Υ̂(k|k)``, ``P(k|k)``, the step's measurement status and NIS (NaN: no update)."""

    x: np.ndarray
    P: np.ndarray
    status: int = VALID
    nis: float = math.nan


class RelativeStateEstimator(LeafSystem):
    """Base of the estimators of ``Υ = [q, ϑ]``; subclasses supply the measurement update.

    Discrete state: the *predicted* ``Υ̂(k|k−1)`` (group 0) and ``P(k|k−1)`` (group 1), and
    any groups a subclass declares and advances in :meth:`advance_extra_state`. The
    filtered estimate of step k is a direct-feedthrough output of the measurement inputs only
    (never of ``u1_W``), so the controller acts on ``Υ̂(k|k)`` in the same tick as in the
    paper, and the periodic update predicts ``P(k+1|k) = A P Aᵀ + B W Bᵀ`` and, with
    ``vehicle_motion``:

    - ``"commanded"`` (the paper's): ``Υ̂(k+1|k) = A Υ̂(k|k) + B a_W(k)`` with ``a_W = R u1``
      the vehicle's commanded world acceleration (port ``u1_W``): exact for the paper's
      kinematic vehicle, which moves exactly as commanded.
    - ``"navigation"``: the vehicle's own state ``X = [p_WU, v_WU]`` is known (ports ``p_WU``,
      ``v_WU``: the paper assumes it known; a real vehicle has its navigation), so the filter
      predicts the target, ``X̄(k+1|k) = A X̄(k|k)`` with ``X̄(k|k) = X(k) − Υ̂(k|k)``, and
      ``Υ̂(k+1|k) = X(k+1) − X̄(k+1|k)``: exact for any vehicle, whatever it did of its
      commands, with the same model (the target's double integrator) and the same P. Group 0
      then holds ``−X̄(k+1|k)``; the prior is that plus ``X`` at the step.

    Steps without a usable measurement (a sonar status other than VALID, as the subclass
    decides) only predict. With ``gate_probability`` set, an update whose NIS exceeds the χ²
    quantile of that probability (for its innovation dimension) is rejected (status GATED).

    Common ports, after the subclass's measurement inputs:

    - input ``sonar_status`` (2): the sonar's per-sonar return status.
    - input ``u1_W`` (3): the vehicle's applied world acceleration ``R u1`` at step k
      (``vehicle_motion="commanded"``), or inputs ``p_WU``, ``v_WU`` (3 each), the vehicle's
      state (``"navigation"``).
    - output ``x_TU_hat`` (6): filtered ``Υ̂(k|k) = [q̂, ϑ̂]`` with ``q = p_WU − p_WT`` (the
      vehicle's position from the target, world frame) and ``ϑ = v_WU − v_WT``.
    - output ``P_TU`` (36): ``P(k|k)`` row-major.
    - outputs ``x_TU_prior`` (6), ``P_TU_prior`` (36): ``Υ̂(k|k−1)`` and ``P(k|k−1)`` (of the
      state, and of the vehicle's state with ``"navigation"``, so the sonar may point at the
      prediction without an algebraic loop).
    - output ``measurement_status`` (1): VALID, DROPPED, OUT_OF_BEAM, OUT_OF_RANGE or GATED.
    - output ``nis`` (1): the update's normalised innovation squared (NaN when none).
    """

    def __init__(
        self,
        time_step: float,
        acceleration_covariance: np.ndarray,
        initial_estimate: np.ndarray,
        initial_covariance: np.ndarray,
        gate_probability: float | None = None,
        vehicle_motion: str = "commanded",
    ) -> None:
        super().__init__()
        if vehicle_motion not in VEHICLE_MOTIONS:
            options = ", ".join(VEHICLE_MOTIONS)
            raise ValueError(f"vehicle_motion: must be one of {options}, got {vehicle_motion!r}")
        self._navigation = vehicle_motion == "navigation"
        self._A, self._B = double_integrator(time_step)
        self._Q = process_noise_covariance(acceleration_covariance, time_step)
        self._gate_probability = gate_probability
        self._gate_thresholds: dict[int, float] = {}
        self._x_index = self.DeclareDiscreteState(np.asarray(initial_estimate, dtype=float))
        self._P_index = self.DeclareDiscreteState(np.asarray(initial_covariance, float).ravel())
        self._time_step = float(time_step)

    def _declare_common_ports(self, measurement_ports: list[InputPort]) -> None:
        """Call at the end of a subclass ``__init__``, after declaring its measurement inputs."""
        self._status_port = self.DeclareVectorInputPort("sonar_status", 2)
        vehicle: list[InputPort] = []
        if self._navigation:
            self._a_port = None
            vehicle = [self.DeclareVectorInputPort(name, 3) for name in ("p_WU", "v_WU")]
            self.DeclareInitializationDiscreteUpdateEvent(self._start_navigation)
        else:
            self._a_port = self.DeclareVectorInputPort("u1_W", 3)
        self._vehicle_ports = vehicle
        tickets = {port.ticket() for port in [*measurement_ports, self._status_port, *vehicle]}
        self._filtered = self.DeclareCacheEntry(
            "filtered estimate",
            ValueProducer(
                allocate=AbstractValue.Make(FilteredEstimate(np.zeros(6), np.eye(6))).Clone,
                calc=self._calc_filtered,
            ),
            tickets | {self.xd_ticket()},
        )
        depends = {self._filtered.ticket()}
        self.DeclareVectorOutputPort("x_TU_hat", 6, self._calc_x_hat, depends)
        self.DeclareVectorOutputPort("P_TU", 36, self._calc_P, depends)
        if self._navigation:
            prior_tickets = {self.xd_ticket(), *(port.ticket() for port in vehicle)}
            self.DeclareVectorOutputPort("x_TU_prior", 6, self._calc_prior, prior_tickets)
        else:
            self.DeclareStateOutputPort("x_TU_prior", self._x_index)
        self.DeclareStateOutputPort("P_TU_prior", self._P_index)
        self.DeclareVectorOutputPort("measurement_status", 1, self._calc_status, depends)
        self.DeclareVectorOutputPort("nis", 1, self._calc_nis, depends)
        self.DeclarePeriodicDiscreteUpdateEvent(self._time_step, 0.0, self._predict)

    def measurement_update(
        self, context: Context, x_prior: np.ndarray, P_prior: np.ndarray, status: np.ndarray
    ) -> MeasurementUpdate | None:
        """The posterior from this step's measurement, or None when there is none to use."""
        raise NotImplementedError

    def advance_extra_state(
        self, context: Context, filtered: FilteredEstimate, discrete_state: DiscreteValues
    ) -> None:
        """Hook for subclasses with discrete state of their own (groups after 0 and 1).

        Called at the end of the periodic update, after the prediction, with this step's
        filtered estimate (its ``status`` is VALID and its ``nis`` finite when an update was
        applied); set the next values of the subclass's groups in ``discrete_state``. The
        default does nothing (the paper's KF has no other state).
        """

    def gate_threshold(self, dof: int) -> float:
        """The NIS above which an update is rejected (``inf`` without a gate)."""
        if self._gate_probability is None:
            return math.inf
        if dof not in self._gate_thresholds:
            self._gate_thresholds[dof] = chi2_ppf(self._gate_probability, dof)
        return self._gate_thresholds[dof]

    def _vehicle_state(self, context: Context) -> np.ndarray:
        """``X = [p_WU, v_WU]`` (``vehicle_motion="navigation"`` only)."""
        p, v = (port.Eval(context) for port in self._vehicle_ports)
        return np.concatenate([p, v])

    def _prior(self, context: Context) -> np.ndarray:
        """``Υ̂(k|k−1)``: the state, plus the vehicle's state with ``"navigation"``."""
        x = context.get_discrete_state(self._x_index).get_value()
        return x + self._vehicle_state(context) if self._navigation else x

    def _start_navigation(self, context: Context, discrete_state: DiscreteValues) -> None:
        """At initialization: group 0 becomes ``Υ̂(0|−1) − X(0)``."""
        x0 = context.get_discrete_state(self._x_index).get_value()
        discrete_state.set_value(self._x_index, x0 - self._vehicle_state(context))

    def _calc_prior(self, context: Context, output: BasicVector) -> None:
        output.set_value(self._prior(context))

    def _calc_filtered(self, context: Context, value: AbstractValue) -> None:
        x_prior = self._prior(context)
        P_prior = context.get_discrete_state(self._P_index).get_value().reshape(6, 6)
        status = self._status_port.Eval(context)
        update = self.measurement_update(context, x_prior, P_prior, status)
        if update is None:
            invalid = status[status != VALID]
            code = int(invalid[0]) if invalid.size else VALID
            value.set_value(FilteredEstimate(x_prior.copy(), P_prior.copy(), code))
        elif update.nis > self.gate_threshold(update.dof):
            value.set_value(FilteredEstimate(x_prior.copy(), P_prior.copy(), GATED, update.nis))
        else:
            value.set_value(FilteredEstimate(update.x, update.P, VALID, update.nis))

    def _predict(self, context: Context, discrete_state: DiscreteValues) -> None:
        filtered: FilteredEstimate = self._filtered.Eval(context)
        if self._navigation:  # −X̄(k+1|k) = A (Υ̂(k|k) − X(k)): the target's prediction
            x, P = predict(
                filtered.x - self._vehicle_state(context), filtered.P, _ZERO3, self._A,
                self._B, self._Q,
            )  # fmt: skip
        else:
            a_W = self._a_port.Eval(context)
            x, P = predict(filtered.x, filtered.P, a_W, self._A, self._B, self._Q)
        discrete_state.set_value(self._x_index, x)
        discrete_state.set_value(self._P_index, P.ravel())
        self.advance_extra_state(context, filtered, discrete_state)

    def _calc_x_hat(self, context: Context, output: BasicVector) -> None:
        output.set_value(self._filtered.Eval(context).x)

    def _calc_P(self, context: Context, output: BasicVector) -> None:
        output.set_value(self._filtered.Eval(context).P.ravel())

    def _calc_status(self, context: Context, output: BasicVector) -> None:
        output.SetAtIndex(0, self._filtered.Eval(context).status)

    def _calc_nis(self, context: Context, output: BasicVector) -> None:
        output.SetAtIndex(0, self._filtered.Eval(context).nis)
