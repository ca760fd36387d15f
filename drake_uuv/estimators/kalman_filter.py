"""The paper's linear Kalman filter on the squared-range difference, eq. (9)."""

import numpy as np
from pydrake.systems.framework import Context

from drake_uuv.estimators.base import MeasurementUpdate, RelativeStateEstimator

# The update's one implementation lives with the other filter steps (pure numpy); it is
# re-exported here for the benchmarks and the paper's-KF users.
from drake_uuv.estimators.filters_math import range_difference_update
from drake_uuv.sensors.dual_sonar import VALID

__all__ = ["RangeDifferenceKalmanFilter", "range_difference_update"]


class RangeDifferenceKalmanFilter(RelativeStateEstimator):
    """The paper's KF (eq. 9) on ``Y = ½(d1² − d2²)``, with the covariance in Joseph form.

    Timing, prediction, gating and the common ports are those of
    :class:`~drake_uuv.estimators.base.RelativeStateEstimator`; this class adds the scalar
    update :func:`range_difference_update`, used when both sonars returned.

    .. pydrake_system::

        name: RangeDifferenceKalmanFilter
        input_ports:
        - Y
        - m
        - Gamma
        - q_s
        - sonar_status
        - a_W
        output_ports:
        - x_hat
        - P
        - x_prior
        - P_prior
        - measurement_status
        - nis

    - ``Y``, ``m``, ``Gamma`` (1 each): measurement, noise mean, noise variance.
    - ``q_s`` (3): world sonar baseline, ``C = [q_sᵀ, 0]``.
    """

    def __init__(
        self,
        time_step: float,
        acceleration_covariance: np.ndarray,
        initial_estimate: np.ndarray,
        initial_covariance: np.ndarray,
        gate_probability: float | None = None,
    ) -> None:
        super().__init__(
            time_step,
            acceleration_covariance,
            initial_estimate,
            initial_covariance,
            gate_probability,
        )
        self._Y_port = self.DeclareVectorInputPort("Y", 1)
        self._m_port = self.DeclareVectorInputPort("m", 1)
        self._Gamma_port = self.DeclareVectorInputPort("Gamma", 1)
        self._q_s_port = self.DeclareVectorInputPort("q_s", 3)
        self._declare_common_ports([self._Y_port, self._m_port, self._Gamma_port, self._q_s_port])

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
            self._q_s_port.Eval(context),
        )
        return MeasurementUpdate(x, P, nis, 1)
