"""Random input ports the builder can find: pydrake does not expose a port's random type."""

from pydrake.common import RandomDistribution
from pydrake.systems.framework import InputPort, LeafSystem

#: The attribute of a system listing its random input ports: name → distribution.
RANDOM_INPUTS = "random_inputs"


def declare_random_input(
    system: LeafSystem, name: str, size: int, distribution: RandomDistribution
) -> InputPort:
    """Declares a random vector input port and records it in ``system.random_inputs``.

    The builder feeds each recorded port from a seeded ``RandomSource`` of its distribution
    (standard normal, uniform on [0, 1) or exponential of mean 1), sampled once per step.
    """
    port = system.DeclareVectorInputPort(name, size, distribution)
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
