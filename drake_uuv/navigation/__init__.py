"""Navigation: what the vehicle knows of its own attitude, velocity and position.

Contract of the slot (system ``navigation``): inputs ``p_WU``, ``v_WU``, ``R_WB`` (the
truth, from the plant), and any random input it declares (``navigation_noise``,
``navigation_bias`` for the inertial navigation); outputs ``p_WU_nav``, ``v_WU_nav`` and
``R_WB_nav`` (row-major), what the vehicle believes of itself. Every consumer of the vehicle's
state (the estimator, the attitude generators, the tracking laws) reads these, never the
truth. See :mod:`drake_uuv.signals`. Each system is built as
``cls(config, setting=NavigationSetting(...), batch_size=B)``
(:class:`~drake_uuv.navigation.base.NavigationSetting`).
"""

from drake_uuv.navigation.base import NavigationSetting
from drake_uuv.navigation.factory import NAVIGATIONS, make_navigation, navigation_setting
from drake_uuv.navigation.inertial_navigation import InertialNavigationSystem
from drake_uuv.navigation.perfect_navigation import PerfectNavigationSystem

__all__ = [
    "NAVIGATIONS",
    "InertialNavigationSystem",
    "NavigationSetting",
    "PerfectNavigationSystem",
    "make_navigation",
    "navigation_setting",
]
