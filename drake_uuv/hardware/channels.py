"""The LCM channels between the loop's two halves, and the systems that pack them.

The loop splits, as Drake's hardware station does, into the **onboard** half (what runs on
the vehicle's computer: the estimator, the attitude generator, the tracking controller) and
the **vehicle** half (the plant, the target, the sonars and the navigation: a real vehicle's
hardware and its navigation, or their simulation). Each signal one half reads from the other
travels on the channel of the system producing it, ``DRAKE_UUV_<SYSTEM>``, as Drake's own
``drake::lcmt_scope`` (``utime``, the step's time in µs; ``size``; ``value``, the signals end
to end in the order of :data:`drake_uuv.signals.SIGNALS`, each row-major as on its port).
The channels (:func:`channels`; the paper's scenario sends only those the paper's systems
read, ``R_WB_nav``, ``range_samples`` and ``sonar_status`` one way, ``u2_W`` and ``u1_B`` the
other):

- ``DRAKE_UUV_NAVIGATION`` (vehicle → onboard): ``p_WU_nav`` (3) and ``v_WU_nav`` (3) for an
  estimator of ``vehicle_motion: navigation``, ``R_WB_nav`` (9, row-major): the navigated
  state of the sonars' midpoint U in the world W (z up) and the attitude, body to world.
- ``DRAKE_UUV_SONAR`` (vehicle → onboard): ``range_samples`` (2f, sonar 1's then sonar 2's,
  NaN without a return), ``sonar_status`` (2: 0 valid, 1 dropped, 2 out of beam, 3 out of
  range, 5 no arrival), and with late ranges ``ping_time`` (2, each range's ping time [s]).
- ``DRAKE_UUV_ATTITUDE_GENERATOR`` (onboard → vehicle): ``u2_W`` (3), the commanded angular
  velocity in W [rad/s] (and ``R_WB_plan`` (18) for a plant that reads it).
- ``DRAKE_UUV_TRACKING_CONTROLLER`` (onboard → vehicle): ``u1_B`` (3), the commanded
  acceleration in the body frame [m/s²].
- ``DRAKE_UUV_READY`` (onboard → vehicle, an empty ``lcmt_scope``): the onboard half is
  listening; the vehicle waits for it before its first message.
- ``DRAKE_UUV_INITIALIZED`` (onboard → vehicle, an empty ``lcmt_scope``): the onboard half
  has initialized from the vehicle's first messages; the vehicle waits for it before step 0's
  (sent sooner, both could reach the onboard half before it latched the first, and it would
  then wait for a third that never comes).

The steps go in lockstep: the vehicle sends one message on each of its channels before the
loop (its state when the onboard half initializes) and then one each step k; the onboard half
answers each step with its commands, which the vehicle applies over the step.
"""

from dataclasses import dataclass

import numpy as np
from drake import lcmt_scope
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, Context, LeafSystem, System

from drake_uuv.primitives.batch import batch_size_field
from drake_uuv.signals import SIGNALS

#: The systems of each half, by their names in the loop.
ONBOARD = ("estimator", "attitude_generator", "tracking_controller")
VEHICLE = ("uuv", "navigation", "target", "sonar")
#: The channel on which the onboard half says it is listening.
READY = "DRAKE_UUV_READY"
#: The channel on which the onboard half says it has initialized.
INITIALIZED = "DRAKE_UUV_INITIALIZED"
#: The only system of the vehicle half that may read the onboard half: the plant, whose
#: update applies the step's commands (a system whose outputs the onboard half reads in the
#: same step could not be answered in lockstep).
COMMANDED = "uuv"


class SplitError(ValueError):
    """A loop that cannot be split into halves over LCM (the message names why)."""


def check_url(url: str) -> str:
    """``url`` if it names an LCM network Drake can open: ``memq://`` (one process) or
    ``udpm://ADDRESS:PORT`` with options (Drake's ``DrakeLcm`` only prints a bad one)."""
    if not (url == "memq://" or url.startswith("udpm://")):
        raise SplitError(
            f"must be memq:// (one process) or udpm://ADDRESS:PORT?ttl=0 (this host), got {url!r}"
        )
    return url


