"""Two monostatic sonars at ±½ b about the body origin, and the linear measurement Y."""

import copy
import math
from dataclasses import dataclass

import numpy as np
from pydrake.common import RandomDistribution
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import (
    BasicVector,
    Context,
    Diagram,
    DiagramBuilder,
    DiscreteValues,
    LeafSystem,
    ValueProducer,
)
from pydrake.systems.primitives import Demultiplexer

from drake_uuv.models.measurement import NO_ARRIVAL, VALID, range_difference_noise
from drake_uuv.primitives.random_input import declare_random_input, export_random_inputs
from drake_uuv.primitives.setting import time_step_field
from drake_uuv.scenario.schema import SonarConfig
from drake_uuv.sensors.sonar_faults import SonarFaults, geometry_status, random_faults
from drake_uuv.sensors.sonar_timing import (
    PingGeometry,
    Pings,
    TickGeometry,
    arrival_delays,
    fifo_push,
    ping_between,
    tick_ping,
)

_NAN = math.nan
_NAN3 = np.full(3, math.nan)
_NAN3.setflags(write=False)


def _clip_at_zero(x: float) -> float:
    """``np.maximum(x, 0.0)`` for a float (NaN stays NaN)."""
    return x if x > 0.0 or x != x else 0.0


@dataclass
class _Measurement:
    arrivals: Pings  # the ranges arriving at this tick
    Y: float  # NaN unless both sonars' ranges arrived and returned
    m: float
    Gamma: float
    b_W: np.ndarray  # (3,) the tick's world baseline
    measured: Pings  # the pings measured at this tick (those a FIFO takes in)
    tick: TickGeometry | None  # this tick's geometry, with timing (the next tick's previous)


def output_layout(samples_per_step: int) -> tuple[tuple[str, int], ...]:
    """The sonar's output ports and their sizes, in the order of the packed ``measurement``."""
    f = samples_per_step
    return (
        ("ranges", 2), ("range_samples", 2 * f), ("Y", 1), ("m", 1), ("Gamma", 1), ("b_W", 3),
        ("sonar_status", 2), ("multipath", 2), ("ping_time", 2), ("p_TS_W", 6),
    )  # fmt: skip


