"""What every attitude generator gets from the rest of the scenario (:class:`AttitudeSetting`),
and what the paper's generators share: the command ``u2`` and the published plan."""

from dataclasses import dataclass

import numpy as np
from pydrake.systems.framework import BasicVector, Context, LeafSystem

from drake_uuv.models.attitude_plans import attitude_commands, planned_attitudes
from drake_uuv.models.information import EstimatorPlanningModel, TrackingPlanningModel
from drake_uuv.primitives.batch import batch_size_field
from drake_uuv.primitives.setting import array_field, time_step_field


@dataclass(frozen=True)
class AttitudeSetting:
    """What every system of the attitude slot gets besides its own configuration.

    An attitude generator is built as
    ``cls(config, setting=AttitudeSetting(...), batch_size=B)``; the slot's factory
    (:func:`drake_uuv.attitude.make_attitude_generator`) makes the setting from the scenario
    (:func:`drake_uuv.attitude.factory.attitude_setting`); every run of a batch shares it.
    Fields:

    - ``time_step``: t [s], the period of the loop (the scenario's ``time_step``): the
      command ``u2`` turns ``R(k)`` into ``R(k+1) = Exp(u2 t) R(k)``.
    - ``baseline_B``: b (3) [m], the sonar baseline in the body frame (``sonar.baseline``),
      the vector the paper's Algorithm 2 steers.
    - ``noise_variances``: η1, η2 (2) [m²] of the two sonars' ranges
      (``sonar.noise_variances``), and ``samples_per_step``: f, the range samples per sonar
      and step (``sonar.samples_per_step``): the measurement noise a planner scores.
    - ``acceleration_covariance``: W (3×3) [m²/s⁴] of the target's random walk
      (``target.acceleration_covariance``): the process noise a planner propagates.
    - ``estimator``: what the estimator updates with (the estimator section's
      ``planning_model()``).
    - ``tracking``: the tracking law's reference, q* if it turns with the body and its lag
      (the tracking section's ``planning_model()``).

    Arrays are stored read-only; a bad field raises ``ValueError`` naming it and its value.
    """

    time_step: float
    baseline_B: np.ndarray
    noise_variances: np.ndarray
    samples_per_step: int
    acceleration_covariance: np.ndarray
    estimator: EstimatorPlanningModel
    tracking: TrackingPlanningModel

    def __post_init__(self) -> None:
        object.__setattr__(self, "time_step", time_step_field(self.time_step))
        b = array_field("baseline_B", self.baseline_B, (3,))
        if not b @ b > 0.0:
            raise ValueError(f"baseline_B: must be a non-zero 3-vector, got {self.baseline_B!r}")
        object.__setattr__(self, "baseline_B", b)
        eta = array_field("noise_variances", self.noise_variances, (2,))
        if not np.all(eta > 0.0):
            raise ValueError(f"noise_variances: must be > 0, got {self.noise_variances!r}")
        object.__setattr__(self, "noise_variances", eta)
        f = self.samples_per_step
        if isinstance(f, bool) or not isinstance(f, int) or f < 1:
            raise ValueError(f"samples_per_step: must be an integer ≥ 1, got {f!r}")
        W = array_field("acceleration_covariance", self.acceleration_covariance, (3, 3))
        object.__setattr__(self, "acceleration_covariance", W)
        for name, value, kind in (
            ("estimator", self.estimator, EstimatorPlanningModel),
            ("tracking", self.tracking, TrackingPlanningModel),
        ):
            if not isinstance(value, kind):
                raise ValueError(f"{name}: must be a {kind.__name__}, got {value!r}")


