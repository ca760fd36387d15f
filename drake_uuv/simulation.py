"""Run one closed-loop simulation and collect its log and metrics."""

import dataclasses
import math
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydrake.geometry import Meshcat
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Context, System

from drake_uuv.diagnostics import RunWarning, run_warnings
from drake_uuv.diagram import UuvDiagram, make_uuv_diagram
from drake_uuv.io import write_json_atomic, write_npz_atomic
from drake_uuv.metrics import metric_signals, run_metrics
from drake_uuv.models.tracking_laws import closed_loop_eigenvalues
from drake_uuv.monitor import EstimatorHealthMonitor, SimulationFailure
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


def log_from_loggers(built: UuvDiagram, context: Context, steps: int) -> dict[str, np.ndarray]:
    """The loggers' columns as the named per-step arrays of ``log.npz``.

    One array per logged signal (:mod:`drake_uuv.signals`), keyed by its name, row k the
    value at step k shaped as the signal's ``shape`` (scalars as a vector of N), plus ``k``
    and ``time``.
    """
    log: dict[str, np.ndarray] = {"k": np.arange(steps)}
    for name, logger in built.loggers.items():
        found = logger.FindLog(context)
        if "time" not in log:
            log["time"] = found.sample_times()[:steps].copy()
        signal = built.signals[name]
        data = found.data().T[:steps]
        shape = signal.shape if all(n > 0 for n in signal.shape) else (-1,)
        data = data.reshape(len(data), *shape).copy()
        log[name] = data.astype(np.int8) if signal.integer else data
    return log


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

    ``systems`` replaces systems of the loop with your own, by name (see
    :func:`~drake_uuv.diagram.make_uuv_diagram`). ``log="full"`` (the default) logs every
    signal of ``log.npz``; ``log="metrics"`` only those the metrics, the warnings and a
    study read (:func:`~drake_uuv.metrics.metric_signals`): the same metrics, with the outputs
    nobody else reads never computed. A plant with continuous state sets up the
    integrator (its ``configure_simulator``). Besides :func:`~drake_uuv.metrics.run_metrics`,
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
    ) -> None:
        if log not in LOGS:
            raise ValueError(f"log: must be one of {', '.join(LOGS)}, got {log!r}")
        self.scenario = scenario
        logged = True if log == "full" else metric_signals(scenario)
        self.built = make_uuv_diagram(scenario, meshcat=meshcat, systems=systems, log=logged)
        self.diagram = self.built.diagram
        self.monitor = EstimatorHealthMonitor(self.built.systems["estimator"], scenario.time_step)
        gain = getattr(self.built.systems["tracking_controller"], "gain", None)
        # The same for every run: the tracking law's closed loop on the relative model.
        self.tracking_spectral_radius = (
            math.nan
            if gain is None
            else float(np.max(np.abs(closed_loop_eigenvalues(scenario.time_step, gain))))
        )

    def run(self, seed: int | None = None, realtime_rate: float = 0.0) -> SimulationResult:
        """One run with ``seed`` (default: the scenario's ``random_seed``).

        ``realtime_rate`` > 0 paces the simulation (for a live Meshcat view).
        """
        start = time.perf_counter()
        scenario = self.scenario
        if seed is not None and seed != scenario.random_seed:
            scenario = dataclasses.replace(scenario, random_seed=seed)
        simulator = Simulator(self.diagram)
        configure = getattr(self.built.systems["uuv"], "configure_simulator", None)
        if configure is not None:
            configure(simulator)
        simulator.set_target_realtime_rate(realtime_rate)
        context = simulator.get_mutable_context()
        self.built.set_random_context(context, scenario.random_seed)
        self.monitor.reset()
        simulator.set_monitor(self.monitor)
        try:
            simulator.Initialize()
            simulator.AdvanceTo((scenario.steps - 1) * scenario.time_step)
        except RuntimeError as e:
            if self.monitor.failure is None:
                raise
            raise SimulationFailure(
                f"seed {scenario.random_seed}: run stopped: {self.monitor.failure}"
            ) from e
        except np.linalg.LinAlgError as e:
            # A factorisation inside a system's update (a UKF's sigma points, a Kalman gain)
            # failed before the monitor saw the step: the estimate had already broken down.
            step = round(context.get_time() / scenario.time_step)
            raise SimulationFailure(
                f"seed {scenario.random_seed}: run stopped: a covariance or innovation matrix "
                f"could not be factorised ({e}) in the update after step k={step} "
                f"(t={context.get_time():g} s)"
            ) from e
        log = log_from_loggers(self.built, context, scenario.steps)
        metrics = run_metrics(log, scenario)
        metrics.update(
            tracking_spectral_radius=self.tracking_spectral_radius,
            steps=scenario.steps,
            seed=scenario.random_seed,
            wall_time_s=time.perf_counter() - start,
        )
        warnings = run_warnings(log, metrics, scenario)
        return SimulationResult(scenario=scenario, log=log, metrics=metrics, warnings=warnings)


def simulate(scenario: Scenario) -> SimulationResult:
    """Builds the diagram, seeds it with ``scenario.random_seed`` and runs ``steps`` steps.

    The loggers publish at k·t; the run advances to (steps − 1)·t, so the log has exactly
    ``steps`` rows, row k holding the values at step k before that step's update.
    """
    return ClosedLoopSimulation(scenario).run()
