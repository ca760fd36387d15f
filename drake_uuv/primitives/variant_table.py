"""The one dispatch every slot's factory does: a variant dataclass's type → its system."""

from typing import TypeVar

S = TypeVar("S")


def variant_system(table: dict[type, S], config: object, slot: str) -> S:
    """``table[type(config)]``: the entry of the slot's variant ``config``.

    A variant with no entry (its dataclass added to the scenario, its line to the factory's
    table forgotten) raises ``TypeError`` naming the slot and the tag.
    """
    entry = table.get(type(config))
    if entry is None:
        raise TypeError(f"{slot}: no system for !{type(config).__name__} in the slot's factory")
    return entry
