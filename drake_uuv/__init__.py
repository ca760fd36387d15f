"""drake_uuv: range-only relative state estimation of a target by a UUV, as a Drake diagram.

The names below are imported on first use (PEP 562), so that ``import drake_uuv.cli`` and
``drake-uuv --help`` do not load Drake: a command can refuse bad input at once.
"""

import importlib
from typing import TYPE_CHECKING, Any

from drake_uuv.kernel_cache import refresh_kernel_cache

refresh_kernel_cache()  # before any kernel module loads its cache (see drake_uuv.kernel_cache)

if TYPE_CHECKING:  # for type checkers and editors; "X as X" marks a re-export
    from drake_uuv.diagram import UuvDiagram as UuvDiagram
    from drake_uuv.diagram import make_uuv_diagram as make_uuv_diagram
    from drake_uuv.scenario import Scenario as Scenario
    from drake_uuv.scenario import ScenarioError as ScenarioError
    from drake_uuv.scenario import load_scenario as load_scenario
    from drake_uuv.simulation import ClosedLoopSimulation as ClosedLoopSimulation
    from drake_uuv.simulation import SimulationResult as SimulationResult
    from drake_uuv.simulation import simulate as simulate

# Public name → the module that defines it.
_EXPORTS = {
    "ClosedLoopSimulation": "drake_uuv.simulation",
    "Scenario": "drake_uuv.scenario",
    "ScenarioError": "drake_uuv.scenario",
    "SimulationResult": "drake_uuv.simulation",
    "UuvDiagram": "drake_uuv.diagram",
    "load_scenario": "drake_uuv.scenario",
    "make_uuv_diagram": "drake_uuv.diagram",
    "simulate": "drake_uuv.simulation",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name not in _EXPORTS:
        raise AttributeError(f"module 'drake_uuv' has no attribute {name!r}")
    value = getattr(importlib.import_module(_EXPORTS[name]), name)
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *_EXPORTS])
