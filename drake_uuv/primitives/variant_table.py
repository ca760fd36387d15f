"""The one dispatch every slot's factory does: a variant dataclass's type → its system."""

from collections.abc import Callable
from typing import Any, TypeVar

S = TypeVar("S")


def build_variant(table: dict[type, Callable[[Any], S]], scenario: Any, slot: str) -> S:
    """``table[type(scenario.<slot>)](scenario)``: the system of the slot's variant.

    A variant with no entry (its dataclass added to the scenario, its line to the factory's
    table forgotten) raises ``TypeError`` naming the slot and the tag.
    """
    config = getattr(scenario, slot)
    make = table.get(type(config))
    if make is None:
        raise TypeError(f"{slot}: no system for !{type(config).__name__} in the slot's factory")
    return make(scenario)