@dataclass(frozen=True)
class Channel:
    """A channel: its name, the system whose signals it carries, the signals and sizes."""

    name: str
    producer: str
    signals: tuple[tuple[str, int], ...]

    @property
    def size(self) -> int:
        return sum(size for _, size in self.signals)

    def describe(self) -> str:
        return f"{self.name} ({', '.join(f'{n} {s}' for n, s in self.signals)})"


def _order(name: str) -> int:
    return next((i for i, s in enumerate(SIGNALS) if s.name == name), len(SIGNALS))


def channels(systems: dict[str, System], reader: tuple[str, ...]) -> list[Channel]:
    """The channels the half of ``reader`` (system names) receives from the other half:
    every input of its systems produced by a system of the other half, grouped by producer.
    A vehicle system other than the plant reading the onboard half is refused naming it."""
    producers = {}
    for name, system in systems.items():
        for i in range(system.num_output_ports()):
            port = system.get_output_port(i)
            producers[port.get_name()] = (name, port.size())
    wanted: dict[str, dict[str, int]] = {}
    for name in reader:
        system = systems[name]
        for i in range(system.num_input_ports()):
            signal = system.get_input_port(i).get_name()
            if signal not in producers or producers[signal][0] in reader:
                continue
            producer, size = producers[signal]
            if reader == VEHICLE and name != COMMANDED:
                raise SplitError(
                    f"{name}: reads {signal!r} from the onboard half ({producer}); over LCM the "
                    "vehicle half reads only its commands, in its plant"
                )
            wanted.setdefault(producer, {})[signal] = size
    return [
        Channel(
            f"DRAKE_UUV_{producer.upper()}",
            producer,
            tuple(sorted(signals.items(), key=lambda item: _order(item[0]))),
        )
        for producer, signals in sorted(wanted.items())
    ]


def _single_run(batch_size: int) -> None:
    if batch_size_field(batch_size) != 1:
        raise ValueError(f"batch_size: the loop over LCM runs one run, got {batch_size}")


class ScopeToVector(LeafSystem):
    """A channel's ``lcmt_scope`` unpacked into its signals' ports.

    .. pydrake_system::

        name: ScopeToVector
        input_ports:
        - message
        output_ports:
        - <each signal of the channel>

    ``message`` (abstract ``lcmt_scope``) holds the signals end to end; a message of another
    size is refused naming the channel.
    """

    def __init__(self, channel: Channel, *, batch_size: int = 1) -> None:
        super().__init__()
        _single_run(batch_size)
        self.batch_size = 1
        self._channel = channel
        self._message = self.DeclareAbstractInputPort("message", AbstractValue.Make(lcmt_scope()))
        start = 0
        for name, size in channel.signals:
            self.DeclareVectorOutputPort(
                name,
                BasicVector(size),
                lambda context, out, a=start, b=start + size: out.SetFromVector(
                    self._values(context)[a:b]
                ),
                {self._message.ticket()},
            )
            start += size

    def _values(self, context: Context) -> np.ndarray:
        message = self._message.Eval(context)
        if message.size != self._channel.size:
            raise ValueError(
                f"{self._channel.name}: a message of {message.size} values, expected "
                f"{self._channel.size}: {self._channel.describe()}"
            )
        return np.asarray(message.value, dtype=float)


class VectorToScope(LeafSystem):
    """A channel's signals packed into one ``lcmt_scope``, stamped with the time in µs.

    .. pydrake_system::

        name: VectorToScope
        input_ports:
        - <each signal of the channel>
        output_ports:
        - message
    """

    def __init__(self, channel: Channel, *, batch_size: int = 1) -> None:
        super().__init__()
        _single_run(batch_size)
        self.batch_size = 1
        self._ports = [self.DeclareVectorInputPort(name, size) for name, size in channel.signals]
        self.DeclareAbstractOutputPort(
            "message", lambda: AbstractValue.Make(lcmt_scope()), self._pack
        )

    def _pack(self, context: Context, out: AbstractValue) -> None:
        message = lcmt_scope()
        message.utime = round(context.get_time() * 1e6)
        values = np.concatenate([port.Eval(context) for port in self._ports])
        message.size = len(values)
        message.value = values.tolist()
        out.set_value(message)
