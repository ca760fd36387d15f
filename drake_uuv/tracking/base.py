"""What every tracking law gets from the rest of the scenario: :class:`TrackingSetting`."""

from dataclasses import dataclass

from drake_uuv.primitives.setting import time_step_field


@dataclass(frozen=True)
class TrackingSetting:
    """What every system of the tracking slot gets besides its own configuration.

    A tracking controller is built as
    ``cls(config, setting=TrackingSetting(...), batch_size=B)``; the slot's factory
    (:func:`drake_uuv.tracking.make_tracking_controller`) makes the setting from the scenario.
    Fields:

    - ``time_step``: t [s], the period of the loop (the scenario's ``time_step``): the
      relative double integrator the gains are designed on steps by it.

    A bad field raises ``ValueError`` naming it and its value.
    """

    time_step: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "time_step", time_step_field(self.time_step))
