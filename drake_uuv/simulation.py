"""Run one closed-loop simulation and collect its log and metrics."""

import dataclasses
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydrake.geometry import Meshcat
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Context, System

from drake_uuv.diagnostics import RunWarning, run_warnings
from drake_uuv.diagram import UuvDiagram, make_uuv_diagram
from drake_uuv.io import write_json_atomic, write_npz_atomic
from drake_uuv.metrics import batch_metrics, metric_signals
from drake_uuv.models.tracking_laws import closed_loop_eigenvalues
from drake_uuv.monitor import EstimatorHealthMonitor, SimulationFailure
from drake_uuv.primitives.threads import one_blas_thread
from drake_uuv.scenario import Scenario


@dataclass
class SimulationResult:
    """A run: its scenario, its per-step log (one row per step k), and its metrics."""

    scenario: Scenario
    log: dict[str, np.ndarray]
    metrics: dict[str, float] = field(default_factory=dict)
    # What the run got wrong, one line each (drake_uuv.diagnostics).
    warnings: list[RunWarning] = field(default_factory=list)

    @property
    def steps(self) -> int:
        return len(self.log["k"])

    def save(self, out_dir: Path) -> None:
        """Writes ``log.npz`` and ``metrics.json`` (the metrics and a ``warnings`` list) into
        ``out_dir`` (atomically)."""
        out_dir = Path(out_dir)
        write_npz_atomic(out_dir / "log.npz", self.log)
        warnings = [{"code": w.code, "message": w.message} for w in self.warnings]
        write_json_atomic(out_dir / "metrics.json", {**self.metrics, "warnings": warnings})


@dataclass
class BatchResult:
    """A batch of runs: their seeds, their log (each signal ``(B, N, *shape)``; ``k`` and
    ``time`` ``(N,)``), their metrics (each ``(B,)``, NaN for a failed run) and each run's
    failure (None for a run that finished)."""

    scenario: Scenario
    seeds: np.ndarray
    log: dict[str, np.ndarray]
    metrics: dict[str, np.ndarray]
    failures: list[str | None]

    @property
    def failed(self) -> np.ndarray:
        """A (B,) mask of the runs the estimator-health monitor stopped."""
        return np.array([f is not None for f in self.failures], dtype=bool)

    def run_log(self, i: int) -> dict[str, np.ndarray]:
        """Run i's own log, as a single run's ``log.npz`` holds it."""
        return {
            name: value if name in ("k", "time") else value[i] for name, value in self.log.items()
        }


#: An integer signal's value where a stopped run logged no number (its float signals: NaN).
NO_VALUE = -1


def log_from_loggers(built: UuvDiagram, context: Context, steps: int) -> dict[str, np.ndarray]:
    """The loggers' columns as the named per-step arrays of a batch's log.

    One array per logged signal (:mod:`drake_uuv.signals`), keyed by its name, shaped
    ``(B, N, *shape)``: run i's row k the value at step k shaped as the signal's ``shape``
    (scalars as ``(B, N)``), plus ``k`` and ``time`` ``(N,)``. After a run's stop its rows
    are NaN, and an integer signal's (a status code) :data:`NO_VALUE`.
    """
    B = built.batch_size
    log: dict[str, np.ndarray] = {"k": np.arange(steps)}
    for name, logger in built.loggers.items():
        found = logger.FindLog(context)
        if "time" not in log:
            log["time"] = _padded_times(found.sample_times()[:steps], steps)
        signal = built.signals[name]
        data = found.data().T[:steps]
        if len(data) < steps:  # every run failed and the Simulator stopped: NaN after it
            data = np.vstack([data, np.full((steps - len(data), data.shape[1]), np.nan)])
        shape = signal.shape if all(n > 0 for n in signal.shape) else (-1,)
        data = np.moveaxis(data.reshape(len(data), B, *shape), 1, 0).copy()
        if signal.integer:  # a code; NO_VALUE where a stopped run's row holds no number
            data = np.where(np.isnan(data), NO_VALUE, data).astype(np.int8)
        log[name] = data
    return log


def _padded_times(times: np.ndarray, steps: int) -> np.ndarray:
    """The loggers' sample times, continued at their period to ``steps`` when a batch whose
    runs all failed stopped early."""
    times = np.array(times, dtype=float)
    if len(times) >= steps or len(times) < 2:
        return np.pad(times, (0, max(steps - len(times), 0)), constant_values=np.nan)
    more = times[-1] + (times[1] - times[0]) * np.arange(1, steps - len(times) + 1)
    return np.concatenate([times, more])


