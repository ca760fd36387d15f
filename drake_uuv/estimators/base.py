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
from dataclasses import dataclass, field

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

from drake_uuv.estimators.vehicle_motion import VEHICLE_MOTIONS
from drake_uuv.models.filters import predict
from drake_uuv.models.measurement import GATED, VALID
from drake_uuv.models.motion import double_integrator, process_noise_covariance
from drake_uuv.models.statistics import chi2_ppf
from drake_uuv.scenario.estimators import EstimatorOptions


@dataclass(frozen=True)
class EstimatorSetting:
    """What every estimator gets from the rest of the scenario (the builder passes it).

    - ``time_step`` t [s] of the loop.
    - ``acceleration_covariance``: W (3×3) of the target's random walk [m²/s⁴]
      (``target.acceleration_covariance``).
    - ``noise_variances``: η1, η2 of the two sonars' range noise [m²]
      (``sonar.noise_variances``).
    - ``samples_per_step``: f, range samples per sonar and step (``sonar.samples_per_step``).
    - ``baseline_B``: b = ᵇp_s1 − ᵇp_s2 in the body frame [m] (``sonar.baseline``): the world
      baseline ``q_s = R_WB_nav b`` of a step follows from the navigated attitude.
    """

    time_step: float
    acceleration_covariance: np.ndarray
    noise_variances: np.ndarray
    samples_per_step: int = 1
    baseline_B: np.ndarray = field(default_factory=lambda: np.array([-1.0, 1.0, 0.0]))

    def __post_init__(self) -> None:
        if not (math.isfinite(self.time_step) and self.time_step > 0.0):
            raise ValueError(f"time_step: must be > 0, got {self.time_step!r}")
        W = np.asarray(self.acceleration_covariance, dtype=float)
        if W.shape != (3, 3) or not np.all(np.isfinite(W)):
            raise ValueError(f"acceleration_covariance: must be a finite 3×3 matrix, got {W!r}")
        eta = np.asarray(self.noise_variances, dtype=float).reshape(-1)
        if eta.shape != (2,) or not np.all(np.isfinite(eta)) or np.any(eta <= 0.0):
            raise ValueError(f"noise_variances: must be two numbers > 0, got {eta.tolist()!r}")
        f = self.samples_per_step
        if isinstance(f, bool) or int(f) != f or f < 1:
            raise ValueError(f"samples_per_step: must be an integer ≥ 1, got {f!r}")
        b = np.asarray(self.baseline_B, dtype=float)
        if b.shape != (3,) or not np.all(np.isfinite(b)):
            raise ValueError(f"baseline_B: must be 3 finite numbers, got {self.baseline_B!r}")
        object.__setattr__(self, "acceleration_covariance", W)
        object.__setattr__(self, "noise_variances", eta)
        object.__setattr__(self, "samples_per_step", int(f))
        object.__setattr__(self, "baseline_B", b)


@dataclass
class Estimate:
    """A relative state estimate ``[q, ϑ]`` and its covariance."""

    x: np.ndarray
    P: np.ndarray


@dataclass(frozen=True)
class Ranges:
    """One step's ranges, as an estimator reads them.

    ``samples`` (2×f, sonar 1's row first; NaN without a return), ``z`` the per-sonar sample
    means, ``valid`` which sonars returned a usable range (status VALID and finite samples),
    ``status`` the sonar's per-sonar codes, ``q_s`` the world baseline ``R_WB_nav b`` [m].
    """

    samples: np.ndarray
    z: np.ndarray
    valid: np.ndarray
    status: np.ndarray
    q_s: np.ndarray

    @property
    def sonars(self) -> np.ndarray:
        """The indices of the sonars that returned."""
        return np.flatnonzero(self.valid)


