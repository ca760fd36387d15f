"""Random input ports the builder can find: pydrake does not expose a port's random type."""

from pydrake.common import RandomDistribution
from pydrake.systems.framework import InputPort, LeafSystem

#: The attribute of a system listing its random input ports: name → distribution.
RANDOM_INPUTS = "random_inputs"


def declare_random_input(
    system: LeafSystem,
    name: str,
    size: int,
    distribution: RandomDistribution,
    *,
    batch_size: int = 1,
) -> InputPort:
    """Declares a random vector input port of ``size`` values per run for a batch of
    ``batch_size`` runs (``batch_size · size`` entries, row-major by run) and records it in
    ``system.random_inputs``.

    The builder feeds each recorded port from a :class:`~drake_uuv.primitives.run_noise.RunNoise`
    source of its distribution (standard normal, uniform on [0, 1) or exponential of mean 1),
    named like the port, whose run i draws from run i's own seed: one draw per run and step,
    the same at the tick's publish and updates.
    """
    port = system.DeclareVectorInputPort(name, batch_size * size, distribution)
    if not hasattr(system, RANDOM_INPUTS):
        setattr(system, RANDOM_INPUTS, {})
    getattr(system, RANDOM_INPUTS)[name] = distribution
    return port


def random_inputs(system: object) -> dict[str, RandomDistribution]:
    """The random input ports a system declared with :func:`declare_random_input`."""
    return dict(getattr(system, RANDOM_INPUTS, {}))


def export_random_inputs(diagram: object, system: object) -> None:
    """Records on ``diagram`` the random input ports of ``system`` it exports under the same
    names (a system of the loop that is a diagram of smaller ones)."""
    setattr(diagram, RANDOM_INPUTS, random_inputs(system))
