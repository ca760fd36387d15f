"""A recording replayed through the estimator slot: the replay diagram and its run.

The diagram is the loop's estimator (any variant of the scenario's estimator section, built by
its factory) fed by a :class:`RecordingSource` instead of the sonar, the navigation and the
tracking controller: the same port names, so the estimator cannot tell a replay from a run.
It is driven on the recording's clock at the scenario's step (:mod:`.reader`); each range
reaches the estimator at its arrival tick with its own ping time, through the estimator's
sonar-timing path, whose ping offsets and latency come from the recording's stamps.
"""

import dataclasses
import math
import time
from pathlib import Path

import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import (
    BasicVector,
    Context,
    DiagramBuilder,
    DiscreteValues,
    LeafSystem,
)
from pydrake.systems.primitives import LogVectorOutput

from drake_uuv.diagnostics import RunWarning
from drake_uuv.diagram import UuvDiagram
from drake_uuv.estimators import make_estimator
from drake_uuv.metrics import errors, rms_norm
from drake_uuv.models.measurement import VALID
from drake_uuv.monitor import EstimatorHealthMonitor, SimulationFailure
from drake_uuv.primitives import random_inputs
from drake_uuv.primitives.batch import batch_size_field
from drake_uuv.primitives.run_noise import RunNoise
from drake_uuv.primitives.threads import one_blas_thread
from drake_uuv.recordings.layout import RecordingError, Topics
from drake_uuv.recordings.reader import Recording, read_recording
from drake_uuv.scenario import Scenario
from drake_uuv.signals import SIGNAL_BY_NAME
from drake_uuv.simulation import SimulationResult, log_from_loggers

#: What a :class:`RecordingSource` outputs: the estimator's inputs, by the loop's names.
SOURCE_SIGNALS = (
    "range_samples", "sonar_status", "ping_time", "R_WB_nav", "p_WU_nav", "v_WU_nav", "u1_W",
)  # fmt: skip


class RecordingSource(LeafSystem):
    """A recording's per-tick values on the loop's ports: what the sonar, the navigation and
    the tracking controller give the estimator in a run.

    .. pydrake_system::

        name: RecordingSource
        output_ports:
        - range_samples
        - sonar_status
        - ping_time
        - R_WB_nav
        - p_WU_nav
        - v_WU_nav
        - u1_W

    At time ``t`` each port holds row ``k = round(t / time_step)`` of the recording's array of
    its name (:class:`~drake_uuv.recordings.reader.Recording`), the last row after the end.
    Before the diagram's initialization (discrete state ``started`` 0, set to 1 by an
    initialization event) the navigation's ports hold the recording's ``initial`` navigation
    instead: what an estimator's initialization reads, as in the run. ``batch_size`` must be
    1: a recording is one run.
    """

    def __init__(self, recording: Recording, *, batch_size: int = 1) -> None:
        super().__init__()
        if batch_size_field(batch_size) != 1:
            raise ValueError(f"batch_size: a recording replays as one run, got {batch_size}")
        self.batch_size = 1
        self._t = recording.time_step
        self._last = recording.steps - 1
        self._started = self.DeclareDiscreteState(1)
        self.DeclareInitializationDiscreteUpdateEvent(self._start)
        for name in SOURCE_SIGNALS:
            rows = np.asarray(getattr(recording, name), dtype=float).reshape(recording.steps, -1)
            initial = recording.initial.get(name)
            self.DeclareVectorOutputPort(
                name,
                BasicVector(rows.shape[1]),
                lambda context, out, rows=rows, initial=initial: out.SetFromVector(
                    self._row(context, rows, initial)
                ),
                {self.time_ticket(), self.xd_ticket()},
            )

    def _start(self, context: Context, discrete_state: DiscreteValues) -> None:
        discrete_state.set_value(self._started, [1.0])

    def _row(self, context: Context, rows: np.ndarray, initial: np.ndarray | None) -> np.ndarray:
        if initial is not None and context.get_discrete_state(self._started)[0] == 0.0:
            return initial
        return rows[min(round(context.get_time() / self._t), self._last)]


def replay_scenario(scenario: Scenario, recording: Recording) -> Scenario:
    """``scenario`` with what the recording says of itself: its steps, the sonars' baseline
    (the mounting), their ping offsets and latency (the stamps)."""
    sonar = dataclasses.replace(
        scenario.sonar,
        baseline=[float(x) for x in recording.baseline],
        ping_offsets=list(recording.ping_offsets),
        latency=recording.latency,
    )
    return dataclasses.replace(scenario, sonar=sonar, steps=recording.steps)


def commands_needed(scenario: Scenario) -> bool:
    """Whether the scenario's estimator reads the commanded acceleration ``u1_W``."""
    return getattr(scenario.estimator, "vehicle_motion", "commanded") == "commanded"


