"""The one builder of the closed loop: every system and logger named, every port wired here."""

from dataclasses import dataclass

import numpy as np
from pydrake.common import RandomDistribution, RandomGenerator
from pydrake.geometry import Meshcat
from pydrake.systems.framework import (
    Context,
    Diagram,
    DiagramBuilder,
    InputPort,
    OutputPort,
    System,
)
from pydrake.systems.primitives import (
    LogVectorOutput,
    RandomSource,
    VectorLogSink,
    ZeroOrderHold,
)

from drake_uuv.attitude import make_attitude_generator
from drake_uuv.estimators import make_estimator
from drake_uuv.plants import TargetRandomWalk, make_plant
from drake_uuv.primitives import random_inputs
from drake_uuv.scenario import Scenario
from drake_uuv.sensors import DualSonar
from drake_uuv.signals import Signal, check_contract, logged_signals
from drake_uuv.tracking import make_tracking_controller
from drake_uuv.visualization.live_visualizer import LiveMeshcatVisualizer

#: The slots: the diagram's system name → the scenario section whose variant builds it.
SLOT_SYSTEMS = {
    "uuv": "plant",
    "estimator": "estimator",
    "attitude_generator": "attitude",
    "tracking_controller": "tracking",
}


@dataclass
class UuvDiagram:
    """The built diagram and handles a caller needs: its systems, loggers and signals by name.

    Seed a context with :meth:`set_random_context` (not the diagram's ``SetRandomContext``
    alone): it also latches each source's first draw into its hold.
    """

    diagram: Diagram
    systems: dict[str, System]
    loggers: dict[str, VectorLogSink]
    signals: dict[str, Signal]
    noise: list[tuple[RandomSource, ZeroOrderHold]]

    def set_random_context(self, context: Context, seed: int) -> None:
        """Seeds every random source from ``seed`` and latches its first draw for step 0.

        A hold samples its source at each tick, which gives step k + 1 its draw; the draw of
        step 0 is the one the seeding makes, set here.
        """
        self.diagram.SetRandomContext(context, RandomGenerator(seed))
        for source, hold in self.noise:
            draw = source.get_output_port().Eval(source.GetMyContextFromRoot(context))
            hold.SetVectorState(hold.GetMyMutableContextFromRoot(context), draw)


def make_systems(scenario: Scenario) -> dict[str, System]:
    """The closed loop's systems by name, each built from its part of the scenario."""
    return {
        "uuv": make_plant(scenario),
        "target": TargetRandomWalk.from_scenario(scenario),
        "sonar": DualSonar.from_scenario(scenario),
        "estimator": make_estimator(scenario),
        "attitude_generator": make_attitude_generator(scenario),
        "tracking_controller": make_tracking_controller(scenario),
    }


def make_uuv_diagram(
    scenario: Scenario,
    builder: DiagramBuilder | None = None,
    meshcat: Meshcat | None = None,
    log: bool = True,
) -> UuvDiagram:
    """Builds the paper's closed loop from a validated scenario.

    Systems: ``uuv`` (the plant slot's variant), ``target``, ``sonar``, ``estimator``,
    ``attitude_generator`` and ``tracking_controller`` (the other slots). Each input port is
    connected to the output port of the same name (the names are
    :data:`drake_uuv.signals.SIGNALS`); each random input port gets a named, seeded
    ``RandomSource`` (named like the port) followed by a ``ZeroOrderHold`` (``<name>_hold``)
    so that publishes and updates of one step see the same draw: Drake's ``RandomSource`` draws
    its next sample in an *unrestricted* update, which the Simulator runs before the same
    tick's discrete updates, so a system reading the source directly would see draw n at the
    tick's publish (the loggers) and draw n + 1 in its discrete updates (the plant, the
    filter), and the log would not hold the measurement the filter used. Loggers are
    ``log_<name>`` for each logged signal, sampled once per step so column k holds the value at
    step k, before that step's update.

    Pass a ``builder`` to add systems of your own before building, ``log=False`` for a
    diagram without loggers (a picture of the loop itself), and ``meshcat`` to draw the
    scene live (a :class:`~drake_uuv.visualization.live_visualizer.LiveMeshcatVisualizer`
    named ``meshcat_visualizer``). A variant whose system lacks a signal of its slot, or reads
    one nobody produces, is refused with a ``ValueError`` naming the variant and the port.
    """
    t = scenario.time_step
    builder = builder or DiagramBuilder()
    systems = make_systems(scenario)
    for name, system in systems.items():
        section = SLOT_SYSTEMS.get(name)
        variant = f"!{type(getattr(scenario, section)).__name__}" if section else name
        check_contract(name, system, variant)
        builder.AddNamedSystem(name, system)
    readers = dict(systems)
    if meshcat is not None:
        visualizer = LiveMeshcatVisualizer(meshcat, np.asarray(scenario.sonar.baseline), t)
        readers["meshcat_visualizer"] = builder.AddNamedSystem("meshcat_visualizer", visualizer)

    producers = _producers(systems)
    noise = []
    for name, system in readers.items():
        random = random_inputs(system)
        for i in range(system.num_input_ports()):
            port = system.get_input_port(i)
            if port.get_name() in random:
                noise.append(_add_noise(builder, port, random[port.get_name()], t))
            elif port.get_name() in producers:
                builder.Connect(producers[port.get_name()], port)
            else:
                raise ValueError(
                    f"{name}: input port {port.get_name()!r} has no producer (the signals are "
                    f"{', '.join(sorted(producers))}; a random port is declared with "
                    "drake_uuv.primitives.declare_random_input)"
                )

    signals = {signal.name: signal for signal in logged_signals(systems)} if log else {}
    loggers = {}
    for signal in signals.values():
        logger = LogVectorOutput(producers[signal.name], builder, t)
        logger.set_name(f"log_{signal.name}")
        loggers[signal.name] = logger

    diagram = builder.Build()
    diagram.set_name("uuv_closed_loop")
    return UuvDiagram(diagram, systems, loggers, signals, noise)


def _producers(systems: dict[str, System]) -> dict[str, OutputPort]:
    """Every output port by name; a name two systems output is refused."""
    producers: dict[str, OutputPort] = {}
    owners: dict[str, str] = {}
    for name, system in systems.items():
        for i in range(system.num_output_ports()):
            port = system.get_output_port(i)
            signal = port.get_name()
            if signal in producers:
                raise ValueError(f"{name} and {owners[signal]} both output {signal!r}")
            producers[signal], owners[signal] = port, name
    return producers


def _add_noise(
    builder: DiagramBuilder, port: InputPort, distribution: RandomDistribution, time_step: float
) -> tuple[RandomSource, ZeroOrderHold]:
    """A ``RandomSource`` of the port's distribution, sampled once per step and held."""
    name = port.get_name()
    source = builder.AddNamedSystem(name, RandomSource(distribution, port.size(), time_step))
    hold = builder.AddNamedSystem(f"{name}_hold", ZeroOrderHold(time_step, port.size()))
    builder.Connect(source.get_output_port(), hold.get_input_port())
    builder.Connect(hold.get_output_port(), port)
    return source, hold