class AttitudeGenerator(LeafSystem):
    """Base of the attitude generators: ``u2(k) = Log(R̄(k) R(k)ᵀ) / t`` so that
    ``R(k+1) = R̄(k)``, for the desired attitude ``R̄(k)`` a subclass supplies.

    With ``max_angular_rate`` a run whose command exceeds it is scaled down to that norm: its
    attitude then moves towards ``R̄(k)`` along the same geodesic without reaching it in one
    step. ``u2`` is a world-frame rate, as the plant (paper eq. 2) left-multiplies by
    ``Exp(u2 t)``.

    The generator also publishes its *plan*, the attitudes ``R(k+1)`` and ``R(k+2)`` it will
    produce, for a tracking controller that feeds the turning reference ``R q*`` forward.
    ``R(k+1) = Exp(u2(k) t) R(k)`` is always known; ``R(k+2)`` rolls the generator's own law one
    step further where a subclass knows ``R̄(k+1)`` (:meth:`next_desired_attitudes`), and is
    ``R(k+1)`` otherwise.

    Subclasses override :meth:`desired_attitudes` (and :meth:`next_desired_attitudes`), and
    may declare input ports of their own before calling :meth:`_declare_outputs`; they take
    the period from the slot's ``setting``.

    Common ports (sizes per run; with ``batch_size`` B every port holds B runs row-major,
    :mod:`drake_uuv.primitives.batch`):

    - input ``R_WB_nav`` (9, row-major): the current attitude ``R(k)`` as the navigation
      knows it: the command turns the navigated attitude onto ``R̄(k)``.
    - output ``u2_W`` (3): the angular velocity command ``u2`` [rad/s], world frame.
    - output ``R_WB_plan`` (18): the planned ``R(k+1)`` and ``R(k+2)``, each row-major.
    """

    def __init__(
        self,
        *,
        setting: AttitudeSetting,
        max_angular_rate: float | None = None,
        batch_size: int = 1,
    ) -> None:
        super().__init__()
        self._time_step = setting.time_step
        self._max_rate = max_angular_rate
        self.batch_size = B = batch_size_field(batch_size)
        self._attitude_port = self.DeclareVectorInputPort("R_WB_nav", 9 * B)
        # Where each entry of a held plan comes from: run i's R(k) twice.
        self._held = (9 * np.arange(B)[:, np.newaxis] + np.tile(np.arange(9), 2)).ravel()

    def _declare_outputs(self) -> None:
        """Call at the end of a subclass ``__init__``, after its own input ports."""
        B = self.batch_size
        self.DeclareVectorOutputPort("u2_W", 3 * B, self._calc_rate)
        self.DeclareVectorOutputPort("R_WB_plan", 18 * B, self._calc_plan)

    @property
    def time_step(self) -> float:
        return self._time_step

    def step_index(self, context: Context) -> int:
        """The sample index k of the context's time (the same for every run)."""
        return round(context.get_time() / self._time_step)

    def desired_attitudes(self, context: Context) -> np.ndarray | None:
        """``R̄(k)``: ``(B, 3, 3)`` one per run, or ``(1, 3, 3)`` for all runs; None to hold
        the attitude of every run."""
        raise NotImplementedError

    def next_desired_attitudes(self, context: Context) -> np.ndarray | None:
        """``R̄(k+1)`` (as :meth:`desired_attitudes`) if it is known at step k, else None (the
        plan then holds ``R(k+1)``)."""
        return None

    def _calc_rate(self, context: Context, output: BasicVector) -> None:
        R_desired = self.desired_attitudes(context)
        if R_desired is None:
            output.SetZero()
            return
        R_WB = self._attitude_port.Eval(context)
        output.set_value(
            attitude_commands(R_desired, R_WB, self._time_step, self._max_rate).ravel()
        )

    def _calc_plan(self, context: Context, output: BasicVector) -> None:
        R_WB = self._attitude_port.Eval(context)
        R_desired = self.desired_attitudes(context)
        if R_desired is None:  # each run holds its attitude: R(k+1) = R(k+2) = R(k)
            output.set_value(R_WB[self._held])
            return
        plan = planned_attitudes(
            R_desired, self.next_desired_attitudes(context), R_WB, self._time_step, self._max_rate
        )
        output.set_value(plan.ravel())