def replay(
    path: str | Path,
    scenario: Scenario,
    *,
    topics: Topics | None = None,
    recording: Recording | None = None,
) -> SimulationResult:
    """Replays the recording at ``path`` (or an already read ``recording``) through the
    estimator of ``scenario`` (seeded by its ``random_seed``, for a particle filter's draws).

    Returns the replay's log (the estimator's outputs, the recording's inputs to it, the truth
    where recorded, ``k`` and ``time`` from 0), metrics (against the truth where recorded) and
    the recording's warnings. A run the estimator-health monitor stops raises
    :class:`~drake_uuv.monitor.SimulationFailure`.
    """
    start = time.perf_counter()
    if recording is None:
        recording = read_recording(
            path,
            time_step=scenario.time_step,
            samples_per_step=scenario.sonar.samples_per_step,
            topics=topics,
            commands=commands_needed(scenario),
        )
    scenario = replay_scenario(scenario, recording)
    built = make_replay_diagram(scenario, recording)
    simulator = Simulator(built.diagram)
    context = simulator.get_mutable_context()
    built.set_random_context(context, scenario.random_seed)
    monitor = EstimatorHealthMonitor(built.systems["estimator"], scenario.time_step)
    simulator.set_monitor(monitor)
    try:
        with one_blas_thread():  # as a simulated run steps: the same bits
            simulator.Initialize()
            simulator.AdvanceTo((recording.steps - 1) * scenario.time_step)
    except RuntimeError as e:
        if monitor.failure is None:
            raise
        raise SimulationFailure(
            f"replay of {str(recording.path)!r} stopped: {monitor.failure}"
        ) from e
    log = {
        name: value[0] if name not in ("k", "time") else value
        for name, value in log_from_loggers(built, context, recording.steps).items()
    }
    log.update(_inputs(recording, scenario))
    metrics = replay_metrics(log, scenario)
    metrics.update(wall_time_s=time.perf_counter() - start, seed=float(scenario.random_seed))
    warnings = [RunWarning("recording", w) for w in recording.warnings]
    return SimulationResult(scenario=scenario, log=log, metrics=metrics, warnings=warnings)


def make_replay_diagram(scenario: Scenario, recording: Recording) -> UuvDiagram:
    """The scenario's estimator fed by a :class:`RecordingSource` (named ``recording``); its
    random ports from per-run noise, as the loop's builder does; a logger per logged output
    of the estimator (``log_<name>``). An estimator input the recording does not give is
    refused naming it."""
    t = scenario.time_step
    builder = DiagramBuilder()
    source = builder.AddNamedSystem("recording", RecordingSource(recording))
    estimator = builder.AddNamedSystem("estimator", make_estimator(scenario))
    random = random_inputs(estimator)
    noise = []
    for i in range(estimator.num_input_ports()):
        port = estimator.get_input_port(i)
        name = port.get_name()
        if name in random:
            runs = RunNoise(name, random[name], port.size(), time_step=t)
            builder.AddNamedSystem(name, runs)
            builder.Connect(runs.get_output_port(), port)
            noise.append(runs)
        elif source.HasOutputPort(name):
            builder.Connect(source.GetOutputPort(name), port)
        else:
            raise RecordingError(
                f"estimator: reads {name!r}, which a recording does not give (it gives "
                f"{', '.join(SOURCE_SIGNALS)})"
            )
    loggers, signals = {}, {}
    for i in range(estimator.num_output_ports()):
        name = estimator.get_output_port(i).get_name()
        signal = SIGNAL_BY_NAME.get(name) or next(
            (s for s in getattr(estimator, "extra_signals", ()) if s.name == name), None
        )
        if signal is None or not signal.logged:
            continue
        logger = LogVectorOutput(estimator.get_output_port(i), builder, t)
        logger.set_name(f"log_{name}")
        loggers[name], signals[name] = logger, signal
    diagram = builder.Build()
    diagram.set_name("uuv_replay")
    return UuvDiagram(
        diagram, {"recording": source, "estimator": estimator}, loggers, signals, noise
    )


def _inputs(recording: Recording, scenario: Scenario) -> dict[str, np.ndarray]:
    """The recording's inputs to the estimator and its truth, as a run's log holds them."""
    N, f = recording.steps, scenario.sonar.samples_per_step
    samples = recording.range_samples.reshape(N, 2, f)
    b = np.asarray(scenario.sonar.baseline)
    R_nav = recording.R_WB_nav.reshape(N, 3, 3)
    log = {
        "ranges": samples[:, :, 0].copy(),
        "sonar_status": recording.sonar_status.astype(np.int8),
        "ping_time": recording.ping_time,
        "R_WB_nav": R_nav,
        "p_WU_nav": recording.p_WU_nav,
        "v_WU_nav": recording.v_WU_nav,
        "b_W": R_nav @ b,
    }
    if recording.has_commands:
        log["u1_W"] = recording.u1_W
    if recording.truth:
        log.update({k: v for k, v in recording.truth.items() if k != "R_WB"})
        log["R_WB"] = recording.truth["R_WB"].reshape(N, 3, 3)
        log["b_W"] = log["R_WB"] @ b  # the true baseline, as a run's sonar logs it
    return log


def replay_metrics(log: dict[str, np.ndarray], scenario: Scenario) -> dict[str, float]:
    """The replay's figures: ``steps``, ``updates`` (applied measurement updates), and with a
    recorded truth the estimation errors over k ≥ ``steady_state_start`` (or all steps of a
    shorter recording): ``position_rmse``, ``velocity_rmse``, ``nees_mean``,
    ``final_position_error``."""
    status = np.asarray(log["measurement_status"]).reshape(-1)
    metrics = {"steps": float(len(status)), "updates": float(np.sum(status == VALID))}
    if "p_WT" not in log:
        return metrics
    e = errors(log, scenario)
    start = scenario.steady_state_start if scenario.steady_state_start < len(status) else 0
    window = slice(start, None)
    metrics.update(
        position_rmse=rms_norm(e["position"][window]),
        velocity_rmse=rms_norm(e["velocity"][window]),
        nees_mean=float(np.mean(e["nees"][window])),
        final_position_error=float(np.linalg.norm(e["position"][-1])),
    )
    return {k: (v if math.isfinite(v) else math.nan) for k, v in metrics.items()}
