"""drake_uuv: range-only relative state estimation of a target by a UUV, as a Drake diagram."""

from drake_uuv.diagram import UuvDiagram, make_uuv_diagram
from drake_uuv.scenario import Scenario, ScenarioError, load_scenario
from drake_uuv.simulation import ClosedLoopSimulation, SimulationResult, simulate

__all__ = [
    "ClosedLoopSimulation",
    "Scenario",
    "ScenarioError",
    "SimulationResult",
    "UuvDiagram",
    "load_scenario",
    "make_uuv_diagram",
    "simulate",
]
