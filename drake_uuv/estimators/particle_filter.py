"""Regularised particle filter on both raw ranges, started by the paper's linear KF."""

import numpy as np

from drake_uuv.estimators.linear_start import LinearStartEstimator
from drake_uuv.models.filters import HandoverPolicy
from drake_uuv.models.handover import HandoverRule
from drake_uuv.models.particle_filter import ParticleFilterParameters
from drake_uuv.scenario import Scenario


class ParticleRangeEstimator(LinearStartEstimator):
    """A regularised particle filter on the two raw ranges (all ``f`` samples).

    The model and the steps are :mod:`drake_uuv.models.particle_filter`'s: the filtered
    estimate of step k is the weighted mean and covariance of the predicted particles
    reweighted by the ranges' likelihood (:func:`~drake_uuv.models.particle_filter.pf_update`,
    a direct-feedthrough output, deterministic in the inputs and the state); the periodic
    update resamples when the effective sample size falls below half the count,
    regularises, and moves every particle by the model with its own target acceleration
    (:func:`~drake_uuv.models.particle_filter.pf_predict`). With a large count its estimate
    is the posterior mean: the reference that shows where the Cramér–Rao bound is attainable.
    The particle phase is :class:`~drake_uuv.estimators.linear_start.LinearStartEstimator`'s
    (the one the EKF and UKF bridge with); this filter has no Gaussian update, so once drawn
    it stays on particles.

    Randomness enters only through the random input port ``particle_seed`` (one uniform draw
    per step, connect a ``RandomSource`` of kUniform), read only in the periodic update, where
    it seeds the ``numpy.random.Generator`` of that update. A run is therefore reproducible
    from the diagram's seed, and the filtered output does not depend on the draw.

    Initialisation: a linear-KF start (:class:`~drake_uuv.estimators.linear_start.
    LinearStartEstimator`) with :class:`~drake_uuv.models.handover.HandoverRule`
    ``(angle_tolerance=None)`` by default: at the update where the prior's share of the KF's
    covariance has fallen below 10 %, the particles are drawn from the KF's ``N(x̂, P)``. The
    scenario's prior ``N(0, I)`` lies three standard deviations from the truth, and particles
    drawn from it at step 0, or from the KF after its first update, lost the target in 1 of
    40 paper runs (5000 particles, numpy study ``benchmarks/estimator_regimes.py
    --prior-share inf``); drawn after the hand-over, none of 40 runs diverged in any of the
    six regimes studied, at 0.98–1.07× the mean per-run bound. No Gaussian-posterior test
    applies: the particles carry the curved, or split, posterior that stops the EKF and UKF.
    The linear start is therefore required (``max_linear_steps`` must not be 0).

    In the Drake loop (40 runs per regime: σ = 0.1, 0.5, 1 m at the paper's standoff, and
    2.8, 14, 28 m with q* in the world frame) it is at 1.02–1.04× the mean per-run
    Cramér–Rao bound in every regime, mean NEES 6.2–7.0, and no run diverged; the paper's KF
    is at 1.5–3.8×, the EKF and UKF (with their particle bridge at σ ≥ 0.5 m) at 1.03–1.08×
    up to 2.8 m and 1.18–1.37× at 14 and 28 m.

    Count: 5000 by default (:class:`~drake_uuv.models.particle_filter.
    ParticleFilterParameters`); see ``benchmarks/bench_particle_filter.py`` for the cost.

    Discrete state: groups 0–3 as in the base classes (groups 0 and 1 hold the predicted
    cloud's mean and covariance once the particles exist); group 4 the predicted particles
    (6N, state-major: the N values of q_x, then of q_y, …); group 5 their log weights (N).
    The phase (group 2) is ``LINEAR_PHASE``, then ``PARTICLE_PHASE``.

    .. pydrake_system::

        name: ParticleRangeEstimator
        input_ports:
        - range_samples
        - b_W
        - sonar_status
        - u1_W
        - particle_seed
        output_ports:
        - x_TU_hat
        - P_TU
        - x_TU_prior
        - P_TU_prior
        - measurement_status
        - nis

    - ``range_samples`` (2f): sonar 1's f samples then sonar 2's [m]; NaN without a return.
    - ``b_W`` (3): world sonar baseline ``q_s = R_WB b``.
    - ``particle_seed`` (1, random uniform in [0, 1)): seeds the step's resampling,
      regularisation and process noise.
    - Common ports (``sonar_status``, ``u1_W`` or ``p_WU``, ``v_WU``, the outputs): see the
      base class.
    """

    gaussian = False

    def __init__(
        self,
        time_step: float,
        acceleration_covariance: np.ndarray,
        initial_estimate: np.ndarray,
        initial_covariance: np.ndarray,
        noise_variances: np.ndarray,
        samples_per_step: int = 1,
        noise_model: str = "derived",
        handover: HandoverRule | HandoverPolicy | None = None,
        gate_probability: float | None = None,
        parameters: ParticleFilterParameters | None = None,
        vehicle_motion: str = "commanded",
    ) -> None:
        if parameters is not None and not isinstance(parameters, ParticleFilterParameters):
            raise ValueError(f"parameters: must be ParticleFilterParameters, got {parameters!r}")
        super().__init__(
            time_step,
            acceleration_covariance,
            initial_estimate,
            initial_covariance,
            noise_variances,
            samples_per_step,
            noise_model,
            handover,
            gate_probability,
            vehicle_motion,
            parameters,
        )
        if not self.handover.linear_start:
            raise ValueError(
                "handover: the particle filter draws its particles from the linear start, "
                f"max_linear_steps must not be 0, got {self.handover!r}"
            )
        self._declare_ports()

    def default_handover(self) -> HandoverRule:
        """:class:`HandoverRule` without the angle test: particles need no Gaussian posterior."""
        return HandoverRule(angle_tolerance=None)

    @classmethod
    def from_scenario(cls, scenario: Scenario) -> "ParticleRangeEstimator":
        """The filter of ``scenario.estimator`` (a :class:`~drake_uuv.scenario.ParticleFilter`)."""
        arguments = cls.scenario_arguments(scenario)
        parameters = arguments.pop("particle_parameters")
        return cls(**arguments, parameters=parameters)
