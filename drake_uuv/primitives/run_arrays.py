"""Per-run arrays held as one abstract state value that Drake copies by reference.

Drake copies a system's state whole wherever it needs a copy: the Simulator copies every
discrete group of a system into its update's values before each of its updates and back after
it, and ``Context.Clone`` copies it all. For a particle cloud of 5000 particles and its late
ranges' draws (2.5 MB a run) that copy is most of a step, even while no run of the batch
carries particles. An abstract state is copied through ``copy.deepcopy`` of its Python value,
so a value that is never written in place can be shared by every copy: :class:`RunArrays`
returns itself from ``copy``/``deepcopy``, its arrays are read-only, and a system's update
builds a new one (:meth:`RunArrays.replaced`) for what changes. A state that does not change
in a step then costs nothing to carry.
"""

from typing import Self

import numpy as np


class SharedValue:
    """A value never written in place, so that its copies can be itself: the base of an
    abstract state that Drake's copies share (``copy``/``deepcopy`` return the value)."""

    __slots__ = ()

    def __copy__(self) -> Self:
        return self

    def __deepcopy__(self, memo: dict) -> Self:
        return self


class RunArrays(SharedValue):
    """Named arrays, each with a leading run axis (B), immutable: copies share them.

    ``RunArrays(particles=array, live=array)``; ``value.particles`` reads one (a read-only
    array). :meth:`replaced` gives a new value with some arrays replaced; :meth:`runs` the
    arrays by name (what a test compares run by run).
    """

    __slots__ = ("_arrays",)

    def __init__(self, **arrays: np.ndarray) -> None:
        frozen = {}
        for name, array in arrays.items():
            array = np.asarray(array)
            if array.flags.writeable:  # a view read-only, so that no one writes it in place
                array = array.view()
                array.flags.writeable = False
            frozen[name] = array
        object.__setattr__(self, "_arrays", frozen)

    def __getattr__(self, name: str) -> np.ndarray:
        try:
            return self._arrays[name]
        except KeyError:
            raise AttributeError(f"RunArrays has no array {name!r}") from None

    def __setattr__(self, name: str, value: object) -> None:
        raise AttributeError("RunArrays is immutable: build a new one with replaced()")

    def replaced(self, **arrays: np.ndarray) -> "RunArrays":
        """A new value: these arrays in place of the same-named ones, the others shared."""
        unknown = set(arrays) - set(self._arrays)
        if unknown:
            raise ValueError(f"replaced: no arrays named {sorted(unknown)}")
        return RunArrays(**{**self._arrays, **arrays})

    def runs(self) -> dict[str, np.ndarray]:
        """The arrays by name (each ``(B, ...)``)."""
        return dict(self._arrays)

    def __repr__(self) -> str:
        shapes = ", ".join(f"{name}={array.shape}" for name, array in self._arrays.items())
        return f"RunArrays({shapes})"


def kept_rows(array: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """A new writable array like ``array`` (B, ...) holding the rows of the runs in ``keep``
    (B bool); the other rows are left unset, for an update that writes them whole (copying
    them first would be wasted)."""
    new = np.empty_like(array)
    for r in np.flatnonzero(keep):
        new[r] = array[r]
    return new
