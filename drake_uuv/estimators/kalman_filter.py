"""The paper's linear Kalman filter on the squared-range difference, eq. (9)."""

from pydrake.systems.framework import Context

from drake_uuv.estimators.base import (
    Estimate,
    EstimatorSetting,
    MeasurementUpdate,
    Ranges,
    RelativeStateEstimator,
)
from drake_uuv.models.filters import range_difference_update
from drake_uuv.models.measurement import paper_measurement
from drake_uuv.scenario.estimators import PaperKf


class RangeDifferenceKalmanFilter(RelativeStateEstimator):
    """The paper's KF (eq. 9) on ``Y = ½(d1² − d2²)``, with the covariance in Joseph form.

    Timing, prediction, gating and the ports are those of
    :class:`~drake_uuv.estimators.base.RelativeStateEstimator`; this class adds the scalar
    update :func:`~drake_uuv.models.filters.range_difference_update` with ``C = [q_sᵀ, 0]``,
    used when both sonars returned. ``Y``, its noise mean ``m`` and variance ``Γ`` are the
    sonar's own (:func:`~drake_uuv.models.measurement.paper_measurement`: the first sample of
    each sonar, ``Γ`` from all f samples, with ``config.noise_model``).

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

    The ports are the base class's (with ``vehicle_motion: navigation``, ``p_WU_nav`` and
    ``v_WU_nav`` in place of ``u1_W``).
    """

    def __init__(self, config: PaperKf, *, setting: EstimatorSetting) -> None:
        super().__init__(config, setting=setting)
        self._noise_model = config.noise_model
        self._eta = setting.noise_variances

    def measurement_update(
        self, context: Context, prior: Estimate, ranges: Ranges
    ) -> MeasurementUpdate | None:
        if not ranges.valid.all():
            return None  # Y needs both ranges.
        eta = ranges.variances(self._eta)
        Y, m, gamma = paper_measurement(ranges.samples, eta, self._noise_model)
        if not ranges.exact:  # the error model's: the baseline's attitude error
            gamma += ranges.difference_variance(prior.x)
        x, P, nis = range_difference_update(prior.x, prior.P, Y, m, gamma, ranges.q_s)
        return MeasurementUpdate(x, P, nis, 1, gamma)

    def needs_both_ranges(self, context: Context) -> bool:
        return True