@dataclass
class MeasurementUpdate:
    """A variant's proposed update: the posterior and its innovation statistic."""

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

    @property
    def applied(self) -> bool:
        """Whether a measurement update was applied (VALID with a finite NIS)."""
        return self.status == VALID and math.isfinite(self.nis)


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
        if self.vehicle_motion.state_ports:
            prior_tickets = {self.xd_ticket(), *self._tickets(self.vehicle_motion.state_ports)}
            self.DeclareVectorOutputPort("x_TU_prior", 6, self._calc_prior, prior_tickets)
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
        :meth:`write_prediction`) for groups 0 and 1.
        """
        self.write_prediction(discrete_state, *self.predicted(context, filtered.x, filtered.P))

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
    def initial_estimate(self) -> Estimate:
        """``Υ̂(0|−1)`` and ``P(0|−1)`` of the config."""
        return self._initial

    def prior(self, context: Context) -> Estimate:
        """This step's prediction ``Υ̂(k|k−1)``, ``P(k|k−1)`` (relative state)."""
        stored = context.get_discrete_state(self._x_index).get_value()
        P = context.get_discrete_state(self._P_index).get_value().reshape(6, 6)
        return Estimate(self.vehicle_motion.prior(context, stored), P)

    def set_prior(self, context: Context, x: np.ndarray, P: np.ndarray) -> None:
        """Sets this step's prediction ``Υ̂(k|k−1)``, ``P(k|k−1)`` in ``context`` (e.g. to start
        a test or a run from a chosen prior); the vehicle inputs must be connected or fixed
        with ``vehicle_motion: navigation``."""
        stored = np.asarray(x, dtype=float) - self.vehicle_motion.offset(context)
        context.SetDiscreteState(self._x_index, stored)
        context.SetDiscreteState(self._P_index, np.asarray(P, dtype=float).ravel())

    def ranges(self, context: Context) -> Ranges:
        """This step's ranges, their means and the world baseline."""
        samples = self._samples_port.Eval(context).reshape(2, self._f)
        status = self._status_port.Eval(context)
        valid = (np.asarray(status) == VALID) & np.all(np.isfinite(samples), axis=1)
        q_s = self._attitude_port.Eval(context).reshape(3, 3) @ self._b
        return Ranges(samples, samples.mean(axis=1), valid, status, q_s)

    def filtered(self, context: Context) -> FilteredEstimate:
        """This step's filtered estimate (the cache entry behind ``x_TU_hat`` and ``P_TU``)."""
        return self._filtered.Eval(context)

    def predicted(
        self, context: Context, x: np.ndarray, P: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """``(A (x − offset) + B acceleration, A P Aᵀ + Q)``: the prediction of a relative
        estimate, in the frame the state stores (see :attr:`vehicle_motion`)."""
        motion = self.vehicle_motion
        return predict(
            x - motion.offset(context), P, motion.acceleration(context), self._A, self._B,
            self._Q,
        )  # fmt: skip

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
        prior = self.prior(context)
        ranges = self.ranges(context)
        update = self.measurement_update(context, prior, ranges)
        if update is None:
            invalid = ranges.status[ranges.status != VALID]
            code = int(invalid[0]) if invalid.size else VALID
            value.set_value(FilteredEstimate(prior.x.copy(), prior.P.copy(), code))
        elif update.nis > self.gate_threshold(update.dof):
            value.set_value(FilteredEstimate(prior.x.copy(), prior.P.copy(), GATED, update.nis))
        else:
            value.set_value(FilteredEstimate(update.x, update.P, VALID, update.nis))

    def _update(self, context: Context, discrete_state: DiscreteValues) -> None:
        self.advance(context, self._filtered.Eval(context), discrete_state)

    def _calc_prior(self, context: Context, output: BasicVector) -> None:
        output.set_value(self.prior(context).x)

    def _calc_x_hat(self, context: Context, output: BasicVector) -> None:
        output.set_value(self._filtered.Eval(context).x)

    def _calc_P(self, context: Context, output: BasicVector) -> None:
        output.set_value(self._filtered.Eval(context).P.ravel())

    def _calc_status(self, context: Context, output: BasicVector) -> None:
        output.SetAtIndex(0, self._filtered.Eval(context).status)

    def _calc_nis(self, context: Context, output: BasicVector) -> None:
        output.SetAtIndex(0, self._filtered.Eval(context).nis)
