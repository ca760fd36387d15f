"""The marginalised particle filter: particles carry the relative position and a Kalman filter
of the velocity given its track (Schön, Gustafsson & Nordlund 2005).

Given the relative position's trajectory the velocity is linear-Gaussian, so a particle needs
only its position ``q`` and the conditional velocity mean ``m``; the conditional covariance
``Σ`` is the same for every particle of a run (the model is linear with the same matrices).
The math is :mod:`drake_uuv.models.marginalized_kernels`; the rest is the particle filter's:

- :class:`MarginalizedCloud` is a :class:`~drake_uuv.estimators.particle_cloud.ParticleCloud`
  whose particles ``(B, N, 6)`` are ``[q, m]`` (stored frame, as the particle cloud's), with
  one discrete state more, ``Σ`` (B·9). Its posterior is the particle cloud's reweighting of
  ``[q, m]`` by the ranges' likelihood of ``q`` (the same kernel, the same ranges and error
  model), its covariance plus ``Σ`` in the velocity block; its periodic update resamples
  (carrying ``q`` and ``m``), draws each ``q'`` from the marginal prediction and conditions
  ``m`` on it (:func:`~drake_uuv.models.marginalized_kernels.marginalized_advance`). A run
  entering its particles draws ``q`` from the Gaussian's position marginal, ``m = E[v | q]``,
  ``Σ = P_vv − P_vq P_qq⁻¹ P_qv``.
- :class:`MarginalizedRangeFilter` is the :class:`~drake_uuv.estimators.range_filter.RangeFilter`
  (linear start, hand-over, phases) with this cloud in place of the particle cloud.

Late ranges (``sonar.ping_offsets``, ``sonar.latency`` with ``error_model: modelled``) are not
supported: the filter refuses them in one line (use ``!ParticleFilter``, or ``error_model:
ideal``).
"""

import numpy as np
from pydrake.systems.framework import Context, State

from drake_uuv.estimators.contract import EstimatorSetting, FilteredEstimate
from drake_uuv.estimators.particle_cloud import CloudMeasurement, ParticleCloud, _mask, _runs
from drake_uuv.estimators.range_filter import RangeFilter
from drake_uuv.models.marginalized_kernels import marginalized_advance
from drake_uuv.models.measurement import VALID
from drake_uuv.models.particle_filter import STATE_SIZE, ParticleFilterParameters
from drake_uuv.models.particle_random import cloud_keys
from drake_uuv.primitives.run_arrays import kept_rows
from drake_uuv.scenario.estimators import MarginalizedParticleFilter

LATE_RANGES = (
    "sonar.ping_offsets: the marginalised particle filter takes each tick's ranges at the "
    "tick only (no sonar.ping_offsets or sonar.latency with error_model: modelled); use "
    "ParticleFilter, or estimator.error_model=ideal"
)


