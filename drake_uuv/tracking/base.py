"""What every tracking law gets from the rest of the scenario: :class:`TrackingSetting`."""

import math
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
    - ``max_speed``: the plant's top speed [m/s] (the scenario's ``plant.top_speed()``), or
      None. With one the law limits its command so that the navigated velocity stays within
      it (it then reads ``v_WU_nav``), and reports that limited acceleration on ``u1_W``:
      the filter predicts with what the vehicle does, not with what it was asked.
    - ``estimator_hands_over``: the estimator starts linear and hands over, publishing its
      phase on ``estimator_phase`` (the raw-range filters); false for one that does not (the
      paper's KF, its own linear start throughout), for which ``hold_until_handover`` holds
      nothing: there is no hand-over to wait for.

    A bad field raises ``ValueError`` naming it and its value.
    """

    time_step: float
    max_speed: float | None = None
    estimator_hands_over: bool = True

    def __post_init__(self) -> None:
        object.__setattr__(self, "time_step", time_step_field(self.time_step))
        speed = self.max_speed
        if speed is not None and not (
            isinstance(speed, int | float) and not isinstance(speed, bool)
            and math.isfinite(speed) and speed > 0.0
        ):  # fmt: skip
            raise ValueError(f"max_speed: must be None or > 0, got {speed!r}")
        if not isinstance(self.estimator_hands_over, bool):
            raise ValueError(
                f"estimator_hands_over: must be true or false, got {self.estimator_hands_over!r}"
            )
