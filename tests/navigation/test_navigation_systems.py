"""Each navigation system alone: ports, the identity, the model's closed form, dead reckoning."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pydrake.common import RandomDistribution
from pydrake.systems.analysis import Simulator

from drake_uuv.navigation import (
    NAVIGATIONS,
    InertialNavigationSystem,
    NavigationSetting,
    PerfectNavigationSystem,
    make_navigation,
)
from drake_uuv.primitives import random_inputs
from drake_uuv.scenario import InertialNavigation, PerfectNavigation, ScenarioError, load_scenario
from drake_uuv.testing import fixed_context
from tests.conftest import T

SETTING = NavigationSetting(T, np.zeros(3), np.zeros(3), np.eye(3))
RNG = np.random.default_rng(7)
P = np.array([3.0, -1.5, -8.0])
V = np.array([0.4, -0.25, 0.1])
#: A generic attitude: roll, pitch, yaw 0.3, −0.4, 2.5 rad.
RPY = np.array([0.3, -0.4, 2.5])
NOISE = np.array([0.7, -1.3, 0.4, -0.2, 1.1, 0.9])
BIAS = np.array([1.4, -0.6, 0.3, -1.8])


def _rx(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _ry(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rz(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _rotation(rpy: np.ndarray) -> np.ndarray:
    """``Rz(yaw) Ry(pitch) Rx(roll)``, written out (Drake's RollPitchYaw, independently)."""
    return _rz(rpy[2]) @ _ry(rpy[1]) @ _rx(rpy[0])


R = _rotation(RPY)


def _outputs(system, context) -> dict[str, np.ndarray]:
    return {
        name: system.GetOutputPort(name).Eval(context).copy()
        for name in ("p_WU_nav", "v_WU_nav", "R_WB_nav")
    }


def _initialized(system, **inputs) -> tuple[Simulator, object]:
    """A simulator of ``system`` alone, its inputs fixed, initialized (the biases latched)."""
    context = fixed_context(system, **inputs)
    simulator = Simulator(system, context)
    simulator.Initialize()
    return simulator, simulator.get_mutable_context()


def _truth(**noise) -> dict[str, np.ndarray]:
    return dict(p_WU=P, v_WU=V, R_WB=R.ravel(), **noise)


def _inertial(
    attitude: list[float], heading: float, noise: float, bias: float
) -> tuple[InertialNavigationSystem, Simulator, object]:
    """The inertial navigation of these σ, at the truth with the draws ``NOISE`` and
    ``BIAS``, initialized."""
    config = InertialNavigation(
        attitude_noise_deg=attitude, heading_bias_deg=heading, velocity_noise=noise,
        velocity_bias=bias,
    )  # fmt: skip
    system = InertialNavigationSystem(config, setting=SETTING)
    return system, *_initialized(system, **_truth(navigation_noise=NOISE, navigation_bias=BIAS))


# ---------------------------------------------------------------------------- the ports


@pytest.mark.parametrize("config", [PerfectNavigation(), InertialNavigation()], ids=type)
def test_ports_and_sizes(config) -> None:
    system = NAVIGATIONS[type(config)](config, setting=SETTING)
    inputs = {system.get_input_port(i).get_name(): system.get_input_port(i).size()
              for i in range(system.num_input_ports())}  # fmt: skip
    outputs = {system.get_output_port(i).get_name(): system.get_output_port(i).size()
               for i in range(system.num_output_ports())}  # fmt: skip
    truth = {"p_WU": 3, "v_WU": 3, "R_WB": 9}
    random = {"navigation_noise": 6, "navigation_bias": 4}
    assert inputs == (truth if isinstance(config, PerfectNavigation) else {**truth, **random})
    assert outputs == {"p_WU_nav": 3, "v_WU_nav": 3, "R_WB_nav": 9}
    gaussian = RandomDistribution.kGaussian
    expected = {} if isinstance(config, PerfectNavigation) else dict.fromkeys(random, gaussian)
    assert random_inputs(system) == expected


def test_each_inertial_output_depends_only_on_what_it_needs() -> None:
    system = InertialNavigationSystem(InertialNavigation(), setting=SETTING)
    index = {system.get_input_port(i).get_name(): i for i in range(system.num_input_ports())}
    feeds = {
        system.get_output_port(j).get_name(): {
            name for name, i in index.items() if system.HasDirectFeedthrough(i, j)
        }
        for j in range(system.num_output_ports())
    }
    assert feeds == {
        "R_WB_nav": {"R_WB", "navigation_noise"},
        "v_WU_nav": {"R_WB", "v_WU", "navigation_noise"},
        "p_WU_nav": {"R_WB", "v_WU", "p_WU", "navigation_noise"},
    }


# ---------------------------------------------------------------------- perfect navigation


def test_perfect_navigation_is_the_identity_bit_for_bit() -> None:
    system = PerfectNavigationSystem(PerfectNavigation(), setting=SETTING)
    p, v, R_rows = RNG.normal(size=3) * 1e3, RNG.normal(size=3) * 1e-7, RNG.normal(size=9)
    outputs = _outputs(system, fixed_context(system, p_WU=p, v_WU=v, R_WB=R_rows))
    for name, value in (("p_WU_nav", p), ("v_WU_nav", v), ("R_WB_nav", R_rows)):
        np.testing.assert_array_equal(outputs[name], value)


# --------------------------------------------------------------------- inertial navigation


def test_inertial_navigation_with_every_sigma_zero_is_the_truth_bit_for_bit() -> None:
    system, simulator, context = _inertial([0.0, 0.0, 0.0], 0.0, 0.0, 0.0)
    for _ in range(3):  # k = 0 and two steps of dead reckoning
        outputs = _outputs(system, context)
        np.testing.assert_array_equal(outputs["p_WU_nav"], P)
        np.testing.assert_array_equal(outputs["v_WU_nav"], V)
        np.testing.assert_array_equal(outputs["R_WB_nav"], R.ravel())
        simulator.AdvanceTo(context.get_time() + T)


def test_one_step_is_the_models_closed_form() -> None:
    """Against the model written out: Drake's roll-pitch-yaw as ``Rz Ry Rx`` of the angles
    plus their noise and the heading bias, the DVL in the body frame."""
    system, _, context = _inertial([0.5, 0.8, 2.0], 3.0, 0.02, 0.01)
    (heading,), (b_v,) = system.latched_bias(context)  # one run
    assert heading == math.radians(3.0) * BIAS[0]
    assert_allclose(b_v, 0.01 * BIAS[1:], rtol=0, atol=0)
    n = np.radians([0.5, 0.8, 2.0]) * NOISE[:3]
    R_nav = _rotation(RPY + n + [0.0, 0.0, heading])
    v_nav = R_nav @ (R.T @ V + b_v + 0.02 * NOISE[3:])
    outputs = _outputs(system, context)
    assert_allclose(outputs["R_WB_nav"].reshape(3, 3), R_nav, rtol=0, atol=1e-14)
    assert_allclose(outputs["v_WU_nav"], v_nav, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(outputs["p_WU_nav"], P)  # e_p(0) = 0: the start is known


def test_the_heading_bias_alone_turns_the_frame_and_the_velocity_about_world_z() -> None:
    system, _, context = _inertial([0.0, 0.0, 0.0], 5.0, 0.0, 0.0)
    b = math.radians(5.0) * BIAS[0]
    outputs = _outputs(system, context)
    assert_allclose(outputs["R_WB_nav"].reshape(3, 3) @ R.T, _rz(b), rtol=0, atol=1e-15)
    assert_allclose(outputs["v_WU_nav"], _rz(b) @ V, rtol=0, atol=1e-15)


def test_dead_reckoning_integrates_a_constant_velocity_error() -> None:
    """With constant inputs the velocity error is constant, and its trapezoid integral is
    ``e_p(k) = k t e_v``."""
    system, simulator, context = _inertial([0.5, 0.5, 2.0], 2.0, 0.01, 0.005)
    e_v = system.GetOutputPort("v_WU_nav").Eval(context) - V
    assert np.all(np.abs(e_v) > 1e-4)
    for k in range(6):
        assert_allclose(system.GetOutputPort("v_WU_nav").Eval(context), V + e_v, atol=1e-15)
        p_nav = system.GetOutputPort("p_WU_nav").Eval(context)
        assert_allclose(p_nav - P, k * T * e_v, rtol=1e-12, atol=1e-15)
        simulator.AdvanceTo((k + 1) * T)


def test_the_bias_is_read_at_initialization_only() -> None:
    system, simulator, context = _inertial([0.5, 0.5, 2.0], 2.0, 0.01, 0.005)
    before = system.latched_bias(context)
    system.GetInputPort("navigation_bias").FixValue(context, -BIAS)
    simulator.AdvanceTo(3 * T)
    after = system.latched_bias(context)
    assert np.array_equal(before[0], after[0]) and np.array_equal(before[1], after[1])
    assert before[0][0] == math.radians(2.0) * BIAS[0]


# ----------------------------------------------------------------- factory and bad values


def test_the_factory_builds_the_scenarios_variant() -> None:
    assert isinstance(make_navigation(load_scenario("paper")), PerfectNavigationSystem)
    inertial = load_scenario("paper", ["navigation=!InertialNavigation"])
    assert isinstance(make_navigation(inertial), InertialNavigationSystem)


def test_a_variant_missing_from_the_factory_is_named(monkeypatch) -> None:
    monkeypatch.delitem(NAVIGATIONS, InertialNavigation)
    with pytest.raises(
        TypeError, match=r"^navigation: no system for !InertialNavigation in the slot's factory$"
    ):
        make_navigation(load_scenario("paper", ["navigation=!InertialNavigation"]))


@pytest.mark.parametrize(
    "override, message",
    [
        ("attitude_noise_deg=[0.5, 0.5]",
         r"^navigation.attitude_noise_deg: must be a list of 3 numbers, got \[0.5, 0.5\]$"),
        ("attitude_noise_deg=[0.5, -0.1, 2.0]",
         r"^navigation.attitude_noise_deg: must be in \[0, 30\] each, got \[0.5, -0.1, 2.0\]$"),
        ("heading_bias_deg=45.0", r"^navigation.heading_bias_deg: must be in \[0, 30\], got 45.0$"),
        ("velocity_noise=-0.01", r"^navigation.velocity_noise: must be ≥ 0, got -0.01$"),
        ("velocity_bias=.nan", r"^navigation.velocity_bias: must be ≥ 0, got nan$"),
    ],
)  # fmt: skip
def test_bad_values_are_named(override: str, message: str) -> None:
    with pytest.raises(ScenarioError, match=message):
        load_scenario("paper", ["navigation=!InertialNavigation", f"navigation.{override}"])


def test_a_system_built_by_hand_checks_its_config_and_setting() -> None:
    with pytest.raises(ScenarioError, match=r"^navigation.velocity_noise: must be ≥ 0, got -1.0$"):
        InertialNavigationSystem(InertialNavigation(velocity_noise=-1.0), setting=SETTING)
    with pytest.raises(ValueError, match=r"^time_step: must be > 0, got 0.0$"):
        NavigationSetting(0.0, np.zeros(3), np.zeros(3), np.eye(3))
    with pytest.raises(ValueError, match=r"^initial_R_WB: must be a rotation matrix, got "):
        NavigationSetting(T, np.zeros(3), np.zeros(3), 2.0 * np.eye(3))