def read_log(path: Path) -> dict[str, np.ndarray]:
    """A run's ``log.npz`` as a dict (keys = signal names, plus ``k`` and ``time``)."""
    with np.load(path) as data:
        return {key: data[key] for key in data.files}


#: What a run logs, by ``ClosedLoopSimulation``'s ``log``: every logged signal (``log.npz``),
#: or only those its metrics read (a study's runs).
LOGS = ("full", "metrics")


class ClosedLoopSimulation:
    """A built closed-loop diagram that runs any number of seeded runs.

    Building the diagram once and creating a fresh context per run is what Monte Carlo studies
    want: only the seed changes between runs, and the same seed gives a bit-identical log.

    Every run is watched by an :class:`~drake_uuv.monitor.EstimatorHealthMonitor`: an estimator
    whose covariance stops being symmetric positive definite, or whose innovations blow up,
    stops the run with a :class:`~drake_uuv.monitor.SimulationFailure` naming the check and
    the step, instead of filling the log with NaNs.

    With ``meshcat``, a live visualiser draws the scene while it simulates (see
    :class:`~drake_uuv.visualization.live_visualizer.LiveMeshcatVisualizer`).

    ``batch_size`` B builds the loop for B runs at once (:meth:`run_batch`): every system
    steps all of them, each run drawing its noise from its own seed, so run i of a batch is
    bit for bit the run of its seed alone. A run the monitor stops is marked and no longer
    watched; the batch's other runs go on.

    ``systems`` replaces systems of the loop with your own, by name (see
    :func:`~drake_uuv.diagram.make_uuv_diagram`). ``log="full"`` (the default) logs every
    signal of ``log.npz``; ``log="metrics"`` only those the metrics, the warnings and a
    study read (:func:`~drake_uuv.metrics.metric_signals`): the same metrics, with the outputs
    nobody else reads never computed. A plant with continuous state sets up the
    integrator (its ``configure_simulator``). Besides :func:`~drake_uuv.metrics.batch_metrics`,
    a run's metrics hold ``tracking_spectral_radius``: the largest |eigenvalue| of the
    tracking law's closed loop ``A − B K`` on the relative double integrator (< 1: the error
    dynamics are stable; the paper's law has 1, its undamped velocity mode), the same for
    every run of a scenario; NaN for a tracking system without a ``gain`` (a 3×6 world-frame
    gain on the relative state), such as one of your own.
    """

    def __init__(
        self,
        scenario: Scenario,
        *,
        meshcat: Meshcat | None = None,
        systems: Mapping[str, System] | None = None,
        log: str = "full",
        batch_size: int = 1,
    ) -> None:
        if log not in LOGS:
            raise ValueError(f"log: must be one of {', '.join(LOGS)}, got {log!r}")
        self.scenario = scenario
        logged = True if log == "full" else metric_signals(scenario)
        self.built = make_uuv_diagram(
            scenario, meshcat=meshcat, systems=systems, log=logged, batch_size=batch_size
        )
        self.batch_size = self.built.batch_size
        self._stopped: RuntimeError | None = None  # the Simulator's error when all runs failed
        self.diagram = self.built.diagram
        self.monitor = EstimatorHealthMonitor(
            self.built.systems["estimator"], scenario.time_step, batch_size=self.batch_size
        )
        gain = getattr(self.built.systems["tracking_controller"], "gain", None)
        # The same for every run: the tracking law's closed loop on the relative model.
        self.tracking_spectral_radius = (
            math.nan
            if gain is None
            else float(np.max(np.abs(closed_loop_eigenvalues(scenario.time_step, gain))))
        )

    def run(self, seed: int | None = None, realtime_rate: float = 0.0) -> SimulationResult:
        """One run with ``seed`` (default: the scenario's ``random_seed``), on a diagram of
        ``batch_size`` 1: a batch of one (:meth:`run_batch`). A run the monitor stops raises
        :class:`~drake_uuv.monitor.SimulationFailure` naming the check and the step.

        ``realtime_rate`` > 0 paces the simulation (for a live Meshcat view).
        """
        if self.batch_size != 1:
            raise ValueError(
                f"run: this simulation steps {self.batch_size} runs at once; use run_batch"
            )
        seed = self.scenario.random_seed if seed is None else seed
        start = time.perf_counter()
        batch = self.run_batch([seed], realtime_rate=realtime_rate)
        if batch.failures[0] is not None:
            raise SimulationFailure(f"seed {seed}: run stopped: {batch.failures[0]}") from (
                self._stopped
            )
        metrics = {name: float(value[0]) for name, value in batch.metrics.items()}
        log = batch.run_log(0)
        metrics.update(wall_time_s=time.perf_counter() - start)
        warnings = run_warnings(log, metrics, batch.scenario)
        return SimulationResult(
            scenario=batch.scenario, log=log, metrics=metrics, warnings=warnings
        )

    def run_batch(
        self,
        seeds: Sequence[int],
        realtime_rate: float = 0.0,
        prepare: Callable[[Context], None] | None = None,
    ) -> BatchResult:
        """The runs of ``seeds`` (one per run of the batch, ``batch_size`` of them) at once.

        Run i draws its noise from ``seeds[i]`` alone. A run the monitor stops keeps its
        record in ``failures`` and NaN metrics; the others go on. An error inside a system
        (not the monitor's finding) stops the whole batch and is raised. ``prepare(context)``,
        if given, is called with the root context after seeding and before the Simulator
        initializes (e.g. to start runs from priors of your own).
        """
        seeds = np.asarray(seeds, dtype=np.int64).reshape(-1)
        if len(seeds) != self.batch_size:
            raise ValueError(
                f"seeds: must be {self.batch_size} seeds (one per run of the batch), "
                f"got {len(seeds)}"
            )
        scenario = self.scenario
        if self.batch_size == 1 and seeds[0] != scenario.random_seed:
            scenario = dataclasses.replace(scenario, random_seed=int(seeds[0]))
        simulator = Simulator(self.diagram)
        configure = getattr(self.built.systems["uuv"], "configure_simulator", None)
        if configure is not None:
            configure(simulator)
        simulator.set_target_realtime_rate(realtime_rate)
        context = simulator.get_mutable_context()
        self.built.set_random_context(context, seeds)
        if prepare is not None:
            prepare(context)
        self.monitor.reset()
        self._stopped = None
        simulator.set_monitor(self.monitor)
        try:
            with one_blas_thread():
                simulator.Initialize()
                simulator.AdvanceTo((scenario.steps - 1) * scenario.time_step)
        except RuntimeError as e:
            if self.monitor.failure is None or self.monitor.failed.sum() < self.batch_size:
                raise
            self._stopped = e  # every run failed: the monitor stopped the Simulator
        except np.linalg.LinAlgError as e:
            # A factorisation inside a system's update (a UKF's sigma points, a Kalman gain)
            # failed before the monitor saw the step: the estimate had already broken down.
            if self.batch_size != 1:
                raise
            step = round(context.get_time() / scenario.time_step)
            raise SimulationFailure(
                f"seed {seeds[0]}: run stopped: a covariance or innovation matrix "
                f"could not be factorised ({e}) in the update after step k={step} "
                f"(t={context.get_time():g} s)"
            ) from e
        log = log_from_loggers(self.built, context, scenario.steps)
        failures = list(self.monitor.failures)
        with one_blas_thread():
            metrics = _batch_metrics(log, scenario, failures)
        metrics.update(
            tracking_spectral_radius=np.full(len(seeds), self.tracking_spectral_radius),
            steps=np.full(len(seeds), scenario.steps),
            seed=seeds.astype(float),
        )
        return BatchResult(scenario, seeds, log, metrics, failures)


def _batch_metrics(
    log: dict[str, np.ndarray], scenario: Scenario, failures: list[str | None]
) -> dict[str, np.ndarray]:
    """Each run's metrics as (B,) arrays (:func:`~drake_uuv.metrics.batch_metrics`), NaN for
    a run the monitor stopped (what its log holds after the failure means nothing)."""
    metrics = batch_metrics(log, scenario)
    failed = np.array([f is not None for f in failures], dtype=bool)
    if failed.any():
        for value in metrics.values():
            value[failed] = math.nan
    return metrics


def simulate(scenario: Scenario) -> SimulationResult:
    """Builds the diagram, seeds it with ``scenario.random_seed`` and runs ``steps`` steps.

    The loggers publish at k·t; the run advances to (steps − 1)·t, so the log has exactly
    ``steps`` rows, row k holding the values at step k before that step's update.
    """
    return ClosedLoopSimulation(scenario).run()
