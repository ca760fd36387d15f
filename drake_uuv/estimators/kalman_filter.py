"""The paper's linear Kalman filter on the squared-range difference, eq. (9)."""

import numpy as np
from pydrake.systems.framework import Context

from drake_uuv.estimators.base import (
    Estimate,
    EstimatorSetting,
    MeasurementUpdate,
    Ranges,
    RelativeStateEstimator,
)
from drake_uuv.models.filter_runs import (
    noise_model_code,
    paper_measurement_runs,
    range_difference_update_runs,
)
from drake_uuv.scenario.estimators import PaperKf


class RangeDifferenceKalmanFilter(RelativeStateEstimator):
    """The paper's KF (eq. 9) on ``Y = ½(d1² − d2²)``, with the covariance in Joseph form.

    Timing, prediction, gating and the ports are those of
    :class:`~drake_uuv.estimators.base.RelativeStateEstimator`; this class adds the scalar
    update :func:`~drake_uuv.models.filters.range_difference_update` with ``C = [q_sᵀ, 0]``,
    used when both sonars returned. ``Y``, its noise mean ``m`` and variance ``Γ`` are the
    sonar's own (:func:`~drake_uuv.models.measurement.paper_measurement`: the first sample of
    each sonar, ``Γ`` from all f samples, with ``config.noise_model``). With ``batch_size``
    B it steps B runs (:class:`~drake_uuv.estimators.base.RelativeStateEstimator`): a run
    without both ranges only predicts.

    .. pydrake_system::

        name: RangeDifferenceKalmanFilter
        input_ports:
        - range_samples
        - sonar_status
        - R_WB_nav
        - u1_W
        output_ports:
        - x_TU_hat
        - P_TU
        - x_TU_prior
        - P_TU_prior
        - measurement_status
        - nis

    The ports are the base class's, sizes per run (with ``vehicle_motion: navigation``,
    ``p_WU_nav`` and ``v_WU_nav`` in place of ``u1_W``); with ``batch_size`` B every port and
    state holds B runs row-major.
    """

    def __init__(self, config: PaperKf, *, setting: EstimatorSetting, batch_size: int = 1) -> None:
        super().__init__(config, setting=setting, batch_size=batch_size)
        self._noise_model = noise_model_code(config.noise_model)
        self._eta = setting.noise_variances
        self._dof = np.ones(self.batch_size, dtype=np.intp)

    def measurement_update(
        self, context: Context, prior: Estimate, ranges: Ranges
    ) -> MeasurementUpdate | None:
        both = ranges.valid[:, 0] & ranges.valid[:, 1]  # Y needs both ranges.
        eta = ranges.variances(self._eta)
        Y, m, gamma = paper_measurement_runs(ranges.samples, eta, self._noise_model)
        if not ranges.exact:  # the error model's: the baseline's attitude error
            gamma += ranges.difference_variance(prior.x)
        x, P, nis = range_difference_update_runs(prior.x, prior.P, Y, m, gamma, ranges.q_s, both)
        return MeasurementUpdate(x, P, nis, self._dof, both, gamma)

    def needs_both_ranges(self, context: Context) -> bool:
        return True
