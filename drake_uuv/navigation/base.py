"""What every navigation system gets from the rest of the scenario: :class:`NavigationSetting`."""

from dataclasses import dataclass

from drake_uuv.primitives.setting import InitialStateSetting


@dataclass(frozen=True)
class NavigationSetting(InitialStateSetting):
    """What every system of the navigation slot gets besides its own configuration.

    A navigation system is built as
    ``cls(config, setting=NavigationSetting(...), batch_size=B)``; the slot's factory
    (:func:`drake_uuv.navigation.make_navigation`) makes the setting from the scenario
    (:func:`drake_uuv.navigation.factory.navigation_setting`). Fields:

    - ``time_step``: t [s], the period of the loop (the scenario's ``time_step``): the
      instruments are sampled at its ticks and dead reckoning integrates over it.
    - ``initial_position``: ``p_WU(0)`` (3) [m], ``initial_velocity``: ``v_WU(0)`` (3) [m/s]
      and ``initial_R_WB``: ``R_WB(0)`` (3×3), the vehicle's known start (``uuv.initial_*``,
      the attitude as Drake's ``RollPitchYaw``). The variants of today read the truth at
      every tick, the start included; a navigation that integrates from the start alone
      (no truth input) would start here.

    Arrays are stored read-only; a bad field raises ``ValueError`` naming it and its value.
    """
