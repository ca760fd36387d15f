"""One half of the loop as a diagram of its own, talking to the other half over LCM.

A :class:`Half` holds the systems of one side (:data:`~.channels.ONBOARD` or
:data:`~.channels.VEHICLE`), wired by the loop's rule (every input to the output of the same
name; random inputs from per-run noise named like the port), with an ``LcmSubscriberSystem``
and a :class:`~.channels.ScopeToVector` for each channel it reads and a
:class:`~.channels.VectorToScope` and an ``LcmPublisherSystem`` (forced publishes only) for
each it writes. The driver (:mod:`.loop`) decides when: :meth:`Half.publish` sends the half's
channels at the current time, :meth:`Half.receive` waits for the other half's messages of the
step and latches them (the subscribers' forced update), :meth:`Half.advance` steps the half's
``Simulator``, and :meth:`Half.sample` reads the half's signals of the step for its log.
"""

import time
from collections.abc import Callable, Mapping

import numpy as np
from drake import lcmt_scope
from pydrake.lcm import DrakeLcm
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, System, TriggerType
from pydrake.systems.lcm import LcmPublisherSystem, LcmSubscriberSystem

from drake_uuv.hardware.channels import (
    ONBOARD,
    VEHICLE,
    Channel,
    ScopeToVector,
    VectorToScope,
    channels,
)
from drake_uuv.primitives import random_inputs
from drake_uuv.primitives.run_noise import RunNoise
from drake_uuv.signals import Signal


class LcmTimeout(RuntimeError):
    """The other half did not answer in time (named: the channel and the step)."""


