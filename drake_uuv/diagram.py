"""The one builder of the closed loop: every system and logger named, every port wired here."""

from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass
from typing import Any

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
from drake_uuv.attitude.factory import ATTITUDE_GENERATORS
from drake_uuv.estimators import make_estimator
from drake_uuv.estimators.factory import ESTIMATORS
from drake_uuv.navigation import make_navigation
from drake_uuv.navigation.factory import NAVIGATIONS
from drake_uuv.plants import TargetRandomWalk, make_plant
from drake_uuv.plants.factory import PLANTS
from drake_uuv.primitives import random_inputs
from drake_uuv.scenario import Scenario
from drake_uuv.sensors import DualSonar
from drake_uuv.signals import Signal, check_contract, logged_signals
from drake_uuv.tracking import make_tracking_controller
from drake_uuv.tracking.factory import TRACKING_CONTROLLERS
from drake_uuv.visualization.live_visualizer import LiveMeshcatVisualizer


@dataclass(frozen=True)
class Slot:
    """A slot of the loop: the scenario section whose variant chooses the system, the
    system's name in the diagram, the factory's table (variant dataclass → its system) and
    the factory itself."""

    section: str
    system: str
    table: Mapping[type, Any]
    make: Callable[[Scenario], System]

    @property
    def tags(self) -> list[str]:
        """The YAML tags of the slot's variants (``!KinematicUuv``, …), in table order."""
        return [f"!{variant.__name__}" for variant in self.table]


#: The slots, in the order the builder makes them; each table maps a variant dataclass to what
#: its factory builds the variant's system with.
SLOT_REGISTRY: tuple[Slot, ...] = (
    Slot("plant", "uuv", PLANTS, make_plant),
    Slot("navigation", "navigation", NAVIGATIONS, make_navigation),
    Slot("estimator", "estimator", ESTIMATORS, make_estimator),
    Slot("attitude", "attitude_generator", ATTITUDE_GENERATORS, make_attitude_generator),
    Slot("tracking", "tracking_controller", TRACKING_CONTROLLERS, make_tracking_controller),
)
#: Every system of the loop by its name in the diagram, in the order the builder adds them.
SYSTEM_NAMES = (
    "uuv", "navigation", "target", "sonar", "estimator", "attitude_generator",
    "tracking_controller",
)  # fmt: skip
#: The system whose random sources are seeded last (see :func:`make_uuv_diagram`).
SEEDED_LAST = "navigation"


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


def make_systems(
    scenario: Scenario, systems: Mapping[str, System] | None = None
) -> dict[str, System]:
    """The closed loop's systems by name (:data:`SYSTEM_NAMES`): those of ``systems`` as
    given, the others built from their part of the scenario (each slot by its factory).

    The wiring across slots is here and in the factories: the sonar's ``m`` and ``Γ``
    follow the estimator section's noise model, whoever supplies the estimator.
    """
    given = dict(systems or {})
    for name, system in given.items():
        if name not in SYSTEM_NAMES:
            raise ValueError(
                f"systems: unknown system name {name!r} (the loop's are {', '.join(SYSTEM_NAMES)})"
            )
        if not isinstance(system, System):
            raise ValueError(f"systems[{name!r}]: must be a Drake System, got {system!r}")
    makers: dict[str, Callable[[], System]] = {
        "uuv": lambda: make_plant(scenario),
        "navigation": lambda: make_navigation(scenario),
        "target": lambda: TargetRandomWalk(scenario.target, time_step=scenario.time_step),
        "sonar": lambda: DualSonar(
            scenario.sonar,
            noise_model=scenario.estimator.noise_model,
            time_step=scenario.time_step,
        ),
        "estimator": lambda: make_estimator(scenario),
        "attitude_generator": lambda: make_attitude_generator(scenario),
        "tracking_controller": lambda: make_tracking_controller(scenario),
    }
    return {name: given[name] if name in given else makers[name]() for name in SYSTEM_NAMES}


