"""Two monostatic sonars at ±½ b about the body origin, and the linear measurement Y."""

import math

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

from drake_uuv.models.measurement import range_difference_noise
from drake_uuv.primitives.batch import batch_size_field, per_run, tiled
from drake_uuv.primitives.random_input import declare_random_input, export_random_inputs
from drake_uuv.primitives.setting import time_step_field
from drake_uuv.scenario.schema import SonarConfig
from drake_uuv.sensors import sonar_kernels as kernels
from drake_uuv.sensors.sonar_faults import SonarFaults
from drake_uuv.sensors.sonar_timing import (
    TickGeometry,
    arrival_delays,
    entry_size,
    no_arrival_entry,
)


def output_layout(samples_per_step: int) -> tuple[tuple[str, int], ...]:
    """The sonar's output ports and their sizes per run, in the order of the packed
    ``measurement`` (each output's block holds all B runs)."""
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
      ticks with latency). A sonar without a return has NaN ranges, and ``Y`` and ``Gamma``
      are NaN unless both returned (``m`` is the noise model's constant).
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
    step k from the geometry of ticks k and k+1 (:func:`~drake_uuv.sensors.sonar_kernels.
    measure`: Hermite positions, geodesic attitude), with the noise drawn at tick k+1,
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
    pan-tilts point at (by the navigated attitude ``R_WB_nav`` (9);
    :func:`~drake_uuv.sensors.sonar_geometry.beam_axis`); the random ports
    ``fault_uniform`` (4, uniform: dropout then outlier draws per sonar) and
    ``multipath_noise`` (2, exponential), drawn when the ping is measured.

    ``config`` (:class:`~drake_uuv.scenario.SonarConfig`) gives the baseline b, the noise
    variances η, the samples per step f, the timing, the sound-speed error ε and the faults
    (:meth:`SonarFaults.from_config`); ``noise_model`` is the model of ``Y``'s noise that
    ``m`` and ``Γ`` follow (:data:`~drake_uuv.scenario.NOISE_MODELS`): the estimator's, which
    the builder passes from the scenario's estimator section; ``time_step`` is the period t
    [s] of the loop's ticks.

    Sizes are per run: with ``batch_size`` B every port and state holds B runs row-major
    (:mod:`drake_uuv.primitives.batch`), each run measured alone (its bits do not depend on
    B or its place in the batch; a run with NaN or inf inputs or state gives NaN to itself
    only). The state's initial value (no tick seen, empty FIFOs) is the same for every run.

    Inside, a :class:`SonarMeasurement` (``measurement``) computes every output of a tick for
    every run in one call, and a Drake ``Demultiplexer`` (``outputs``) splits it into the
    ports: one Python call per tick however many of them are read.
    """

    def __init__(
        self, config: SonarConfig, *, noise_model: str, time_step: float, batch_size: int = 1
    ) -> None:
        super().__init__()
        self.batch_size = B = batch_size_field(batch_size)
        builder = DiagramBuilder()
        model = builder.AddNamedSystem(
            "measurement",
            SonarMeasurement(config, noise_model=noise_model, time_step=time_step, batch_size=B),
        )
        layout = output_layout(config.samples_per_step)
        split = builder.AddNamedSystem("outputs", Demultiplexer([B * n for _, n in layout]))
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

    The inputs are :class:`DualSonar`'s, B runs row-major each; ``measurement`` holds its
    outputs one after the other in the order of :func:`output_layout`, each output's block
    the B runs row-major (``ranges`` of every run, then ``range_samples`` of every run, …),
    so that a ``Demultiplexer`` cuts it into :class:`DualSonar`'s ports. Without timing the
    output is computed from the inputs at once; with timing, from a cache entry the update
    shares (the outputs, this tick's geometry and the FIFOs moved on). The arithmetic is
    :mod:`~drake_uuv.sensors.sonar_kernels`': one kernel call per tick for all runs.
    """

    def __init__(
        self, config: SonarConfig, *, noise_model: str, time_step: float, batch_size: int = 1
    ) -> None:
        super().__init__()
        self.batch_size = B = batch_size_field(batch_size)
        self._faults = faults = SonarFaults.from_config(config)
        self._b = np.asarray(config.baseline, dtype=float)
        eta = np.asarray(config.noise_variances, dtype=float)
        self._f = f = int(config.samples_per_step)
        range_difference_noise(noise_model, eta, np.ones(2))  # Fail early on a bad model.
        self._time_step = time_step_field(time_step)
        self._tau = tuple(float(tau) for tau in config.ping_offsets)
        self._delays = arrival_delays(self._tau, float(config.latency), self._time_step)
        self._settings = self._settings_vector(config, noise_model, eta)
        self._timed = max(self._delays) > 0
        self._beam = faults.beam_half_angle is not None
        self._random = faults.random_faults

        self._uuv_port = self.DeclareVectorInputPort("p_WU", 3 * B)
        self._attitude_port = self.DeclareVectorInputPort("R_WB", 9 * B)
        self._target_port = self.DeclareVectorInputPort("p_WT", 3 * B)
        self._noise_port = declare_random_input(
            self, "range_noise", 2 * f, RandomDistribution.kGaussian, batch_size=B
        )
        if self._beam:
            self._prior_port = self.DeclareVectorInputPort("x_TU_prior", 6 * B)
            # The pan-tilts point by the attitude the vehicle believes it has.
            self._pointing_attitude_port = self.DeclareVectorInputPort("R_WB_nav", 9 * B)
            self._prior_covariance_port = self.DeclareVectorInputPort("P_TU_prior", 36 * B)
        if self._random:
            self._uniform_port = declare_random_input(
                self, "fault_uniform", 4, RandomDistribution.kUniform, batch_size=B
            )
            self._multipath_port = declare_random_input(
                self, "multipath_noise", 2, RandomDistribution.kExponential, batch_size=B
            )
        self._size = size = B * sum(n for _, n in output_layout(f))
        self._declare_timing()
        # The kernel's arrays of a feature that is off (never read), and its switches; a
        # state's stand-in read-only as the state is (one compiled signature).
        self._unused = np.zeros((B, 0))
        self._unused_state = np.zeros((B, 0))
        self._unused_state.setflags(write=False)
        self._flags = np.array([self._timed, self._beam, self._random], dtype=np.int64)
        self._delay_array = np.array(self._delays, dtype=np.int64)
        if self._timed:  # the output and the update share one measurement per context
            self._step = self.DeclareCacheEntry(
                "step",
                ValueProducer(
                    allocate=AbstractValue.Make(BasicVector(size + self._state_size)).Clone,
                    calc=self._calc_step,
                ),
                {self.all_sources_ticket()},
            )
            self.DeclareVectorOutputPort(
                "measurement", size, self._calc_timed_output, {self._step.ticket()}
            )
            self.DeclarePeriodicDiscreteUpdateEvent(self._time_step, 0.0, self._advance)
            return
        # Without timing, faults or a beam every ping is at the tick and every range returns:
        # the paper's sonar, a kernel of its own (the same arithmetic, fewer arguments).
        plain = not (self._beam or self._random or faults.max_range is not None)
        calc = self._calc_plain_output if plain else self._calc_output
        self.DeclareVectorOutputPort("measurement", size, calc, {self.all_sources_ticket()})

    def _settings_vector(
        self, config: SonarConfig, noise_model: str, eta: np.ndarray
    ) -> np.ndarray:
        """The kernels' float settings (:data:`~drake_uuv.sensors.sonar_kernels.SETTINGS_SIZE`)."""
        k, faults = kernels, self._faults
        settings = np.zeros(k.SETTINGS_SIZE)
        settings[k.TIME_STEP] = self._time_step
        settings[k.TAU1], settings[k.TAU2] = self._tau
        settings[k.SCALE] = 1.0 + float(config.sound_speed_error)
        settings[k.SIGMA1 : k.SIGMA2 + 1] = np.sqrt(eta)
        settings[k.ETA1 : k.ETA2 + 1] = eta
        # m and Γ's constant term, as range_difference_noise computes them (Γ at zero ranges).
        m, gamma_constant = range_difference_noise(noise_model, eta, np.zeros(2) + eta)
        if noise_model == "paper_printed":
            gamma_constant = 2 * eta[0] ** 2 + 2 * eta[1] ** 2
        settings[k.M], settings[k.GAMMA_CONSTANT] = m, gamma_constant
        settings[k.PAPER_PRINTED] = noise_model == "paper_printed"
        settings[k.MAX_RANGE] = math.inf if faults.max_range is None else faults.max_range
        half_angle = faults.beam_half_angle
        settings[k.BEAM_HALF_ANGLE] = math.nan if half_angle is None else half_angle
        settings[k.DROPOUT1 : k.DROPOUT2 + 1] = faults.dropout_probability
        settings[k.OUTLIER_PROBABILITY] = faults.outlier_probability
        settings[k.OUTLIER_SCALE] = faults.outlier_scale
        settings[k.B0 : k.B2 + 1] = self._b
        return settings

    def _declare_timing(self) -> None:
        """With timing: the velocity inputs, the previous tick's geometry, one FIFO per sonar
        whose ranges wait a tick or more after they are measured (all per run)."""
        B, E = self.batch_size, entry_size(self._f)
        self._fifo_index: dict[int, int] = {}
        self._state_size = 0
        if not self._timed:
            return
        self._uuv_velocity_port = self.DeclareVectorInputPort("v_WU", 3 * B)
        self._target_velocity_port = self.DeclareVectorInputPort("v_WT", 3 * B)
        self._previous_index = self.DeclareDiscreteState(
            tiled(TickGeometry.before_start().to_vector(), B)
        )
        self._state_size = B * TickGeometry.SIZE
        self._fifo_sizes = [0, 0]
        for i, d in enumerate(self._delays):
            if d >= 2:  # a ping of step k is measured at tick k + 1 and read at k + d
                empty = np.tile(no_arrival_entry(self._f), d - 1)
                self._fifo_index[i] = self.DeclareDiscreteState(tiled(empty, B))
                self._fifo_sizes[i] = (d - 1) * E
                self._state_size += B * (d - 1) * E

    @property
    def faults(self) -> SonarFaults:
        return self._faults

    @property
    def delays(self) -> tuple[int, int]:
        """``(d_1, d_2)``: the ticks from each sonar's step to the arrival of its range."""
        return self._delays

    def _tick_inputs(self, context: Context) -> tuple[np.ndarray, ...]:
        """``q_s`` (by numpy's BLAS, as before), ``p_WU``, ``R_WB``, ``p_WT`` and the noise,
        (B, n) each."""
        B = self.batch_size
        R_WB = per_run(self._attitude_port.Eval(context), B)
        q_s = R_WB.reshape(B, 3, 3) @ self._b
        return (
            q_s,
            per_run(self._uuv_port.Eval(context), B),
            R_WB,
            per_run(self._target_port.Eval(context), B),
            per_run(self._noise_port.Eval(context), B),
        )

    def _calc_plain_output(self, context: Context, output: BasicVector) -> None:
        """The paper's sonar: both pings at the tick, both ranges returned, status VALID."""
        q_s, p_WU, _, p_WT, noise = self._tick_inputs(context)
        kernels.measure_plain(
            context.get_time(), q_s, p_WU, p_WT, noise, self._settings, output.get_mutable_value()
        )

    def _calc_output(self, context: Context, output: BasicVector) -> None:
        """Faults or a beam at the paper's timing: the pings at the tick, no state."""
        self._measure(context, output.get_mutable_value(), self._unused, [])

    def _calc_step(self, context: Context, value: AbstractValue) -> None:
        """With timing: the outputs, then the next state (this tick's geometry, the FIFOs)."""
        work = value.get_mutable_value().get_mutable_value()
        B, n = self.batch_size, self._size
        next_previous = work[n : n + B * TickGeometry.SIZE].reshape(B, TickGeometry.SIZE)
        next_fifos, start = [], n + B * TickGeometry.SIZE
        for size in self._fifo_sizes:
            next_fifos.append(work[start : start + B * size].reshape(B, size))
            start += B * size
        self._measure(context, work[:n], next_previous, next_fifos)

    def _calc_timed_output(self, context: Context, output: BasicVector) -> None:
        output.set_value(self._step.Eval(context).value()[: self._size])

    def _measure(
        self,
        context: Context,
        out: np.ndarray,
        next_previous: np.ndarray,
        next_fifos: list[np.ndarray],
    ) -> None:
        """One kernel call for all runs, with what the features that are on read."""
        B, unused = self.batch_size, self._unused
        q_s, p_WU, R_WB, p_WT, noise = self._tick_inputs(context)
        v_WU = v_WT = unused
        previous = self._unused_state
        fifos = [previous, previous]
        if self._timed:
            v_WU = per_run(self._uuv_velocity_port.Eval(context), B)
            v_WT = per_run(self._target_velocity_port.Eval(context), B)
            previous = per_run(context.get_discrete_state(self._previous_index).value(), B)
            for i, index in self._fifo_index.items():
                fifos[i] = per_run(context.get_discrete_state(index).value(), B)
        else:
            next_fifos = [unused, unused]
        prior = R_nav = radius = uniform = exponential = unused
        if self._beam:
            prior = per_run(self._prior_port.Eval(context), B)
            R_nav = per_run(self._pointing_attitude_port.Eval(context), B)
            P_prior = per_run(self._prior_covariance_port.Eval(context), B, 6, 6)
            radius = self._faults.search_radii(P_prior).reshape(B, 1)
        if self._random:
            uniform = per_run(self._uniform_port.Eval(context), B)
            exponential = per_run(self._multipath_port.Eval(context), B)
        kernels.measure(
            context.get_time(), q_s, p_WU, R_WB, p_WT, noise, v_WU, v_WT, previous, prior,
            R_nav, radius, uniform, exponential, fifos[0], fifos[1], self._delay_array,
            self._flags, self._settings, out, next_previous, next_fifos[0], next_fifos[1],
        )  # fmt: skip

    def _advance(self, context: Context, discrete_state: DiscreteValues) -> None:
        """Keeps this tick's geometry for the next tick's pings and moves each FIFO on by
        the ping measured now."""
        work = self._step.Eval(context).value()
        B, start = self.batch_size, self._size
        end = start + B * TickGeometry.SIZE
        discrete_state.set_value(self._previous_index, work[start:end])
        for i, size in enumerate(self._fifo_sizes):
            start, end = end, end + B * size
            if i in self._fifo_index:
                discrete_state.set_value(self._fifo_index[i], work[start:end])
