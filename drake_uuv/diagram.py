"""The one builder of the closed loop: every system and logger named, every port wired here."""

from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from pydrake.common import RandomDistribution
from pydrake.geometry import Meshcat
from pydrake.systems.framework import (
    Context,
    Diagram,
    DiagramBuilder,
    InputPort,
    OutputPort,
    System,
)
from pydrake.systems.primitives import LogVectorOutput, VectorLogSink

from drake_uuv.attitude import make_attitude_generator
from drake_uuv.attitude.factory import ATTITUDE_GENERATORS
from drake_uuv.estimators import make_estimator
from drake_uuv.estimators.factory import ESTIMATORS
from drake_uuv.navigation import make_navigation
from drake_uuv.navigation.factory import NAVIGATIONS
from drake_uuv.plants import TargetRandomWalk, make_plant
from drake_uuv.plants.factory import PLANTS
from drake_uuv.primitives import random_inputs
from drake_uuv.primitives.batch import batch_size_field, batch_size_of
from drake_uuv.primitives.run_noise import RunNoise
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


@dataclass
class UuvDiagram:
    """The built diagram and handles a caller needs: its systems, loggers and signals by name.

    ``batch_size`` is the number of runs the diagram steps at once (every port and state holds
    that many runs, row-major by run; :mod:`drake_uuv.primitives.batch`). Seed a context with
    :meth:`set_random_context`: one seed per run.
    """

    diagram: Diagram
    systems: dict[str, System]
    loggers: dict[str, VectorLogSink]
    signals: dict[str, Signal]
    noise: list[RunNoise]
    batch_size: int = 1

    def set_random_context(self, context: Context, seeds: int | Sequence[int]) -> None:
        """Gives run i of the batch its seed ``seeds[i]`` (a single int for a batch of one):
        every noise source then draws run i's numbers from that seed alone
        (:class:`~drake_uuv.primitives.run_noise.RunNoise`)."""
        seeds = np.atleast_1d(np.asarray(seeds))
        for source in self.noise:
            source.set_seeds(source.GetMyMutableContextFromRoot(context), seeds)


def make_systems(
    scenario: Scenario, systems: Mapping[str, System] | None = None, *, batch_size: int = 1
) -> dict[str, System]:
    """The closed loop's systems by name (:data:`SYSTEM_NAMES`): those of ``systems`` as
    given, the others built from their part of the scenario (each slot by its factory), each
    stepping ``batch_size`` runs.

    The wiring across slots is here and in the factories: the sonar's ``m`` and ``Γ``
    follow the estimator section's noise model, whoever supplies the estimator. A given
    system must step the same batch (its ``batch_size``); one without that attribute runs
    only alone.
    """
    B = batch_size_field(batch_size)
    given = dict(systems or {})
    for name, system in given.items():
        if name not in SYSTEM_NAMES:
            raise ValueError(
                f"systems: unknown system name {name!r} (the loop's are {', '.join(SYSTEM_NAMES)})"
            )
        if not isinstance(system, System):
            raise ValueError(f"systems[{name!r}]: must be a Drake System, got {system!r}")
        runs = batch_size_of(system)
        if (runs or 1) != B:
            stepped = "has no batch_size: it steps one run" if runs is None else f"steps {runs}"
            raise ValueError(
                f"systems[{name!r}]: {type(system).__name__} {stepped}, but the diagram "
                f"steps a batch of {B} runs (run it with batch_size=1, run by run)"
            )
    makers: dict[str, Callable[[], System]] = {
        "uuv": lambda: make_plant(scenario, batch_size=B),
        "navigation": lambda: make_navigation(scenario, batch_size=B),
        "target": lambda: TargetRandomWalk(
            scenario.target, time_step=scenario.time_step, batch_size=B
        ),
        "sonar": lambda: DualSonar(
            scenario.sonar,
            noise_model=scenario.estimator.noise_model,
            time_step=scenario.time_step,
            batch_size=B,
        ),
        "estimator": lambda: make_estimator(scenario, batch_size=B),
        "attitude_generator": lambda: make_attitude_generator(scenario, batch_size=B),
        "tracking_controller": lambda: make_tracking_controller(scenario, batch_size=B),
    }
    return {name: given[name] if name in given else makers[name]() for name in SYSTEM_NAMES}


def batch_incapable(scenario: Scenario, systems: Mapping[str, System] | None = None) -> list[str]:
    """The names of the given ``systems`` that cannot step a batch (no ``batch_size``): a
    study with them runs run by run. The scenario's own systems all can."""
    return [name for name, system in (systems or {}).items() if batch_size_of(system) is None]


def make_uuv_diagram(
    scenario: Scenario,
    *,
    builder: DiagramBuilder | None = None,
    meshcat: Meshcat | None = None,
    log: bool | Collection[str] = True,
    systems: Mapping[str, System] | None = None,
    batch_size: int = 1,
) -> UuvDiagram:
    """Builds the paper's closed loop from a validated scenario.

    Systems: ``uuv`` (the plant slot's variant), ``navigation``, ``target``, ``sonar``,
    ``estimator``, ``attitude_generator`` and ``tracking_controller`` (the other slots). Each
    input port is connected to the output port of the same name (the names are
    :data:`drake_uuv.signals.SIGNALS`); each random input port gets a named
    :class:`~drake_uuv.primitives.run_noise.RunNoise` source (named like the port) whose run
    i draws from run i's seed alone (a pure function of seed, source name and step: the same
    draw at a tick's publish and updates, whatever the batch or the other sources; Drake's
    ``RandomSource`` draws one stream for its whole vector). Loggers are ``log_<name>`` for
    each logged signal, sampled once per step: column k holds the value at step k, before
    that step's update.

    ``batch_size`` B builds every system for B runs at once (ports and states hold B runs
    row-major); a system of yours in ``systems`` must step B runs too (its ``batch_size``).

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
    B = batch_size_field(batch_size)
    builder = builder or DiagramBuilder()
    given = set(systems or {})
    systems = make_systems(scenario, systems, batch_size=B)
    for name, system in systems.items():
        check_contract(name, system, _origin(scenario, name, system, name in given), B)
        builder.AddNamedSystem(name, system)
    readers = dict(systems)
    if meshcat is not None:
        if B != 1:
            raise ValueError(f"meshcat: draws one run, got a batch of {B}")
        visualizer = LiveMeshcatVisualizer(
            meshcat, baseline_B=np.asarray(scenario.sonar.baseline), publish_period=t
        )
        readers["meshcat_visualizer"] = builder.AddNamedSystem("meshcat_visualizer", visualizer)

    producers = _producers(systems)
    noise = []
    for name, system in readers.items():
        random = random_inputs(system)
        for i in range(system.num_input_ports()):
            port = system.get_input_port(i)
            if port.get_name() in random:
                noise.append(_add_noise(builder, port, random[port.get_name()], t, B))
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
    return UuvDiagram(diagram, systems, loggers, signals, noise, B)


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
    builder: DiagramBuilder,
    port: InputPort,
    distribution: RandomDistribution,
    time_step: float,
    batch_size: int,
) -> RunNoise:
    """The port's per-run noise: a :class:`RunNoise` named like the port."""
    name = port.get_name()
    size = port.size() // batch_size
    source = RunNoise(name, distribution, size, batch_size=batch_size, time_step=time_step)
    builder.AddNamedSystem(name, source)
    builder.Connect(source.get_output_port(), port)
    return source
