"""A batch of runs through the navigation systems: each run's bits are its own."""

import math

import numpy as np
import pytest
from pydrake.math import RollPitchYaw, RotationMatrix
from pydrake.systems.analysis import Simulator

from drake_uuv.navigation import (
    InertialNavigationSystem,
    NavigationSetting,
    PerfectNavigationSystem,
    make_navigation,
)
from drake_uuv.navigation.inertial_navigation import perturbed_attitudes
from drake_uuv.primitives import random_inputs
from drake_uuv.scenario import InertialNavigation, PerfectNavigation, load_scenario
from drake_uuv.testing import assert_batch_equals_runs
from tests.conftest import T

SETTING = NavigationSetting(T, np.zeros(3), np.zeros(3), np.eye(3))
#: Each branch of the inertial navigation: every σ zero (the truth), the DVL's errors alone
#: (the attitude exact), the attitude's alone (the DVL exact), and all of them.
CONFIGS = {
    "exact": InertialNavigation(),
    "dvl": InertialNavigation(velocity_noise=0.02, velocity_bias=0.01),
    "attitude": InertialNavigation(attitude_noise_deg=[0.5, 0.5, 2.0], heading_bias_deg=2.0),
    "all": InertialNavigation(
        attitude_noise_deg=[0.5, 0.8, 2.0], heading_bias_deg=3.0, velocity_noise=0.02,
        velocity_bias=0.01,
    ),
}  # fmt: skip


def attitudes(rng: np.random.Generator, batch_size: int) -> np.ndarray:
    """Random attitudes (B×3×3); run 1 at pitch −90° (roll and yaw from the quaternion), run 2
    turned by π about z (the quaternion's other branches)."""
    R = [RotationMatrix(RollPitchYaw(rng.normal(size=3) * 2)).matrix() for _ in range(batch_size)]
    if batch_size > 1:
        R[1] = RotationMatrix(RollPitchYaw(0.3, -math.pi / 2, 0.1)).matrix()
    if batch_size > 2:
        R[2] = RotationMatrix(RollPitchYaw(0.0, 0.0, math.pi)).matrix()
    return np.array(R)


def inputs(rng: np.random.Generator, batch_size: int, nan: bool = True) -> dict:
    values = {
        "p_WU": rng.normal(size=(batch_size, 3)) * 5.0,
        "v_WU": rng.normal(size=(batch_size, 3)),
        "R_WB": attitudes(rng, batch_size).reshape(batch_size, 9),
        "navigation_noise": rng.normal(size=(batch_size, 6)),
        "navigation_bias": rng.normal(size=(batch_size, 4)),
    }
    if nan and batch_size >= 4:
        values["v_WU"][-1, 0] = np.nan
        values["navigation_noise"][-1, 2] = np.inf
    return values


def states(rng: np.random.Generator, batch_size: int) -> list[np.ndarray]:
    """Latched biases and dead reckoning; even runs not yet started (k = 0), odd runs started
    (their own e_p and e_v), a NaN dead reckoning last in a batch of four or more."""
    bias = rng.normal(scale=0.02, size=(batch_size, 4))
    dead_reckoning = rng.normal(scale=0.1, size=(batch_size, 7))
    dead_reckoning[:, 6] = np.arange(batch_size) % 2
    if batch_size >= 4:
        dead_reckoning[-1, :6] = np.nan
    return [bias, dead_reckoning]


@pytest.mark.parametrize("batch_size", [1, 2, 5])
@pytest.mark.parametrize("name", CONFIGS)
def test_an_inertial_batch_step_is_each_run_alone(batch_size: int, name: str) -> None:
    rng = np.random.default_rng(batch_size)

    def make(B: int) -> InertialNavigationSystem:
        return InertialNavigationSystem(CONFIGS[name], setting=SETTING, batch_size=B)

    assert_batch_equals_runs(make, inputs(rng, batch_size), states(rng, batch_size), time=T)


@pytest.mark.parametrize("batch_size", [1, 3])
def test_a_perfect_batch_is_each_run_alone(batch_size: int) -> None:
    rng = np.random.default_rng(batch_size)
    values = {k: v for k, v in inputs(rng, batch_size).items() if "navigation" not in k}

    def make(B: int) -> PerfectNavigationSystem:
        return PerfectNavigationSystem(PerfectNavigation(), setting=SETTING, batch_size=B)

    assert_batch_equals_runs(make, values)


def test_each_run_latches_its_own_first_draw_and_a_nan_run_leaves_the_others() -> None:
    """Initialized and stepped as a batch, each run's biases and its outputs over three steps
    are those of the run alone; the NaN run stays NaN, the others finite."""
    B = 5
    rng = np.random.default_rng(11)
    values = inputs(rng, B)
    scenario = load_scenario("realistic", ["plant=!KinematicUuv"])

    def outputs(batch_size: int, runs: slice) -> tuple[list[np.ndarray], tuple]:
        system = make_navigation(scenario, batch_size=batch_size)
        assert system.batch_size == batch_size
        assert set(random_inputs(system)) == {"navigation_noise", "navigation_bias"}
        context = system.CreateDefaultContext()
        for name, value in values.items():
            system.GetInputPort(name).FixValue(context, value[runs].ravel())
        simulator = Simulator(system, context)
        simulator.Initialize()
        seen = []
        for k in range(3):
            simulator.AdvanceTo(k * T)
            seen.append(
                np.concatenate(
                    [
                        system.GetOutputPort(name).Eval(context).reshape(batch_size, -1)
                        for name in ("p_WU_nav", "v_WU_nav", "R_WB_nav")
                    ],
                    axis=1,
                )
            )
        return seen, system.latched_bias(context)

    batch, (b_psi, b_v) = outputs(B, slice(None))
    for i in range(B):
        alone, (a_psi, a_v) = outputs(1, slice(i, i + 1))
        assert b_psi[i] == a_psi[0] and np.array_equal(b_v[i], a_v[0])
        for k in range(3):
            np.testing.assert_array_equal(batch[k][i], alone[k][0])
    assert np.all(np.isfinite(batch[-1][:-1])) and not np.all(np.isfinite(batch[-1][-1]))


def test_the_attitude_round_trip_is_drakes() -> None:
    """The written-out roll-pitch-yaw round trip against Drake's, at random attitudes and the
    singular ones (to rounding: the quaternion's normalisation differs in the last bits)."""
    rng = np.random.default_rng(5)
    R = attitudes(rng, 200)
    delta = rng.normal(scale=0.05, size=(200, 3))
    delta[:3] = 0.0
    got = perturbed_attitudes(R, delta)
    for i in range(200):
        rpy = RollPitchYaw(RotationMatrix(R[i])).vector() + delta[i]
        expected = RollPitchYaw(rpy).ToRotationMatrix().matrix()
        np.testing.assert_allclose(got[i], expected, rtol=0, atol=1e-13)
