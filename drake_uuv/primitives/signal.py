"""A signal of the closed loop: an output port, and how a run logs it."""

from dataclasses import dataclass


@dataclass(frozen=True)
class Signal:
    """One output port of the closed loop, and how a run logs it."""

    name: str  # port name = logger name without "log_" = log.npz key
    system: str  # the name of the system in the diagram that outputs it
    shape: tuple[int, ...]  # one step's value in the log; () for a scalar
    meaning: str
    logged: bool = True
    integer: bool = False  # a status code: logged as int8

    @property
    def size(self) -> int:
        """The port's size (the product of ``shape``)."""
        size = 1
        for n in self.shape:
            size *= n
        return size