class Half:
    """One half of the loop (``side`` ``"onboard"`` or ``"vehicle"``) over ``lcm``.

    ``systems`` is the whole loop's systems by name (from
    :func:`drake_uuv.diagram.make_systems`; this half takes its own); ``signals`` the logged
    signals, of which this half samples those its systems produce; ``seed`` seeds its noise.
    """

    def __init__(
        self,
        side: str,
        systems: Mapping[str, System],
        lcm: DrakeLcm,
        *,
        time_step: float,
        signals: list[Signal],
        seed: int,
        timeout: float = 10.0,
    ) -> None:
        if side not in ("onboard", "vehicle"):
            raise ValueError(f"side: must be onboard or vehicle, got {side!r}")
        names = ONBOARD if side == "onboard" else VEHICLE
        other = VEHICLE if side == "onboard" else ONBOARD
        self.side, self.lcm, self.time_step, self.timeout = side, lcm, time_step, timeout
        self.reads = channels(dict(systems), names)
        self.writes = channels(dict(systems), other)
        builder = DiagramBuilder()
        mine = {name: builder.AddNamedSystem(name, systems[name]) for name in names}
        producers = {}
        for system in mine.values():
            for i in range(system.num_output_ports()):
                producers[system.get_output_port(i).get_name()] = system.get_output_port(i)
        self.subscribers: list[tuple[Channel, LcmSubscriberSystem]] = []
        for channel in self.reads:
            subscriber = builder.AddNamedSystem(
                f"subscribe_{channel.name}", LcmSubscriberSystem.Make(channel.name, lcmt_scope, lcm)
            )
            unpack = builder.AddNamedSystem(f"unpack_{channel.name}", ScopeToVector(channel))
            builder.Connect(subscriber.get_output_port(), unpack.get_input_port())
            for name, _ in channel.signals:
                producers[name] = unpack.GetOutputPort(name)
            self.subscribers.append((channel, subscriber))
        self.noise = self._wire(builder, mine, producers)
        self.publishers = []
        for channel in self.writes:
            pack = builder.AddNamedSystem(f"pack_{channel.name}", VectorToScope(channel))
            for name, _ in channel.signals:
                builder.Connect(producers[name], pack.GetInputPort(name))
            publisher = builder.AddNamedSystem(
                f"publish_{channel.name}",
                LcmPublisherSystem.Make(
                    channel.name, lcmt_scope, lcm, publish_triggers={TriggerType.kForced}
                ),
            )
            builder.Connect(pack.get_output_port(), publisher.get_input_port())
            self.publishers.append(publisher)
        self.systems = mine
        self._ports = {s.name: producers[s.name] for s in signals if s.name in producers}
        # The signals this half's own systems produce (the others it received).
        self.own = {s.name for s in signals if s.system in mine or _extra(s, mine)}
        self.diagram = builder.Build()
        self.diagram.set_name(f"uuv_{side}")
        self.simulator = Simulator(self.diagram)
        configure = getattr(mine.get("uuv"), "configure_simulator", None)
        if configure is not None:
            configure(self.simulator)
        self.context = self.simulator.get_mutable_context()
        seeds = np.array([seed])
        for source in self.noise:
            source.set_seeds(source.GetMyMutableContextFromRoot(self.context), seeds)
        self._heard: dict[str, tuple[int, int]] = {}  # channel → (messages, last utime)
        self._latched: dict[str, int] = {}  # channel → messages when last latched
        for channel, _ in self.subscribers:
            self._heard[channel.name], self._latched[channel.name] = (0, -1), 0
            lcm.Subscribe(channel.name, lambda data, name=channel.name: self._hear(name, data))

    def _wire(
        self, builder: DiagramBuilder, mine: dict[str, System], producers: dict
    ) -> list[RunNoise]:
        """Every input of this half's systems to its producer, random ones to their noise."""
        noise = []
        for system in mine.values():
            random = random_inputs(system)
            for i in range(system.num_input_ports()):
                port = system.get_input_port(i)
                signal = port.get_name()
                if signal in random:
                    source = RunNoise(signal, random[signal], port.size(), time_step=self.time_step)
                    builder.AddNamedSystem(signal, source)
                    builder.Connect(source.get_output_port(), port)
                    noise.append(source)
                else:
                    builder.Connect(producers[signal], port)
        return noise

    def _hear(self, channel: str, data: bytes) -> None:
        count, _ = self._heard[channel]
        self._heard[channel] = (count + 1, lcmt_scope.decode(data).utime)

    def publish(self) -> None:
        """Sends this half's channels, from its state and inputs at the current time."""
        for publisher in self.publishers:
            publisher.ForcedPublish(publisher.GetMyContextFromRoot(self.context))

    def receive(self, step: int | None, waiting: Callable[[], None] | None = None) -> None:
        """Waits for a message not yet latched on each channel this half reads (of ``step``,
        or of the initial state for None), then latches them into the subscribers.
        ``waiting`` is called while there is none yet (the onboard half's ready signal)."""
        utime = None if step is None else round(step * self.time_step * 1e6)
        deadline = time.monotonic() + self.timeout

        def missing() -> list[str]:
            return [
                name for name, (count, last) in self._heard.items()
                if count <= self._latched[name] or (utime is not None and last < utime)
            ]  # fmt: skip

        while late := missing():
            if time.monotonic() > deadline:
                when = "the initial state" if step is None else f"step {step}"
                raise LcmTimeout(
                    f"{self.side}: no message on {', '.join(late)} for {when} within "
                    f"{self.timeout:g} s"
                )
            if waiting is not None:
                waiting()
            self.lcm.HandleSubscriptions(10)
        for name, (count, last) in self._heard.items():
            if utime is not None and last != utime:
                raise LcmTimeout(
                    f"{self.side}: {name} sent utime {last} at step {step}, expected {utime} "
                    "(the halves are out of step)"
                )
            self._latched[name] = count
        for _, subscriber in self.subscribers:
            subscriber.ExecuteForcedEvents(subscriber.GetMyMutableContextFromRoot(self.context))

    def initialize(self) -> None:
        self.simulator.Initialize()

    def advance(self, step: int) -> None:
        """Steps this half's Simulator to step ``step`` (its updates of step − 1)."""
        self.simulator.AdvanceTo(step * self.time_step)

    def sample(self, received: bool = False) -> dict[str, np.ndarray]:
        """This half's logged signals now, each a flat vector: those its systems produce,
        and with ``received`` those it received too."""
        return {
            name: port.Eval(port.get_system().GetMyContextFromRoot(self.context)).copy()
            for name, port in self._ports.items()
            if received or name in self.own
        }


def _extra(signal: Signal, mine: dict[str, System]) -> bool:
    """Whether ``signal`` is an extra signal of one of these systems."""
    return any(signal in getattr(system, "extra_signals", ()) for system in mine.values())
