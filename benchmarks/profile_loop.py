"""Where a paper run's time goes: the figures behind benchmarks/PROFILE.md.

    python benchmarks/profile_loop.py systems    # self time per system and callback [us/step]
    python benchmarks/profile_loop.py skeleton   # the framework alone: the loop's shape, no math
    python benchmarks/profile_loop.py run        # a run's parts: setup, simulation, log, metrics
    python benchmarks/profile_loop.py count none|plain|simulate   # for instruction counts

``count`` runs one warm-up of bench_loop's plain loop and of ``simulate``, then three more of
the one it names (none: nothing more), so that under callgrind
(``valgrind --tool=callgrind --callgrind-out-file=/tmp/cg.<mode> python ... count <mode>``)
``(count(mode) − count(none)) / 3`` is one run's instructions, whatever the machine's load.

``systems`` wraps every method of the package's LeafSystems and of the health monitor with a
timer and subtracts the callbacks nested in each (a port evaluated inside a callback runs its
producer's calc there), so a row is a method's own Python work plus the Drake calls it makes
(port evaluations, state reads and writes). The wrapper adds about 0.5 us a call.

``skeleton`` builds a diagram of the paper loop's shape (seven Python systems with its update
events, computed outputs and port evaluations, two seeded ``RandomSource``s with their
``ZeroOrderHold``s, a monitor) whose callbacks do no arithmetic, with 0, 10 or 24 loggers or the
24 signals through one ``Multiplexer`` into one logger: what the systems framework costs a step
before any of the loop's math.
"""

import argparse
import collections
import dataclasses
import functools
import importlib
import inspect
import pkgutil
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from pydrake.common import RandomDistribution, RandomGenerator
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, EventStatus, LeafSystem
from pydrake.systems.primitives import (
    LogVectorOutput,
    Multiplexer,
    RandomSource,
    ZeroOrderHold,
)

import drake_uuv
from drake_uuv.diagnostics import run_warnings
from drake_uuv.metrics import run_metrics
from drake_uuv.monitor import EstimatorHealthMonitor
from drake_uuv.scenario import load_scenario
from drake_uuv.simulation import ClosedLoopSimulation, log_from_loggers, simulate

STEPS = 500
T = 0.5


def best_of(f: Callable[[], object], repeats: int = 7) -> float:
    """The fastest of ``repeats`` calls [s]."""
    best = float("inf")
    for _ in range(repeats):
        tic = time.perf_counter()
        f()
        best = min(best, time.perf_counter() - tic)
    return best


def systems() -> None:
    own: collections.Counter = collections.Counter()
    stack: list[float] = []

    def timed(key: str, f: Callable) -> Callable:
        @functools.wraps(f)
        def wrapper(*args, **kwargs):
            tic = time.perf_counter()
            stack.append(0.0)
            try:
                return f(*args, **kwargs)
            finally:
                elapsed = time.perf_counter() - tic
                own[key] += elapsed - stack.pop()
                if stack:
                    stack[-1] += elapsed

        return wrapper

    for module in pkgutil.walk_packages(drake_uuv.__path__, "drake_uuv."):
        importlib.import_module(module.name)
    classes, pending = [EstimatorHealthMonitor], list(LeafSystem.__subclasses__())
    while pending:
        cls = pending.pop()
        pending.extend(cls.__subclasses__())
        if cls.__module__.startswith("drake_uuv"):
            classes.append(cls)
    for cls in classes:
        for name, f in list(vars(cls).items()):
            if inspect.isfunction(f) and (not name.startswith("__") or name == "__call__"):
                setattr(cls, name, timed(f"{cls.__name__}.{name}", f))
    simulation = ClosedLoopSimulation(load_scenario("paper"))
    simulation.run(0)
    own.clear()
    runs = 5
    total = sum(best_of(lambda s=seed: simulation.run(s), 1) for seed in range(runs)) / runs
    per_class: collections.Counter = collections.Counter()
    for key, seconds in own.items():
        per_class[key.split(".")[0]] += seconds
    scale = 1e6 / (runs * STEPS)
    print(f"paper run, {STEPS} steps: {total * 1e6 / STEPS:.1f} us/step with the timers")
    print(f"  Python callbacks, all: {sum(own.values()) * scale:.1f} us/step")
    for name, seconds in per_class.most_common():
        print(f"  {name:34s} {seconds * scale:6.1f} us/step")
    print("  callbacks over 2 us/step:")
    for key, seconds in own.most_common():
        if seconds * scale >= 2.0:
            print(f"    {key:52s} {seconds * scale:6.1f}")


class _Box(LeafSystem):
    """A system with the port and event counts of one of the loop's, doing no arithmetic."""

    def __init__(self, inputs: int, states: int, outputs: int) -> None:
        super().__init__()
        self.ins = [self.DeclareVectorInputPort(f"u{i}", 3) for i in range(inputs)]
        self.states = [self.DeclareDiscreteState(3) for _ in range(states)]
        if states:
            self.DeclarePeriodicDiscreteUpdateEvent(T, 0.0, self._update)
        for i, index in enumerate(self.states):
            self.DeclareStateOutputPort(f"x{i}", index)
        for i in range(outputs):
            self.DeclareVectorOutputPort(f"y{i}", 3, self._calc)

    def _update(self, context, discrete_state) -> None:
        for port in self.ins:
            port.Eval(context)
        for index in self.states:
            discrete_state.set_value(index, np.zeros(3))

    def _calc(self, context, output) -> None:
        for port in self.ins:
            port.Eval(context)
        output.set_value(np.zeros(3))