class MarginalizedCloud(ParticleCloud):
    """N particles ``[q, m]`` and one conditional velocity covariance ``Σ`` per run, declared on
    ``host`` (see the module notes; the API is the particle cloud's, with ``P`` including
    ``Σ``). Discrete state on the host: the particle cloud's, then ``Σ`` (B·9)."""

    def __init__(
        self,
        host,
        parameters: ParticleFilterParameters,
        range_covariance: np.ndarray,
        *,
        batch_size: int = 1,
    ) -> None:
        if host.window is not None:
            raise ValueError(LATE_RANGES)
        super().__init__(host, parameters, range_covariance, batch_size=batch_size)
        B = self.batch_size
        A, Bu, W = host.model
        self._Q = Bu @ np.asarray(W, dtype=float) @ Bu.T
        self._Q_runs = np.broadcast_to(self._Q, (B, 6, 6)).copy()
        self._Sigma_index = host.DeclareDiscreteState(np.zeros(B * 9))

    def velocity_covariance(self, context: Context) -> np.ndarray:
        """Each run's conditional velocity covariance ``Σ``, ``(B, 3, 3)``."""
        value = context.get_discrete_state(self._Sigma_index).get_value()
        return value.reshape(self.batch_size, 3, 3)

    def set_particles(
        self,
        context: Context,
        particles: np.ndarray,
        log_weights: np.ndarray,
        velocity_covariance: np.ndarray | None = None,
    ) -> None:
        """Sets this step's particles ``[q, m]`` (relative, ``(B, N, 6)``), log weights and
        ``Σ`` (``(B, 3, 3)`` or one for every run; default zero: the velocities known)."""
        super().set_particles(context, particles, log_weights)
        Sigma = np.zeros((3, 3)) if velocity_covariance is None else velocity_covariance
        context.SetDiscreteState(self._Sigma_index, _runs(Sigma, self.batch_size, 3, 3).ravel())

    def posterior(self, context: Context) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The particle cloud's posterior of ``[q, m]``, ``Σ`` added to its velocity block."""
        x, P, nis, log_weights = super().posterior(context)
        P = np.array(P)
        Sigma = self.velocity_covariance(context)
        if self._one_run_host:
            P[3:, 3:] += Sigma[0]
        else:
            P[:, 3:, 3:] += Sigma
        return x, P, nis, log_weights

    def advance(
        self,
        context: Context,
        filtered: FilteredEstimate,
        state: State,
        draw: tuple[np.ndarray, np.ndarray] | None = None,
        weigh_draw: bool | np.ndarray = False,
        *,
        drawn: np.ndarray | None = None,
        runs: np.ndarray | None = None,
        write_prediction: bool = True,
    ) -> tuple[np.ndarray, np.ndarray]:
        """The particle cloud's periodic update (the same arguments), each particle's ``q``
        drawn from the marginal prediction and ``m`` conditioned on it."""
        host, B, n = self._host, self.batch_size, self._parameters.count
        moving = np.ones(B, dtype=bool) if runs is None else _mask(runs, B)
        if draw is None:
            drawn = np.zeros(B, dtype=bool)
            draw_x, draw_P = np.zeros((B, 6)), np.zeros((B, 6, 6))
        else:
            drawn = moving if drawn is None else _mask(drawn, B) & moving
            draw_x, draw_P = _runs(draw[0], B, STATE_SIZE), _runs(draw[1], B, 6, 6)
        weighed = _mask(weigh_draw, B) & drawn
        reweigh = _mask(np.asarray(filtered.status) == VALID, B) & moving & ~drawn
        if reweigh.any():  # the cloud's own moments: the cache's, without Σ
            posterior = self._posterior.Eval(context)
        else:  # not read
            posterior = (np.empty((B, 6)), np.empty((B, 6, 6)), None, *np.empty((2, B, n)))
        if weighed.any():
            m = self._measurement(context, self._R_runs)
        else:
            offset = _runs(host.vehicle_motion.offset(context), B, STATE_SIZE)
            m = CloudMeasurement(self._no_z, self._no_used, self._no_q_s, self._R_runs, offset)
        keys = cloud_keys(np.array(self._seed_port.Eval(context), dtype=float))
        acceleration = _runs(host.vehicle_motion.acceleration(context), B, 3)
        Q_nav = host.navigation_process_noise(context)
        Q = self._Q_runs if Q_nav is None else self._Q + _runs(Q_nav, B, 6, 6)
        before = self.arrays(context)
        discrete_state = state.get_mutable_discrete_state()
        # The runs not moving keep their particles and Σ: the kernel writes the moving ones'.
        out = kept_rows(before.particles, ~moving)
        out_log_weights = kept_rows(before.log_weights, ~moving)
        out_Sigma = discrete_state.get_mutable_value(self._Sigma_index).reshape(B, 3, 3)
        x, P = np.empty((B, 6)), np.empty((B, 6, 6))
        marginalized_advance(
            before.particles, before.log_weights,
            self.velocity_covariance(context).copy(), reweigh, posterior[3], posterior[4],
            posterior[0], posterior[1], keys, moving, drawn, draw_x, draw_P, weighed, m.offset,
            m.z, m.used, m.q_s, m.R, self._time_step, acceleration, Q,
            self._parameters.resample_threshold, self._parameters.bandwidth,
            self._parameters.kernel == "range_bearing", out, out_log_weights, out_Sigma, x, P,
        )  # fmt: skip
        self._write(
            state,
            before.replaced(particles=out, log_weights=out_log_weights, live=moving.astype(float)),
        )
        if write_prediction:
            if self._one_run_host:
                host.write_prediction(discrete_state, x[0], P[0])
            else:
                host.write_prediction(discrete_state, x, P, runs=moving)
        return x, P


class MarginalizedRangeFilter(RangeFilter):
    """The raw-range filter (:class:`~drake_uuv.estimators.range_filter.RangeFilter`: linear
    start, hand-over, phases, ports) whose particle phase is the marginalised particle filter
    (:class:`MarginalizedCloud`). Refuses late ranges (see the module notes). Ports, state
    and phases are the raw-range filter's; the cloud adds ``Σ`` (B·9) to its state.

    .. pydrake_system::

        name: MarginalizedRangeFilter
        input_ports:
        - range_samples
        - sonar_status
        - R_WB_nav
        - u1_W
        - particle_seed
        output_ports:
        - x_TU_hat
        - P_TU
        - x_TU_prior
        - P_TU_prior
        - measurement_status
        - nis
        - estimator_phase
        - estimator_recovery
    """

    cloud_type = MarginalizedCloud

    def __init__(
        self,
        config: MarginalizedParticleFilter,
        *,
        setting: EstimatorSetting,
        batch_size: int = 1,
    ) -> None:
        if config.error_model == "modelled" and not setting.ping_schedule.immediate:
            raise ValueError(LATE_RANGES)
        super().__init__(config, setting=setting, batch_size=batch_size)
