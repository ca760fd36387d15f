"""Two monostatic sonars at ±½ b about the body origin, and the linear measurement Y."""

import math
from dataclasses import dataclass
from typing import Self

import numpy as np
from pydrake.common import RandomDistribution
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, Context, LeafSystem, ValueProducer

from drake_uuv.models.measurement import (
    DROPPED,
    OUT_OF_BEAM,
    OUT_OF_RANGE,
    VALID,
    range_difference_noise,
)
from drake_uuv.models.so3 import norm
from drake_uuv.primitives.random_input import declare_random_input
from drake_uuv.scenario.schema import SonarConfig


def _clip_at_zero(x: float) -> float:
    """``np.maximum(x, 0.0)`` for a float (NaN stays NaN)."""
    return x if x > 0.0 or x != x else 0.0


@dataclass
class SonarFaults:
    """Sensor realism beyond the paper; the defaults switch every effect off.

    - ``max_range`` [m]: no return from a target farther than this.
    - ``beam_half_angle`` [rad]: each pan-tilt sonar points at the estimator's *predicted*
      target position (known before the step's measurement, so there is no algebraic loop);
      a target further off that axis gives no return. Within one step (hundreds of pings at
      the sonar's rate) the pan-tilt scans the prediction's ``search_sigma``-σ region, so the
      acceptance cone is the wider of the beam and that region's angular radius: a target
      lost while the estimate drifts is found again once the uncertainty covers it.
    - ``dropout_probability`` (per sonar): a return lost, independently each step.
    - ``outlier_probability``, ``outlier_scale`` [m]: a multipath return, longer by an
      exponentially distributed excess of mean ``outlier_scale`` (all f samples of that step).
    """

    max_range: float | None = None
    beam_half_angle: float | None = None
    dropout_probability: tuple[float, float] = (0.0, 0.0)
    outlier_probability: float = 0.0
    outlier_scale: float = 1.0
    search_sigma: float = 3.0

    @property
    def random_faults(self) -> bool:
        return max(self.dropout_probability) > 0.0 or self.outlier_probability > 0.0

    @classmethod
    def from_config(cls, config: SonarConfig) -> Self:
        """The fault model of a sonar section (all off in the paper scenario)."""
        s = config
        half_angle = s.beam_half_angle_deg
        return cls(
            max_range=s.max_range,
            beam_half_angle=None if half_angle is None else math.radians(half_angle),
            dropout_probability=tuple(s.dropout_probability),
            outlier_probability=s.outlier_probability,
            outlier_scale=s.outlier_scale,
            search_sigma=s.search_sigma,
        )


@dataclass
class _Measurement:
    range_samples: np.ndarray  # (2, f); NaN where a sonar has no return
    Y: float  # NaN unless both sonars returned
    m: float
    Gamma: float
    b_W: np.ndarray  # (3,)
    status: np.ndarray  # (2,) VALID, DROPPED, OUT_OF_BEAM or OUT_OF_RANGE
    multipath: np.ndarray  # (2,) the true multipath excess [m], 0 without an outlier