class DualSonar(Diagram):
    """Ranges from two sonars to the target, and the paper's linearised measurement.

    Sonar s1 sits at ``p_WU + ½ q_s`` and s2 at ``p_WU − ½ q_s``, with the world baseline
    ``q_s = R_WB b`` (the paper's symbol; the port is ``b_W``). Each returns ``f`` samples
    ``d_i = (1 + ε)|p_WS_i − p_WT| + v``, ``v ~ N(0, η_i)``, with ``ε`` the sound-speed error
    (0 in the paper); the first sample forms ``Y = ½(d1² − d2²) = q_sᵀ q + v̄`` and all
    ``f`` estimate ``d̄²`` for the noise variance ``Γ``
    (:func:`~drake_uuv.models.measurement.range_difference_noise`).

    .. pydrake_system::

        name: DualSonar
        input_ports:
        - p_WU
        - R_WB
        - p_WT
        - range_noise
        - v_WU (with timing)
        - v_WT (with timing)
        - x_TU_prior (with a beam)
        - R_WB_nav (with a beam)
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
        - ping_time
        - p_TS_W

    - ``p_WU``, ``v_WU`` (3 each), the vehicle's body origin and its velocity; ``R_WB`` (9,
      row-major); ``p_WT``, ``v_WT`` (3 each), the target.
    - ``range_noise`` (2f, random, standard normal): scaled here by ``√η_i``.

    The outputs of a tick describe the ranges *arriving* at it (the ping's, with timing):

    - ``ranges`` (2): the first sample of each sonar, ``[d1, d2]`` [m].
    - ``range_samples`` (2f): all samples, sonar 1's then sonar 2's [m].
    - ``Y``, ``m``, ``Gamma`` (1 each): the measurement, its noise mean and variance.
    - ``b_W`` (3): the tick's true world baseline ``q_s = R_WB b`` (so ``C(k) = [q_sᵀ, 0]``).
    - ``sonar_status`` (2): per sonar, ``VALID``, ``DROPPED``, ``OUT_OF_BEAM``,
      ``OUT_OF_RANGE``, or ``NO_ARRIVAL`` (no ping of the sonar is due at this tick: the first
      ticks with latency). A sonar without a return has NaN ranges, and ``Y``, ``m``,
      ``Gamma`` are NaN unless both returned.
    - ``multipath`` (2): ground truth for analysis, the excess added to each sonar's return.
    - ``ping_time`` (2) [s]: when each arriving range's ping was sent (NaN with NO_ARRIVAL).
    - ``p_TS_W`` (6) [m]: ground truth, each arriving range's sonar from the target at its
      ping, ``q ± ½ q_s`` then, in W (s1's three, then s2's; NaN with NO_ARRIVAL).

    **Timing** (``config.ping_offsets`` τ_i, ``config.latency`` L;
    :mod:`~drake_uuv.sensors.sonar_timing`): sonar i pings at ``t_k + τ_i`` in step k and its
    range arrives at tick ``k + d_i``, ``d_i = ⌈(τ_i + L)/t⌉``. With ``τ_i = L = 0`` (the
    paper's, the default) the range is measured at the tick from the inputs (direct
    feedthrough, no state). Otherwise the sonar keeps the previous tick's geometry (the truth
    and the estimator's prediction) as discrete state: at tick k+1 it measures the ping of
    step k from the geometry of ticks k and k+1 (:func:`~drake_uuv.sensors.sonar_timing.
    ping_between`: Hermite positions, geodesic attitude), with the noise drawn at tick k+1,
    and holds it in a FIFO (discrete state) until tick ``k + d_i``; the velocity inputs exist
    only then. The interpolation is exact for the kinematic plant and the target (constant
    acceleration and world rate over a step); for the hovering UUV, a continuous plant, it
    is an approximation. In the flyable configuration (the vehicle study's feasible
    overrides, 500 steps, seed 1) a ping at τ = 0.25 s of the 0.5 s step puts the sonar at
    most 0.009 m from where the vehicle's true state at that time puts it (attitude: at most
    0.014 rad), and its range is off by at most 0.0081 m (RMS 0.0007 m), a twelfth of the
    paper's 0.1 m range noise (``python benchmarks/bench_ping_interpolation.py --offset
    0.25``); pings soon after the tick are off more, those late in the step less: at most
    0.0135 m at τ = 0.1 s, 0.0023 m at τ = 0.4 s.

    **Faults** (:class:`~drake_uuv.sensors.sonar_faults.SonarFaults`, all off by default)
    apply to each ping's own geometry and add ports only when switched on: ``x_TU_prior``
    (6) and ``P_TU_prior`` (36), the estimator's prediction of the ping's tick, which the
    pan-tilts point at (by the attitude of
    :func:`~drake_uuv.sensors.sonar_faults.pointing_attitude`); the random ports
    ``fault_uniform`` (4, uniform: dropout then outlier draws per sonar) and
    ``multipath_noise`` (2, exponential), drawn when the ping is measured.

    ``config`` (:class:`~drake_uuv.scenario.SonarConfig`) gives the baseline b, the noise
    variances η, the samples per step f, the timing, the sound-speed error ε and the faults
    (:meth:`SonarFaults.from_config`); ``noise_model`` is the model of ``Y``'s noise that
    ``m`` and ``Γ`` follow (:data:`~drake_uuv.scenario.NOISE_MODELS`): the estimator's, which
    the builder passes from the scenario's estimator section; ``time_step`` is the period t
    [s] of the loop's ticks.

    Inside, a :class:`SonarMeasurement` (``measurement``) computes every output of a tick in
    one call, and a Drake ``Demultiplexer`` (``outputs``) splits it into the ports: one Python
    call per tick however many of them are read.
    """

    def __init__(self, config: SonarConfig, *, noise_model: str, time_step: float) -> None:
        super().__init__()
        builder = DiagramBuilder()
        model = builder.AddNamedSystem(
            "measurement", SonarMeasurement(config, noise_model=noise_model, time_step=time_step)
        )
        layout = output_layout(config.samples_per_step)
        split = builder.AddNamedSystem("outputs", Demultiplexer([size for _, size in layout]))
        builder.Connect(model.get_output_port(), split.get_input_port())
        for i in range(model.num_input_ports()):
            port = model.get_input_port(i)
            builder.ExportInput(port, port.get_name())
        for i, (name, _) in enumerate(layout):
            builder.ExportOutput(split.get_output_port(i), name)
        builder.BuildInto(self)
        export_random_inputs(self, model)
        self._model = model

    @property
    def faults(self) -> SonarFaults:
        return self._model.faults

    @property
    def delays(self) -> tuple[int, int]:
        """``(d_1, d_2)``: the ticks from each sonar's step to the arrival of its range."""
        return self._model.delays


