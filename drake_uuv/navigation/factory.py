"""The navigation slot's factory: the system of each variant of ``scenario.navigation``."""

from pydrake.systems.framework import System

from drake_uuv.navigation.base import NavigationSetting
from drake_uuv.navigation.inertial_navigation import InertialNavigationSystem
from drake_uuv.navigation.perfect_navigation import PerfectNavigationSystem
from drake_uuv.primitives.variant_table import variant_system
from drake_uuv.scenario import InertialNavigation, PerfectNavigation, Scenario

#: Variant dataclass → its system, built as ``cls(config, setting=NavigationSetting(...))``.
NAVIGATIONS: dict[type, type[System]] = {
    PerfectNavigation: PerfectNavigationSystem,
    InertialNavigation: InertialNavigationSystem,
}


def navigation_setting(scenario: Scenario) -> NavigationSetting:
    """What a navigation gets from ``scenario``: the period and ``scenario.uuv``'s initial
    state."""
    return NavigationSetting.of(scenario.time_step, scenario.uuv)


def make_navigation(scenario: Scenario, *, batch_size: int = 1) -> System:
    """The navigation of ``scenario.navigation``'s variant."""
    cls = variant_system(NAVIGATIONS, scenario.navigation, "navigation")
    return cls(scenario.navigation, setting=navigation_setting(scenario), **_TRANSITIONAL(batch_size))


def _TRANSITIONAL(batch_size: int) -> dict:  # TRANSITIONAL until the slot's systems batch
    return {} if batch_size == 1 else {"batch_size": batch_size}