class DualSonar(LeafSystem):
    """Ranges from two sonars to the target, and the paper's linearised measurement.

    Sonar s1 sits at ``p_WU + ½ q_s`` and s2 at ``p_WU − ½ q_s``, with the world baseline
    ``q_s = R_WB b`` (the paper's symbol; the port is ``b_W``). Each returns ``f`` samples
    ``d_i = |p_WS_i − p_WT| + v``, ``v ~ N(0, η_i)``; the first sample forms
    ``Y = ½(d1² − d2²) = q_sᵀ q + v̄`` and all ``f`` estimate ``d̄²`` for the noise variance
    ``Γ`` (:func:`~drake_uuv.models.measurement.range_difference_noise`).

    .. pydrake_system::

        name: DualSonar
        input_ports:
        - p_WU
        - R_WB
        - p_WT
        - range_noise
        - x_TU_prior (with a beam)
        - P_TU_prior (with a beam)
        - fault_uniform (with dropouts or outliers)
        - multipath_noise (with dropouts or outliers)
        output_ports:
        - ranges
        - range_samples
        - Y
        - m
        - Gamma
        - b_W
        - sonar_status
        - multipath

    - ``p_WU`` (3), the vehicle's body origin; ``R_WB`` (9, row-major); ``p_WT`` (3), the
      target.
    - ``range_noise`` (2f, random, standard normal): scaled here by ``√η_i``.
    - ``ranges`` (2): the first sample of each sonar, ``[d1, d2]`` [m].
    - ``range_samples`` (2f): all samples, sonar 1's then sonar 2's [m].
    - ``Y``, ``m``, ``Gamma`` (1 each): the measurement, its noise mean and variance.
    - ``b_W`` (3): the world baseline ``q_s = R_WB b`` (so ``C(k) = [q_sᵀ, 0]``).
    - ``sonar_status`` (2): per sonar, ``VALID``, ``DROPPED``, ``OUT_OF_BEAM`` or ``OUT_OF_RANGE``.
      A sonar without a return has NaN ranges, and ``Y``, ``m``, ``Gamma`` are NaN unless
      both returned.
    - ``multipath`` (2): ground truth for analysis, the excess added to each sonar's return.

    Faults (:class:`SonarFaults`, all off by default) add ports only when switched on:
    ``x_TU_prior`` (6) and ``P_TU_prior`` (36), the estimator's prediction the pan-tilts point
    at, the random ports ``fault_uniform`` (4, uniform: dropout then outlier draws per sonar) and
    ``multipath_noise`` (2, exponential).

    ``config`` (:class:`~drake_uuv.scenario.SonarConfig`) gives the baseline b, the noise
    variances η, the samples per step f and the faults (:meth:`SonarFaults.from_config`);
    ``noise_model`` is the model of ``Y``'s noise that ``m`` and ``Γ`` follow
    (:data:`~drake_uuv.scenario.NOISE_MODELS`): the estimator's, which the builder passes
    from the scenario's estimator section.
    """

    def __init__(self, config: SonarConfig, *, noise_model: str) -> None:
        super().__init__()
        self._faults = SonarFaults.from_config(config)
        self._b = np.asarray(config.baseline, dtype=float)
        self._eta = np.asarray(config.noise_variances, dtype=float)
        self._sigma = np.sqrt(self._eta)[:, np.newaxis]
        self._f = int(config.samples_per_step)
        self._noise_model = noise_model
        range_difference_noise(noise_model, self._eta, np.ones(2))  # Fail early on a bad model.
        # The derived model's constants, computed as range_difference_noise computes them.
        self._derived_m, gamma_at_zero = range_difference_noise(
            "derived", self._eta, np.zeros(2) + self._eta
        )
        self._derived_gamma_floor = float(gamma_at_zero)
        self._derived_m = float(self._derived_m)
        self._eta_floats = tuple(float(e) for e in self._eta)

        self._uuv_port = self.DeclareVectorInputPort("p_WU", 3)
        self._attitude_port = self.DeclareVectorInputPort("R_WB", 9)
        self._target_port = self.DeclareVectorInputPort("p_WT", 3)
        self._noise_port = declare_random_input(
            self, "range_noise", 2 * self._f, RandomDistribution.kGaussian
        )
        self._prior_port = self._prior_covariance_port = None
        if self._faults.beam_half_angle is not None:
            self._prior_port = self.DeclareVectorInputPort("x_TU_prior", 6)
            self._prior_covariance_port = self.DeclareVectorInputPort("P_TU_prior", 36)
        if self._faults.random_faults:
            self._uniform_port = declare_random_input(
                self, "fault_uniform", 4, RandomDistribution.kUniform
            )
            self._multipath_port = declare_random_input(
                self, "multipath_noise", 2, RandomDistribution.kExponential
            )
        # One measurement per context, shared by every output port.
        self._measurement = self.DeclareCacheEntry(
            "measurement",
            ValueProducer(
                allocate=AbstractValue.Make(
                    _Measurement(
                        np.zeros((2, self._f)), 0, 0, 0, np.zeros(3), np.zeros(2), np.zeros(2)
                    )
                ).Clone,
                calc=self._calc_measurement,
            ),
            {self.all_input_ports_ticket()},
        )
        depends = {self._measurement.ticket()}
        self.DeclareVectorOutputPort("ranges", 2, self._calc_ranges, depends)
        self.DeclareVectorOutputPort("range_samples", 2 * self._f, self._calc_samples, depends)
        self.DeclareVectorOutputPort("Y", 1, self._calc_Y, depends)
        self.DeclareVectorOutputPort("m", 1, self._calc_m, depends)
        self.DeclareVectorOutputPort("Gamma", 1, self._calc_Gamma, depends)
        self.DeclareVectorOutputPort("b_W", 3, self._calc_b_W, depends)
        self.DeclareVectorOutputPort("sonar_status", 2, self._calc_status, depends)
        self.DeclareVectorOutputPort("multipath", 2, self._calc_multipath, depends)

    @property
    def faults(self) -> SonarFaults:
        return self._faults

    def _calc_measurement(self, context: Context, value: AbstractValue) -> None:
        p_WU = self._uuv_port.Eval(context)
        p_WT = self._target_port.Eval(context)
        q_s = self._attitude_port.Eval(context).reshape(3, 3) @ self._b
        q = p_WU - p_WT
        half = 0.5 * q_s
        to_s1, to_s2 = q + half, q - half
        true_ranges = np.array([math.sqrt(float(to_s1 @ to_s1)), math.sqrt(float(to_s2 @ to_s2))])
        noise = self._noise_port.Eval(context).reshape(2, self._f)
        samples = true_ranges[:, np.newaxis] + self._sigma * noise
        status = np.zeros(2)
        multipath = np.zeros(2)
        faulty = False
        if self._prior_port is not None or self._faults.max_range is not None:
            status = self._geometry_status(context, q, q_s, true_ranges)
            faulty = True
        if self._faults.random_faults:
            uniform = self._uniform_port.Eval(context)
            dropped = uniform[:2] < self._faults.dropout_probability
            status[(status == VALID) & dropped] = DROPPED
            outlier = uniform[2:] < self._faults.outlier_probability
            multipath = np.where(
                outlier, self._faults.outlier_scale * self._multipath_port.Eval(context), 0.0
            )
            samples += multipath[:, np.newaxis]
            faulty = True
        if faulty and status.any():
            samples[status != VALID] = np.nan
        if self._f == 1 and self._noise_model == "derived":
            # The same arithmetic as below on Python floats (a sum of one sample is that
            # sample; dividing by 1 changes nothing), without a dozen numpy calls.
            d1, d2 = samples.ravel().tolist()
            eta1, eta2 = self._eta_floats
            m = self._derived_m
            gamma = (
                eta1 * _clip_at_zero(d1 * d1 - eta1)
                + eta2 * _clip_at_zero(d2 * d2 - eta2)
                + self._derived_gamma_floor
            )
        else:
            d1, d2 = samples[:, 0]
            mean_squares = (samples * samples).sum(axis=1) / self._f
            m, gamma = range_difference_noise(self._noise_model, self._eta, mean_squares)
        value.set_value(
            _Measurement(samples, 0.5 * (d1 * d1 - d2 * d2), m, gamma, q_s, status, multipath)
        )

    def _geometry_status(
        self, context: Context, q: np.ndarray, q_s: np.ndarray, true_ranges: np.ndarray
    ) -> np.ndarray:
        """OUT_OF_RANGE / OUT_OF_BEAM per sonar from the true and the pointed-at target."""
        status = np.zeros(2)
        if self._faults.max_range is not None:
            status[true_ranges > self._faults.max_range] = OUT_OF_RANGE
        if self._prior_port is not None:
            q_prior = self._prior_port.Eval(context)[:3]
            P_position = self._prior_covariance_port.Eval(context).reshape(6, 6)[:3, :3]
            search_radius = self._faults.search_sigma * math.sqrt(
                max(np.linalg.eigvalsh(P_position)[-1], 0.0)
            )
            for i, offset in enumerate((0.5 * q_s, -0.5 * q_s)):
                to_target = -(q + offset)  # from sonar i to the true target
                axis = -(q_prior + offset)  # from sonar i to the predicted target
                distance = norm(axis)
                half_angle = max(
                    self._faults.beam_half_angle,
                    math.pi if search_radius >= distance else math.asin(search_radius / distance),
                )
                cos_angle = (to_target @ axis) / (norm(to_target) * distance + 1e-300)
                if status[i] == VALID and cos_angle < math.cos(half_angle):
                    status[i] = OUT_OF_BEAM
        return status

    def _calc_ranges(self, context: Context, output: BasicVector) -> None:
        output.set_value(self._measurement.Eval(context).range_samples[:, 0])

    def _calc_samples(self, context: Context, output: BasicVector) -> None:
        output.set_value(self._measurement.Eval(context).range_samples.ravel())

    def _calc_Y(self, context: Context, output: BasicVector) -> None:
        output.SetAtIndex(0, self._measurement.Eval(context).Y)

    def _calc_m(self, context: Context, output: BasicVector) -> None:
        output.SetAtIndex(0, self._measurement.Eval(context).m)

    def _calc_Gamma(self, context: Context, output: BasicVector) -> None:
        output.SetAtIndex(0, self._measurement.Eval(context).Gamma)

    def _calc_b_W(self, context: Context, output: BasicVector) -> None:
        output.set_value(self._measurement.Eval(context).b_W)

    def _calc_status(self, context: Context, output: BasicVector) -> None:
        output.set_value(self._measurement.Eval(context).status)

    def _calc_multipath(self, context: Context, output: BasicVector) -> None:
        output.set_value(self._measurement.Eval(context).multipath)