def skeleton_step(loggers: int, mux: bool) -> float:
    """us per step of the skeleton with ``loggers`` loggers (through one Multiplexer)."""
    builder = DiagramBuilder()
    uuv, target, sonar, estimator, attitude, tracking, navigation = (
        builder.AddSystem(_Box(*shape))
        for shape in ((2, 3, 0), (1, 2, 0), (3, 0, 1), (2, 2, 2), (1, 0, 1), (2, 0, 1), (3, 0, 1))
    )
    for port in (target.get_input_port(0), sonar.get_input_port(2)):
        source = builder.AddSystem(RandomSource(RandomDistribution.kGaussian, 3, T))
        hold = builder.AddSystem(ZeroOrderHold(T, 3))
        builder.Connect(source.get_output_port(), hold.get_input_port())
        builder.Connect(hold.get_output_port(), port)
    for producer, out, reader, i in (
        (tracking, 0, uuv, 0), (attitude, 0, uuv, 1), (uuv, 0, navigation, 0),
        (uuv, 1, navigation, 1), (uuv, 2, navigation, 2), (uuv, 0, sonar, 0), (target, 0, sonar, 1),
        (sonar, 0, estimator, 0), (navigation, 0, estimator, 1), (navigation, 0, attitude, 0),
        (estimator, 2, tracking, 0), (navigation, 0, tracking, 1),
    ):  # fmt: skip
        builder.Connect(producer.get_output_port(out), reader.get_input_port(i))
    boxes = (uuv, target, sonar, estimator, attitude, tracking, navigation)
    outputs = [s.get_output_port(i) for s in boxes for i in range(s.num_output_ports())]
    logged = [outputs[i % len(outputs)] for i in range(loggers)]
    if mux and logged:
        together = builder.AddSystem(Multiplexer([3] * loggers))
        for i, port in enumerate(logged):
            builder.Connect(port, together.get_input_port(i))
        logged = [together.get_output_port()]
    for port in logged:
        LogVectorOutput(port, builder, T)
    diagram = builder.Build()
    filtered = estimator.get_output_port(2)

    def monitor(root):
        filtered.Eval(estimator.GetMyContextFromRoot(root))
        return EventStatus.Succeeded()

    def run() -> None:
        simulator = Simulator(diagram)
        diagram.SetRandomContext(simulator.get_mutable_context(), RandomGenerator(1))
        simulator.set_monitor(monitor)
        simulator.Initialize()
        simulator.AdvanceTo((STEPS - 1) * T)

    return best_of(run) * 1e6 / STEPS


def skeleton() -> None:
    print(f"framework alone (callbacks without arithmetic), {STEPS} steps, best of 7:")
    for loggers, mux in ((0, False), (10, False), (24, False), (24, True)):
        label = f"{loggers} loggers" + (" through one Multiplexer" if mux else "")
        print(f"  {label:36s} {skeleton_step(loggers, mux):6.1f} us/step")


def run() -> None:
    scenario = load_scenario("paper")
    simulation = ClosedLoopSimulation(scenario)
    result = simulation.run(0)
    simulator = Simulator(simulation.diagram)
    context = simulator.get_mutable_context()
    simulation.built.set_random_context(context, 0)
    simulator.Initialize()
    simulator.AdvanceTo((STEPS - 1) * T)
    metrics = run_metrics(result.log, scenario)
    ms = {
        "ClosedLoopSimulation (build the diagram)": best_of(lambda: ClosedLoopSimulation(scenario)),
        "ClosedLoopSimulation.run, all": best_of(lambda: simulation.run(0)),
        "Simulator + context": best_of(lambda: Simulator(simulation.diagram)),
        "log_from_loggers": best_of(lambda: log_from_loggers(simulation.built, context, STEPS)),
        "run_metrics": best_of(lambda: run_metrics(result.log, scenario)),
        "run_warnings": best_of(lambda: run_warnings(result.log, metrics, scenario)),
    }
    print(f"paper run, {STEPS} steps, best of 7:")
    for label, seconds in ms.items():
        print(f"  {label:42s} {seconds * 1e3:7.2f} ms")


def count(mode: str) -> None:
    sys.path.insert(0, str(Path(__file__).parent))
    from bench_loop import plain_loop  # the benchmark beside this file

    scenario = load_scenario("paper")
    runs = {"plain": lambda seed: plain_loop(scenario, seed), "simulate": lambda seed: simulate(
        dataclasses.replace(scenario, random_seed=seed))}  # fmt: skip
    for f in runs.values():
        f(0)
    for seed in range(1, 4) if mode != "none" else ():
        runs[mode](seed)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("part", choices=("systems", "skeleton", "run", "count"))
    parser.add_argument("mode", nargs="?", choices=("none", "plain", "simulate"), default="none")
    args = parser.parse_args()
    if args.part == "count":
        count(args.mode)
    else:
        {"systems": systems, "skeleton": skeleton, "run": run}[args.part]()


if __name__ == "__main__":
    main()