def make_uuv_diagram(
    scenario: Scenario,
    *,
    builder: DiagramBuilder | None = None,
    meshcat: Meshcat | None = None,
    log: bool | Collection[str] = True,
    systems: Mapping[str, System] | None = None,
) -> UuvDiagram:
    """Builds the paper's closed loop from a validated scenario.

    Systems: ``uuv`` (the plant slot's variant), ``navigation``, ``target``, ``sonar``,
    ``estimator``, ``attitude_generator`` and ``tracking_controller`` (the other slots). Each
    input port is connected to the output port of the same name (the names are
    :data:`drake_uuv.signals.SIGNALS`); each random input port gets a named, seeded
    ``RandomSource`` (named like the port) followed by a ``ZeroOrderHold`` (``<name>_hold``)
    so that publishes and updates of one step see the same draw: Drake's ``RandomSource`` draws
    its next sample in an *unrestricted* update, which the Simulator runs before the same
    tick's discrete updates, so a system reading the source directly would see draw n at the
    tick's publish (the loggers) and draw n + 1 in its discrete updates (the plant, the
    filter), and the log would not hold the measurement the filter used. The sources of
    :data:`SEEDED_LAST` (the navigation) are added after all others, so a seed's other draws
    do not depend on the navigation's variant. Loggers are ``log_<name>`` for each logged
    signal, sampled once per step so column k holds the value at step k, before that step's
    update.

    ``systems`` maps names of the loop's systems (:data:`SYSTEM_NAMES`) to systems of your
    own, used instead of the scenario's: e.g. ``systems={"estimator": MyEstimator()}`` with
    any ``LeafSystem`` that reads the signals it needs by name and outputs its slot's
    signals. Pass a ``builder`` to add systems of your own before building, ``log=False`` for
    a diagram without loggers (a picture of the loop itself), ``log`` a collection of signal
    names to log only those (a study's runs log what their metrics read), and ``meshcat`` to
    draw the scene live (a :class:`~drake_uuv.visualization.live_visualizer.LiveMeshcatVisualizer`
    named ``meshcat_visualizer``). A system that lacks a signal of its slot (named with its
    variant's tag, or ``given <class>`` for one of ``systems``), or reads one nobody
    produces, is refused with a one-line ``ValueError`` naming the system and the port.
    """
    t = scenario.time_step
    builder = builder or DiagramBuilder()
    given = set(systems or {})
    systems = make_systems(scenario, systems)
    for name, system in systems.items():
        check_contract(name, system, _origin(scenario, name, system, name in given))
        builder.AddNamedSystem(name, system)
    readers = dict(systems)
    if meshcat is not None:
        visualizer = LiveMeshcatVisualizer(
            meshcat, baseline_B=np.asarray(scenario.sonar.baseline), publish_period=t
        )
        readers["meshcat_visualizer"] = builder.AddNamedSystem("meshcat_visualizer", visualizer)

    producers = _producers(systems)
    noise = []
    # Drake seeds the sources in the order they are added, each from the same generator: the
    # navigation's come last so that a seed gives the target, the sonars and the attitude the
    # same draws whatever the navigation (its cost is measured on the same run).
    for name, system in sorted(readers.items(), key=lambda item: item[0] == SEEDED_LAST):
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

    signals = {signal.name: signal for signal in _chosen_signals(systems, log)}
    loggers = {}
    for signal in signals.values():
        logger = LogVectorOutput(producers[signal.name], builder, t)
        logger.set_name(f"log_{signal.name}")
        loggers[signal.name] = logger

    diagram = builder.Build()
    diagram.set_name("uuv_closed_loop")
    return UuvDiagram(diagram, systems, loggers, signals, noise)


def _chosen_signals(systems: dict[str, System], log: bool | Collection[str]) -> list[Signal]:
    """The logged signals ``log`` asks for: all (True), none (False) or those it names."""
    if isinstance(log, bool):
        return logged_signals(systems) if log else []
    if isinstance(log, str):
        raise ValueError(f"log: must be True, False or a collection of signal names, got {log!r}")
    names = set(log)
    return [signal for signal in logged_signals(systems) if signal.name in names]


def _origin(scenario: Scenario, name: str, system: System, given: bool) -> str:
    """Where a system of the loop comes from, for its contract's errors: ``given <class>``
    for one of the caller's, its variant's tag for a slot's, else its name."""
    if given:
        return f"given {type(system).__name__}"
    for slot in SLOT_REGISTRY:
        if slot.system == name:
            return f"!{type(getattr(scenario, slot.section)).__name__}"
    return name


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
