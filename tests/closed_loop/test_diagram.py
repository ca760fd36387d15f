"""The builder: every system named, inputs wired by name, slot contracts checked."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pydrake.systems.framework import LeafSystem

from drake_uuv.diagram import SLOT_REGISTRY, SYSTEM_NAMES, make_uuv_diagram
from drake_uuv.models.tracking_laws import paper_tracking_command
from drake_uuv.plants.factory import PLANTS
from drake_uuv.primitives.run_noise import RunNoise, run_draws
from drake_uuv.scenario import SLOTS, KinematicUuv, Scenario, load_scenario, variants
from drake_uuv.signals import SIGNALS, check_contract
from drake_uuv.simulation import ClosedLoopSimulation
from tests.closed_loop.user_systems import ConstantEstimator, ProportionalTracking

SHORT = ["steps=40", "steady_state_start=10"]


def test_names_systems_sources_and_loggers(paper) -> None:
    built = make_uuv_diagram(paper)
    diagram = built.diagram
    slots = [
        "uuv", "navigation", "target", "sonar", "estimator", "attitude_generator",
        "tracking_controller",
    ]  # fmt: skip
    assert list(built.systems) == slots
    for name in [*slots, "acceleration_noise", "range_noise"]:
        assert diagram.HasSubsystemNamed(name), name
    assert isinstance(diagram.GetSubsystemByName("range_noise"), RunNoise)
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
    monkeypatch.setitem(PLANTS, KinematicUuv, lambda config, *, setting, batch_size: _NoAttitude())
    with pytest.raises(ValueError, match=r"^uuv \(!KinematicUuv\): has no output port 'R_WB'"):
        make_uuv_diagram(paper)
    with pytest.raises(ValueError, match=r"^uuv \(given _NoAttitude\): has no output port 'R_WB'"):
        make_uuv_diagram(paper, systems={"uuv": _NoAttitude()})


def test_an_input_without_a_producer_is_refused(paper) -> None:
    with pytest.raises(ValueError, match=r"^uuv: input port 'water_current_W' has no producer"):
        make_uuv_diagram(paper, systems={"uuv": _NeedsSomethingElse()})


def test_a_signal_with_two_producers_is_refused(paper) -> None:
    estimator = ConstantEstimator(np.zeros(6), np.eye(6))
    estimator.DeclareVectorOutputPort("p_WT", 3, lambda context, output: output.SetZero())
    with pytest.raises(ValueError, match=r"^estimator and target both output 'p_WT'"):
        make_uuv_diagram(paper, systems={"estimator": estimator})


@pytest.mark.parametrize(
    "systems, message",
    [
        ({"filter": _NoAttitude()}, r"^systems: unknown system name 'filter' \(the loop's are uuv, "),
        ({"estimator": "kf"}, r"^systems\['estimator'\]: must be a Drake System, got 'kf'$"),
    ],
)  # fmt: skip
def test_bad_user_systems_are_named(paper, systems: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        make_uuv_diagram(paper, systems=systems)


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


def test_set_random_context_fixes_each_draw_by_seed_source_and_step(paper) -> None:
    """A seed fixes every draw: step 0's noise is the seed's (not zero), the same seed gives
    the same numbers, another seed others, and each is ``run_draws`` of (seed, source, step)."""
    built = make_uuv_diagram(paper)
    context = built.diagram.CreateDefaultContext()
    source = built.diagram.GetSubsystemByName("range_noise")
    draws = []
    for seed in (5, 5, 6):
        built.set_random_context(context, seed)
        draws.append(source.get_output_port().Eval(source.GetMyContextFromRoot(context)).copy())
    assert np.all(draws[0] != 0.0)
    np.testing.assert_array_equal(draws[0], draws[1])
    assert not np.array_equal(draws[0], draws[2])
    np.testing.assert_array_equal(draws[2], run_draws([6], "range_noise", 0, 2)[0])
    context.SetTime(3 * paper.time_step)
    step_3 = source.get_output_port().Eval(source.GetMyContextFromRoot(context))
    np.testing.assert_array_equal(step_3, run_draws([6], "range_noise", 3, 2)[0])


def test_a_variant_missing_from_its_factory_is_named(paper, monkeypatch) -> None:
    monkeypatch.delitem(PLANTS, KinematicUuv)
    with pytest.raises(
        TypeError, match=r"^plant: no system for !KinematicUuv in the slot's factory"
    ):
        make_uuv_diagram(paper)


def test_the_registry_holds_every_slot_and_every_variant() -> None:
    assert [slot.section for slot in SLOT_REGISTRY] == list(SLOTS)
    assert {slot.system for slot in SLOT_REGISTRY} < set(SYSTEM_NAMES)
    for slot in SLOT_REGISTRY:
        assert set(slot.table) == set(variants(Scenario, slot.section).values())
        assert set(slot.tags) == {f"!{tag}" for tag in variants(Scenario, slot.section)}


# ------------------------------------------------------------------ systems of your own


def test_a_user_estimator_replaces_the_scenarios() -> None:
    """A constant estimate drives the loop: the log holds it, the paper's law acts on it, the
    sonar still measures, and the monitor lets a consistent-looking estimate run."""
    scenario = load_scenario("paper", SHORT)
    x = np.array([-1.0, -2.5, 0.5, 0.1, 0.0, -0.1])
    P = np.diag([0.3, 0.2, 0.1, 0.03, 0.02, 0.01])
    simulation = ClosedLoopSimulation(scenario, systems={"estimator": ConstantEstimator(x, P)})
    log = simulation.run(3).log
    assert isinstance(simulation.built.systems["estimator"], ConstantEstimator)
    assert_allclose(log["x_TU_hat"], np.broadcast_to(x, (40, 6)))
    assert_allclose(log["P_TU"], np.broadcast_to(P, (40, 6, 6)))
    k_p, k_v = 2 * 1.2 / 0.5**2, 2 / 0.5
    expected = [
        paper_tracking_command(x, R, np.array([-2.0, -2.0, 0.0]), k_p, k_v) for R in log["R_WB"]
    ]
    assert_allclose(log["u1_B"], expected, rtol=1e-12, atol=1e-12)
    # Y = q_sᵀ q + v̄, the noise of mean m and variance Γ: within 5 σ at all 40 steps.
    noise = log["Y"] - np.einsum("ki,ki->k", log["b_W"], log["p_WU"] - log["p_WT"])
    assert np.all(np.abs(noise - log["m"]) < 5 * np.sqrt(log["Gamma"]))
    assert np.all(np.isnan(log["nis"]))


def test_a_user_tracking_law_without_a_gain_runs_and_reports_no_spectral_radius() -> None:
    q_star = np.array([-2.0, -2.0, 0.0])
    law = ProportionalTracking(0.5, q_star)
    result = ClosedLoopSimulation(
        load_scenario("paper", SHORT), systems={"tracking_controller": law}
    ).run()
    assert math.isnan(result.metrics["tracking_spectral_radius"])
    assert_allclose(result.log["u1_W"], -0.5 * (result.log["x_TU_hat"][:, :3] - q_star))
    assert np.isfinite(result.metrics["position_rmse"])
