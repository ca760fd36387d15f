"""The builder: every system named, inputs wired by name, slot contracts checked."""

import numpy as np
import pytest
from pydrake.systems.framework import LeafSystem

from drake_uuv.diagram import make_uuv_diagram
from drake_uuv.estimators import RangeDifferenceKalmanFilter
from drake_uuv.estimators.factory import ESTIMATORS
from drake_uuv.plants.factory import PLANTS
from drake_uuv.scenario import KinematicUuv, PaperKf, load_scenario
from drake_uuv.signals import SIGNALS, check_contract


def test_names_systems_sources_and_loggers(paper) -> None:
    built = make_uuv_diagram(paper)
    diagram = built.diagram
    slots = ["uuv", "target", "sonar", "estimator", "attitude_generator", "tracking_controller"]
    assert list(built.systems) == slots
    for name in [*slots, "acceleration_noise", "acceleration_noise_hold", "range_noise"]:
        assert diagram.HasSubsystemNamed(name), name
    logged = [s.name for s in SIGNALS if s.logged]
    assert sorted(built.loggers) == sorted(logged)
    for name in logged:
        assert diagram.HasSubsystemNamed(f"log_{name}")
    assert not make_uuv_diagram(paper, log=False).loggers


def test_every_input_is_connected_to_the_output_of_its_name(paper) -> None:
    """Evaluating every system's inputs in a default context raises if one is unconnected."""
    built = make_uuv_diagram(paper)
    context = built.diagram.CreateDefaultContext()
    for system in built.systems.values():
        sub = system.GetMyContextFromRoot(context)
        for i in range(system.num_input_ports()):
            assert np.all(np.isfinite(system.get_input_port(i).Eval(sub)))


class _NoAttitude(LeafSystem):
    """A plant that forgets an output of its slot's contract."""

    def __init__(self) -> None:
        super().__init__()
        self.DeclareVectorInputPort("u1_B", 3)
        self.DeclareVectorInputPort("u2_W", 3)
        for name in ("p_WU", "v_WU"):
            self.DeclareVectorOutputPort(name, 3, lambda context, output: output.SetZero())


class _NeedsSomethingElse(_NoAttitude):
    """A plant with a complete contract that reads a signal nobody produces."""

    def __init__(self) -> None:
        super().__init__()
        self.DeclareVectorOutputPort("R_WB", 9, lambda context, output: output.SetZero())
        self.DeclareVectorInputPort("water_current_W", 3)


def test_a_plant_missing_a_contract_output_is_refused(paper, monkeypatch) -> None:
    monkeypatch.setitem(PLANTS, KinematicUuv, lambda scenario: _NoAttitude())
    with pytest.raises(ValueError, match=r"^uuv \(!KinematicUuv\): has no output port 'R_WB'"):
        make_uuv_diagram(paper)


def test_an_input_without_a_producer_is_refused(paper, monkeypatch) -> None:
    monkeypatch.setitem(PLANTS, KinematicUuv, lambda scenario: _NeedsSomethingElse())
    with pytest.raises(ValueError, match=r"^uuv: input port 'water_current_W' has no producer"):
        make_uuv_diagram(paper)


def test_a_signal_with_two_producers_is_refused(paper, monkeypatch) -> None:
    def estimator_with_a_stray_output(scenario):
        system = RangeDifferenceKalmanFilter.from_scenario(scenario)
        system.DeclareVectorOutputPort("p_WT", 3, lambda context, output: output.SetZero())
        return system

    monkeypatch.setitem(ESTIMATORS, PaperKf, estimator_with_a_stray_output)
    with pytest.raises(ValueError, match=r"^estimator and target both output 'p_WT'"):
        make_uuv_diagram(paper)


def test_contract_sizes_are_checked() -> None:
    class WrongSize(_NoAttitude):
        def __init__(self) -> None:
            super().__init__()
            self.DeclareVectorOutputPort("R_WB", 4, lambda context, output: output.SetZero())

    with pytest.raises(
        ValueError, match=r"^uuv \(test\): output port 'R_WB' has size 4, expected 9"
    ):
        check_contract("uuv", WrongSize(), "test")


def test_random_ports_of_a_variant_get_their_own_source() -> None:
    built = make_uuv_diagram(load_scenario("paper", ["attitude=!RandomAttitude"]))
    assert built.diagram.HasSubsystemNamed("rotation_noise")
    assert built.diagram.HasSubsystemNamed("rotation_noise_hold")


def test_set_random_context_latches_the_first_draw_and_reproduces_a_run(paper) -> None:
    """Step 0's noise is the seeded first draw (not the hold's zero), and a seed fixes it."""
    built = make_uuv_diagram(paper)
    context = built.diagram.CreateDefaultContext()
    draws = []
    for seed in (5, 5, 6):
        built.set_random_context(context, seed)
        hold = built.diagram.GetSubsystemByName("range_noise_hold")
        draws.append(hold.get_output_port().Eval(hold.GetMyContextFromRoot(context)).copy())
    assert np.all(draws[0] != 0.0)
    np.testing.assert_array_equal(draws[0], draws[1])
    assert not np.array_equal(draws[0], draws[2])


def test_a_variant_missing_from_its_factory_is_named(paper, monkeypatch) -> None:
    monkeypatch.delitem(PLANTS, KinematicUuv)
    with pytest.raises(
        TypeError, match=r"^plant: no system for !KinematicUuv in the slot's factory"
    ):
        make_uuv_diagram(paper)