class SonarMeasurement(LeafSystem):
    """The dual sonar's measurement of a tick, every output of :class:`DualSonar` in one
    vector (the model; :class:`DualSonar` is the system of the loop).

    .. pydrake_system::

        name: SonarMeasurement
        input_ports: [p_WU, R_WB, p_WT, range_noise, v_WU (with timing), v_WT (with timing),
                      x_TU_prior (with a beam), R_WB_nav (with a beam), P_TU_prior (with a beam),
                      fault_uniform (with dropouts or outliers),
                      multipath_noise (with dropouts or outliers)]
        output_ports: [measurement]

    The inputs are :class:`DualSonar`'s; ``measurement`` holds its outputs end to end in the
    order of :func:`output_layout`. Without timing the output is computed from the inputs at
    once; with timing, from a cache entry the update shares.
    """

    def __init__(self, config: SonarConfig, *, noise_model: str, time_step: float) -> None:
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
        self._scale = 1.0 + float(config.sound_speed_error)
        self._time_step = time_step_field(time_step)
        self._tau = tuple(float(tau) for tau in config.ping_offsets)
        self._delays = arrival_delays(self._tau, float(config.latency), self._time_step)

        self._uuv_port = self.DeclareVectorInputPort("p_WU", 3)
        self._attitude_port = self.DeclareVectorInputPort("R_WB", 9)
        self._target_port = self.DeclareVectorInputPort("p_WT", 3)
        self._noise_port = declare_random_input(
            self, "range_noise", 2 * self._f, RandomDistribution.kGaussian
        )
        self._prior_port = self._prior_covariance_port = None
        if self._faults.beam_half_angle is not None:
            self._prior_port = self.DeclareVectorInputPort("x_TU_prior", 6)
            # The pan-tilts point by the attitude the vehicle believes it has.
            self._pointing_attitude_port = self.DeclareVectorInputPort("R_WB_nav", 9)
            self._prior_covariance_port = self.DeclareVectorInputPort("P_TU_prior", 36)
        if self._faults.random_faults:
            self._uniform_port = declare_random_input(
                self, "fault_uniform", 4, RandomDistribution.kUniform
            )
            self._multipath_port = declare_random_input(
                self, "multipath_noise", 2, RandomDistribution.kExponential
            )
        self._declare_timing()
        # With timing, the output and the update share one measurement per context.
        nan2 = np.full(2, math.nan)
        empty = Pings(np.zeros((2, self._f)), nan2, nan2, nan2, np.zeros((2, 3)))
        self._measurement = self.DeclareCacheEntry(
            "measurement",
            ValueProducer(
                allocate=AbstractValue.Make(
                    _Measurement(empty, 0.0, 0.0, 0.0, np.zeros(3), empty, None)
                ).Clone,
                calc=self._calc_measurement,
            ),
            {self.all_sources_ticket()},
        )
        size = sum(n for _, n in output_layout(self._f))
        if self._timed:  # the update reads the same measurement
            self.DeclareVectorOutputPort(
                "measurement", size, self._calc_timed_output, {self._measurement.ticket()}
            )
        else:
            # Without timing, faults or a beam every ping is at the tick and every range
            # returns: the output straight from the inputs (the same arithmetic, no pings).
            plain = self._prior_port is None and self._faults.max_range is None
            plain = plain and not self._faults.random_faults
            calc = self._calc_plain_output if plain else self._calc_output
            self.DeclareVectorOutputPort("measurement", size, calc, {self.all_sources_ticket()})

    def _declare_timing(self) -> None:
        """With timing: the velocity inputs, the previous tick's geometry, one FIFO per sonar
        whose ranges wait a tick or more after they are measured, and the update."""
        self._timed = max(self._delays) > 0
        self._fifo_index: dict[int, int] = {}
        if not self._timed:
            return
        self._uuv_velocity_port = self.DeclareVectorInputPort("v_WU", 3)
        self._target_velocity_port = self.DeclareVectorInputPort("v_WT", 3)
        self._previous_index = self.DeclareDiscreteState(TickGeometry.before_start().to_vector())
        for i, d in enumerate(self._delays):
            if d >= 2:  # a ping of step k is measured at tick k + 1 and read at k + d
                empty = Pings.no_arrival_entry(self._f)
                self._fifo_index[i] = self.DeclareDiscreteState(np.tile(empty, d - 1))
        self.DeclarePeriodicDiscreteUpdateEvent(self._time_step, 0.0, self._advance)

    @property
    def faults(self) -> SonarFaults:
        return self._faults

    @property
    def delays(self) -> tuple[int, int]:
        """``(d_1, d_2)``: the ticks from each sonar's step to the arrival of its range."""
        return self._delays

    def _calc_measurement(self, context: Context, value: AbstractValue) -> None:
        value.set_value(self._measurement_at(context))

    def _calc_output(self, context: Context, output: BasicVector) -> None:
        output.set_value(self._packed(self._measurement_at(context)))

    def _calc_timed_output(self, context: Context, output: BasicVector) -> None:
        output.set_value(self._packed(self._measurement.Eval(context)))

    def _calc_plain_output(self, context: Context, output: BasicVector) -> None:
        """:meth:`_calc_output` of a sonar without timing, faults or a beam: both pings at
        the tick (:func:`tick_ping`'s ``q ± ½ q_s``), both ranges returned, status VALID."""
        R_WB = self._attitude_port.Eval(context).reshape(3, 3)
        q_s = R_WB @ self._b
        q = self._uuv_port.Eval(context) - self._target_port.Eval(context)
        half = 0.5 * q_s
        p_TS_W = (q + half, q + -half)
        true_ranges = np.array([math.sqrt(float(p @ p)) for p in p_TS_W])
        measured = true_ranges if self._scale == 1.0 else self._scale * true_ranges
        noise = self._noise_port.Eval(context).reshape(2, self._f)
        samples = measured[:, np.newaxis] + self._sigma * noise
        Y, m, gamma = self._paper_measurement(samples)
        now = context.get_time()
        output.set_value(
            np.concatenate(
                (
                    samples[:, 0], samples.ravel(), (Y, m, gamma), q_s,
                    (0.0, 0.0, 0.0, 0.0, now, now), p_TS_W[0], p_TS_W[1],
                )
            )
        )  # fmt: skip

    @staticmethod
    def _packed(measurement: _Measurement) -> np.ndarray:
        """The outputs of :func:`output_layout`, end to end."""
        a = measurement.arrivals
        return np.concatenate(
            (
                a.samples[:, 0], a.samples.ravel(),
                (measurement.Y, measurement.m, measurement.Gamma), measurement.b_W,
                a.status, a.multipath, a.time, a.p_TS_W.ravel(),
            )
        )  # fmt: skip

    def _measurement_at(self, context: Context) -> _Measurement:
        """The tick's measurement: the arriving pings, Y, m, Γ, the baseline, the geometry."""
        p_WU = self._uuv_port.Eval(context)
        p_WT = self._target_port.Eval(context)
        R_WB = self._attitude_port.Eval(context).reshape(3, 3)
        q_s = R_WB @ self._b
        q = p_WU - p_WT
        now = context.get_time()
        q_prior, radius = self._pointing(context)
        R_point = R_WB
        if self._prior_port is not None:
            R_point = self._pointing_attitude_port.Eval(context).reshape(3, 3)
        tick = previous = None
        if self._timed:
            tick = TickGeometry(
                now, p_WU, self._uuv_velocity_port.Eval(context), R_WB, p_WT,
                self._target_velocity_port.Eval(context), q_prior, radius, R_point,
            )  # fmt: skip
            previous = TickGeometry.from_vector(
                context.get_discrete_state(self._previous_index).value()
            )
            if math.isnan(previous.time):
                previous = None  # the first tick: no ping between ticks yet
        pings: list[PingGeometry | None] = []
        for i, (tau, d) in enumerate(zip(self._tau, self._delays, strict=True)):
            if d == 0:
                pings.append(tick_ping(i, now, q, R_WB, q_s, q_prior, radius, R_point))
            elif previous is None:
                pings.append(None)
            else:
                pings.append(ping_between(i, tau, previous, tick, self._time_step, self._b))
        measured = self._measure(context, pings)
        arrivals = measured
        if self._fifo_index:
            arrivals = copy.deepcopy(measured)
            n = Pings.entry_size(self._f)
            for i, index in self._fifo_index.items():
                arrivals.set_entry(i, context.get_discrete_state(index).value()[:n])
        Y, m, gamma = self._paper_measurement(arrivals.samples)
        return _Measurement(arrivals, Y, m, gamma, q_s, measured, tick)

    def _pointing(self, context: Context) -> tuple[np.ndarray, float]:
        """The estimator's predicted ``q`` and the radius the pan-tilts scan (NaN without a
        beam)."""
        if self._prior_port is None:
            return _NAN3, math.nan  # nothing to point at
        P_prior = self._prior_covariance_port.Eval(context).reshape(6, 6)
        return self._prior_port.Eval(context)[:3], self._faults.search_radius(P_prior)

    def _measure(self, context: Context, pings: list[PingGeometry | None]) -> Pings:
        """Both sonars' ranges of these pings (None: no ping), with this tick's draws."""
        true_ranges = np.array(
            [0.0 if p is None else math.sqrt(float(p.p_TS_W @ p.p_TS_W)) for p in pings]
        )
        noise = self._noise_port.Eval(context).reshape(2, self._f)
        measured = true_ranges if self._scale == 1.0 else self._scale * true_ranges
        samples = measured[:, np.newaxis] + self._sigma * noise
        status = np.zeros(2)
        multipath = np.zeros(2)
        faulty = False
        if self._prior_port is not None or self._faults.max_range is not None:
            status = geometry_status(self._faults, pings, true_ranges, self._b)
            faulty = True
        if self._faults.random_faults:
            multipath = random_faults(
                self._faults,
                status,
                self._uniform_port.Eval(context),
                self._multipath_port.Eval(context),
            )
            samples += multipath[:, np.newaxis]
            faulty = True
        if any(ping is None for ping in pings):
            missing = np.array([ping is None for ping in pings])
            status[missing], multipath[missing] = NO_ARRIVAL, 0.0
            faulty = True
        times = np.array([_NAN if p is None else p.time for p in pings])
        p_TS_W = np.array([_NAN3 if p is None else p.p_TS_W for p in pings])
        if faulty and status.any():
            samples[status != VALID] = np.nan
        return Pings(samples, status, multipath, times, p_TS_W)

    def _paper_measurement(self, samples: np.ndarray) -> tuple[float, float, float]:
        """``(Y, m, Γ)`` of the arriving samples (2×f)."""
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
        return 0.5 * (d1 * d1 - d2 * d2), m, gamma

    def _advance(self, context: Context, discrete_state: DiscreteValues) -> None:
        """Keeps this tick's geometry for the next tick's pings and moves each FIFO on by
        the ping measured now."""
        measurement = self._measurement.Eval(context)
        discrete_state.set_value(self._previous_index, measurement.tick.to_vector())
        for i, index in self._fifo_index.items():
            fifo = context.get_discrete_state(index).value()
            discrete_state.set_value(index, fifo_push(fifo, measurement.measured.entry(i)))
