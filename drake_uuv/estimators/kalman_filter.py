"""The paper's linear Kalman filter on the squared-range difference, eq. (9)."""

from typing import Self

import numpy as np
from pydrake.systems.framework import Context

from drake_uuv.estimators.base import MeasurementUpdate, RelativeStateEstimator
from drake_uuv.models.filters import range_difference_update
from drake_uuv.models.measurement import VALID
from drake_uuv.scenario import Scenario


class RangeDifferenceKalmanFilter(RelativeStateEstimator):
    """The paper's KF (eq. 9) on ``Y = ½(d1² − d2²)``, with the covariance in Joseph form.

    Timing, prediction, gating and the common ports are those of
    :class:`~drake_uuv.estimators.base.RelativeStateEstimator`; this class adds the scalar
    update :func:`~drake_uuv.models.filters.range_difference_update`, used when both sonars
    returned.

    .. pydrake_system::

        name: RangeDifferenceKalmanFilter
        input_ports:
        - Y
        - m
        - Gamma
        - b_W
        - sonar_status
        - u1_W
        output_ports:
        - x_TU_hat
        - P_TU
        - x_TU_prior
        - P_TU_prior
        - measurement_status
        - nis

    - ``Y``, ``m``, ``Gamma`` (1 each): measurement, noise mean, noise variance.
    - ``b_W`` (3): world sonar baseline ``q_s``, ``C = [q_sᵀ, 0]``.
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
        super().__init__(
            time_step,
            acceleration_covariance,
            initial_estimate,
            initial_covariance,
            gate_probability,
            vehicle_motion,
        )
        self._Y_port = self.DeclareVectorInputPort("Y", 1)
        self._m_port = self.DeclareVectorInputPort("m", 1)
        self._Gamma_port = self.DeclareVectorInputPort("Gamma", 1)
        self._b_W_port = self.DeclareVectorInputPort("b_W", 3)
        self._declare_common_ports([self._Y_port, self._m_port, self._Gamma_port, self._b_W_port])

    @classmethod
    def from_scenario(cls, scenario: Scenario) -> Self:
        """The filter of ``scenario.estimator`` (a :class:`~drake_uuv.scenario.PaperKf`)."""
        e = scenario.estimator
        return cls(
            scenario.time_step,
            e.filter_acceleration_covariance(scenario.target.acceleration_covariance),
            np.asarray(e.initial_estimate),
            np.asarray(e.initial_covariance),
            e.gate_probability,
            e.vehicle_motion,
        )

    def measurement_update(
        self, context: Context, x_prior: np.ndarray, P_prior: np.ndarray, status: np.ndarray
    ) -> MeasurementUpdate | None:
        if status[0] != VALID or status[1] != VALID:
            return None  # Y needs both ranges.
        x, P, nis = range_difference_update(
            x_prior,
            P_prior,
            self._Y_port.Eval(context)[0],
            self._m_port.Eval(context)[0],
            self._Gamma_port.Eval(context)[0],
            self._b_W_port.Eval(context),
        )
        return MeasurementUpdate(x, P, nis, 1)
