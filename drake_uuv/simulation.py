"""Run one closed-loop simulation and collect its log and metrics."""

import dataclasses
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydrake.common import RandomGenerator
from pydrake.geometry import Meshcat
from pydrake.systems.analysis import Simulator

from drake_uuv.diagram import UuvDiagram, make_uuv_diagram
from drake_uuv.io import write_json_atomic, write_npz_atomic
from drake_uuv.metrics import run_metrics
from drake_uuv.monitor import EstimatorHealthMonitor, SimulationFailure
from drake_uuv.scenario import Scenario


@dataclass
class SimulationResult:
    """A run: its scenario, its per-step log (one row per step k), and its metrics."""

    scenario: Scenario
    log: dict[str, np.ndarray]
    metrics: dict[str, float] = field(default_factory=dict)

    @property
    def steps(self) -> int:
        return len(self.log["k"])

    def save(self, out_dir: Path) -> None:
        """Writes ``log.npz`` and ``metrics.json`` into ``out_dir`` (atomically)."""
        out_dir = Path(out_dir)
        write_npz_atomic(out_dir / "log.npz", self.log)
        write_json_atomic(out_dir / "metrics.json", self.metrics)


def log_from_loggers(built: UuvDiagram, context, scenario: Scenario) -> dict[str, np.ndarray]:
    """Turns the loggers' columns into the named per-step arrays of ``log.npz``."""
    data = {name: logger.FindLog(context).data().T.copy() for name, logger in built.loggers.items()}
    n = scenario.steps
    data = {name: value[:n] for name, value in data.items()}
    times = built.loggers["uuv_state"].FindLog(context).sample_times()[:n]
    return {
        "k": np.arange(n),
        "time": times.copy(),
        "p_uuv": data["uuv_state"][:, :3],
        "v_uuv": data["uuv_state"][:, 3:],
        "R_WB": data["R_WB"].reshape(n, 3, 3),
        "p_target": data["target_state"][:, :3],
        "v_target": data["target_state"][:, 3:],
        "ranges": data["ranges"],
        "Y": data["Y"][:, 0],
        "m": data["m"][:, 0],
        "Gamma": data["Gamma"][:, 0],
        "q_s": data["q_s"],
        "q_hat": data["x_hat"][:, :3],
        "v_hat": data["x_hat"][:, 3:],
        "P": data["P"].reshape(n, 6, 6),
        "u1": data["u1_B"],
        "u2": data["w_W"],
        "a_world": data["a_W"],
        "sonar_status": data["sonar_status"].astype(np.int8),
        "multipath": data["multipath"],
        "measurement_status": data["measurement_status"][:, 0].astype(np.int8),
        "nis": data["nis"][:, 0],
    }


def _monitor_message(error: RuntimeError) -> str:
    """The monitor's own message out of the Simulator's wrapping text."""
    text = " ".join(str(error).split())
    marker = "with message: "
    return text.split(marker, 1)[1].rstrip(".").strip('"') if marker in text else text


class ClosedLoopSimulation:
    """A built closed-loop diagram that runs any number of seeded runs.

    Building the diagram once and creating a fresh context per run is what Monte Carlo studies
    want: only the seed changes between runs, and the same seed gives a bit-identical log.

    Every run is watched by an :class:`~drake_uuv.monitor.EstimatorHealthMonitor`: an estimator
    whose covariance stops being symmetric positive definite, or whose innovations blow up,
    stops the run with a :class:`~drake_uuv.monitor.SimulationFailure` naming the check and
    the step, instead of filling the log with NaNs.

    With ``meshcat``, a live visualiser draws the scene while it simulates (see
    :func:`~drake_uuv.visualization.add_live_meshcat_visualizer`).
    """

    def __init__(self, scenario: Scenario, meshcat: Meshcat | None = None) -> None:
        self.scenario = scenario
        self.built = make_uuv_diagram(scenario, meshcat=meshcat)
        self.diagram = self.built.diagram
        self.monitor = EstimatorHealthMonitor(self.built.systems["estimator"], scenario.time_step)

    def run(self, seed: int | None = None, realtime_rate: float = 0.0) -> SimulationResult:
        """One run with ``seed`` (default: the scenario's ``random_seed``).

        ``realtime_rate`` > 0 paces the simulation (for a live Meshcat view).
        """
        start = time.perf_counter()
        scenario = self.scenario
        if seed is not None and seed != scenario.random_seed:
            scenario = dataclasses.replace(scenario, random_seed=seed)
        simulator = Simulator(self.diagram)
        simulator.set_target_realtime_rate(realtime_rate)
        context = simulator.get_mutable_context()
        self.diagram.SetRandomContext(context, RandomGenerator(scenario.random_seed))
        self.monitor.reset()
        simulator.set_monitor(self.monitor)
        try:
            simulator.Initialize()
            simulator.AdvanceTo((scenario.steps - 1) * scenario.time_step)
        except RuntimeError as e:
            if "estimator" not in str(e):
                raise
            raise SimulationFailure(
                f"seed {scenario.random_seed}: run stopped: {_monitor_message(e)}"
            ) from e
        log = log_from_loggers(self.built, context, scenario)
        metrics = run_metrics(log, scenario)
        metrics.update(
            steps=scenario.steps,
            seed=scenario.random_seed,
            wall_time_s=time.perf_counter() - start,
        )
        return SimulationResult(scenario=scenario, log=log, metrics=metrics)


def simulate(scenario: Scenario) -> SimulationResult:
    """Builds the diagram, seeds it with ``scenario.random_seed`` and runs ``steps`` steps.

    The loggers publish at k·t; the run advances to (steps − 1)·t, so the log has exactly
    ``steps`` rows, row k holding the values at step k before that step's update.
    """
    return ClosedLoopSimulation(scenario).run()
