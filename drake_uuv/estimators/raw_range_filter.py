"""EKF and iterated EKF on both raw ranges, started by the paper's linear KF."""

import numpy as np
from pydrake.systems.framework import Context

from drake_uuv.estimators.linear_start import (  # noqa: F401 (re-exported)
    LINEAR_PHASE,
    RANGE_PHASE,
    LinearStartEstimator,
)
from drake_uuv.models.filters import HandoverPolicy, RangeUpdate, ekf_update, iekf_update
from drake_uuv.models.handover import HandoverRule
from drake_uuv.models.particle_filter import ParticleFilterParameters
from drake_uuv.scenario import Iekf, Scenario

#: The range update of each method.
UPDATES: dict[str, RangeUpdate] = {"ekf": ekf_update, "iekf": iekf_update}


class RawRangeEstimator(LinearStartEstimator):
    """An EKF (``method="ekf"``) or iterated EKF (``"iekf"``) on the two raw ranges.

    The paper's ``Y = ½(d1² − d2²)`` keeps only ``q_sᵀ q``; the two ranges also carry the
    distance. This filter uses them directly, with all ``f`` samples: the per-sonar sample
    means ``z_i`` are sufficient, with covariance ``R = diag(η1/f, η2/f)``
    (:func:`~drake_uuv.models.measurement.range_noise_covariance`), ``h(x) = [|q + ½ q_s|,
    |q − ½ q_s|]``. Updates are :func:`~drake_uuv.models.filters.ekf_update` or
    :func:`~drake_uuv.models.filters.iekf_update` (Joseph form). With one sonar
    returning, it updates with that one range (NIS with 1 degree of freedom); with none, it
    only predicts. Timing, prediction, the NIS gate and the common ports are those of
    :class:`~drake_uuv.estimators.base.RelativeStateEstimator`.

    Initialisation: a linear-KF start. A range is nearly linear in ``q`` only once the
    position error is small against the range (second-order error ``σ⊥²/(2d)``). From the
    paper's prior (``x̂ = 0``, ``P = I``, true ``|q| ≈ 3 m``) the EKF linearises where both
    lines of sight are ±q_s, its two Jacobian rows antiparallel, and it can lock onto the
    mirror solution (the ranges are symmetric about any plane through the baseline): without
    a start it diverged in 14 of 30 runs of the numpy reference; the IEKF's line search
    survives the paper's prior but not a 3 m prior (31 of 60) nor a mirrored one (60 of 60).
    ``Y`` is *exactly* linear in ``q``, so the paper's KF converges from any prior without a
    linearisation point, and its covariance is exact for its second moments. So the filter
    begins as that KF (on ``Y = ½(z1² − z2²)`` from the same sample means, its noise mean and
    variance from the sonar's own :func:`~drake_uuv.models.measurement.range_difference_noise`
    with variances ``η/f``, so there is one noise model) and hands over to the raw ranges
    (:class:`~drake_uuv.estimators.linear_start.LinearStartEstimator`) when the hand-over
    says so:

    * :class:`~drake_uuv.models.handover.HandoverRule` (the default,
      ``second_order_tolerance=1, particle_bridge=True``): once the prior's share of the KF's
      covariance is below 10 %, the cross-range angle ``√tr(P⊥)/d`` below 0.25 rad, which
      scales with the range and, through the KF's covariance, with the noise, and the
      second-order range error ``tr(P⊥)/(2d)`` below the range noise σ/√f the EKF drops it
      against (see :mod:`drake_uuv.models.handover`). Where the prior is forgotten but the
      Gaussian is too wide (σ = 0.5 or 1 m at 2.8 m), the filter carries the posterior on
      particles (the particle bridge, 5000 by default) until the test holds on them, and
      goes back to particles when an angle exceeds 1.2 × 0.25 rad: without the bridge the
      EKF stayed the paper's KF at σ = 1 m (3.5× the bound in the numpy loop), with it it is
      at 1.01×, none of 40 runs lost. At 14 and 28 m, and in the paper scenario, it hands
      over from the KF directly, as without the bridge.
    * :class:`~drake_uuv.models.filters.HandoverPolicy` (``handover: threshold``): the first
      raw-range EKF's ``trace(P_qq)`` below a threshold (0.5 m² by default: second-order range
      error ≈ 0.03 m, under the 0.1 m noise; hand-over at step ≈ 30 from the paper's prior),
      or after ``max_linear_steps`` linear updates if that is set. The threshold is
      absolute: with σ = 0.5 or 1 m of range noise or at 14 m the KF never reaches it and the
      filter stays the paper's KF.

    Neither forces a hand-over by default: where the linear KF cannot converge (a fixed
    attitude leaves two directions unobservable) a forced hand-over linearises a covariance
    of thousands of m² and the loop blows up, while staying linear the filter is the
    paper's KF. The linear start needs both ranges: a step with one sonar only predicts.

    Discrete state: as :class:`~drake_uuv.estimators.linear_start.LinearStartEstimator`
    (groups 0 and 1 of the base class; group 2 ``[phase, linear updates]`` with phase
    :data:`LINEAR_PHASE` (1), :data:`RANGE_PHASE` (0) or ``PARTICLE_PHASE`` (2); group 3 the
    prior's share of the KF's covariance, used by
    :class:`~drake_uuv.models.handover.HandoverRule`; with the bridge, groups 4 and 5 the
    particles and their log weights).

    .. pydrake_system::

        name: RawRangeEstimator
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
    - ``particle_seed`` (1, random uniform, with the bridge): seeds the particles' draws.
    - Common ports (``sonar_status``, ``u1_W`` or ``p_WU``, ``v_WU``, the outputs): see the
      base class.
    """

    def __init__(
        self,
        time_step: float,
        acceleration_covariance: np.ndarray,
        initial_estimate: np.ndarray,
        initial_covariance: np.ndarray,
        noise_variances: np.ndarray,
        samples_per_step: int = 1,
        method: str = "ekf",
        noise_model: str = "derived",
        handover: HandoverPolicy | HandoverRule | None = None,
        gate_probability: float | None = None,
        vehicle_motion: str = "commanded",
        particle_parameters: ParticleFilterParameters | None = None,
    ) -> None:
        if method not in UPDATES:
            raise ValueError(f"method: must be one of {', '.join(UPDATES)}, got {method!r}")
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
            particle_parameters,
        )
        self._method = method
        self._update = UPDATES[method]
        self._declare_ports()

    @classmethod
    def from_scenario(cls, scenario: Scenario) -> "RawRangeEstimator":
        """The filter of ``scenario.estimator`` (an :class:`~drake_uuv.scenario.Ekf` or
        :class:`~drake_uuv.scenario.Iekf`)."""
        method = "iekf" if isinstance(scenario.estimator, Iekf) else "ekf"
        return cls(**cls.scenario_arguments(scenario), method=method)

    def default_handover(self) -> HandoverRule:
        """:class:`~drake_uuv.models.handover.HandoverRule` with the second-order test: the
        EKF drops the ranges' second-order term."""
        return HandoverRule(second_order_tolerance=1.0, particle_bridge=True)

    @property
    def method(self) -> str:
        return self._method

    def range_update(
        self,
        context: Context,
        x_prior: np.ndarray,
        P_prior: np.ndarray,
        z: np.ndarray,
        q_s: np.ndarray,
        sonars: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, float]:
        return self._update(x_prior, P_prior, z, q_s, self._R, sonars=sonars)
