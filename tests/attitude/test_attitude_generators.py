"""The attitude generators alone: Algorithms 1 and 2, the fixed attitude, rate limits, plans."""

import dataclasses
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pydrake.math import RollPitchYaw, RotationMatrix

from drake_uuv.attitude import (
    AttitudeGenerator,
    FixedAttitudeGenerator,
    RandomAttitudeGenerator,
    TrajectoryAttitudeGenerator,
    attitude_setting,
    make_attitude_generator,
)
from drake_uuv.models.attitude_plans import zeta
from drake_uuv.models.so3 import exp_so3, matrix_from_quaternion
from drake_uuv.scenario import FixedAttitude, RandomAttitude, TrajectoryAttitude, load_scenario
from drake_uuv.testing import fixed_context
from tests.conftest import T

b = np.array([-1.0, 1.0, 0.0])
R = RotationMatrix(RollPitchYaw(0.4, -0.3, 1.2)).matrix()
#: The paper's setting: t = 0.5 s, the baseline b.
SETTING = attitude_setting(load_scenario("paper"))


def next_attitude(generator: AttitudeGenerator, context) -> np.ndarray:
    """Applies the plant's eq. (2) with the generator's command."""
    return exp_so3(generator.GetOutputPort("u2_W").Eval(context) * T) @ R


def test_ports_per_variant() -> None:
    for generator in (
        FixedAttitudeGenerator(FixedAttitude(), setting=SETTING),
        TrajectoryAttitudeGenerator(TrajectoryAttitude(), setting=SETTING),
    ):
        assert generator.num_input_ports() == 1 and generator.GetInputPort("R_WB_nav").size() == 9
        assert generator.GetOutputPort("u2_W").size() == 3
        assert generator.GetOutputPort("R_WB_plan").size() == 18
    assert (
        RandomAttitudeGenerator(RandomAttitude(), setting=SETTING)
        .GetInputPort("rotation_noise")
        .size()
        == 4
    )
    with pytest.raises(ValueError, match=r"^baseline_B: must be a non-zero 3-vector"):
        dataclasses.replace(SETTING, baseline_B=np.zeros(3))


@pytest.mark.parametrize(
    "tag, kind",
    [("FixedAttitude", FixedAttitudeGenerator), ("RandomAttitude", RandomAttitudeGenerator),
     ("TrajectoryAttitude", TrajectoryAttitudeGenerator)],
)  # fmt: skip
def test_factory_builds_each_variant(tag: str, kind: type) -> None:
    scenario = load_scenario("paper", [f"attitude=!{tag}"])
    assert isinstance(make_attitude_generator(scenario), kind)


def test_fixed_attitude_commands_nothing() -> None:
    generator = FixedAttitudeGenerator(FixedAttitude(), setting=SETTING)
    assert_allclose(
        generator.GetOutputPort("u2_W").Eval(fixed_context(generator, R_WB_nav=R.ravel())), 0
    )


def test_zeta_is_the_papers_function() -> None:
    k = 7
    expected = math.sqrt(2) * np.array(
        [math.sin(k * math.pi / 24), math.cos(k * math.pi / 24), 0.5 * math.cos(k * math.pi / 6)]
    )
    assert_allclose(zeta(k, math.sqrt(2), 1 / 24, 0.5, 1 / 6), expected)


@pytest.mark.parametrize("k", [0, 1, 5, 13, 24, 37, 100])
def test_algorithm_2_makes_the_next_baseline_parallel_to_zeta(k: int) -> None:
    generator = TrajectoryAttitudeGenerator(TrajectoryAttitude(), setting=SETTING)
    context = fixed_context(generator, R_WB_nav=R.ravel())
    context.SetTime(k * T)
    q_s_next = next_attitude(generator, context) @ b
    direction = zeta(k, np.linalg.norm(b), 1 / 24, 0.5, 1 / 6)
    assert_allclose(np.cross(q_s_next, direction), 0, atol=1e-12)
    assert q_s_next @ direction > 0
    assert_allclose(np.linalg.norm(q_s_next), np.linalg.norm(b))


def test_algorithm_1_jumps_to_the_sampled_rotation() -> None:
    generator = RandomAttitudeGenerator(RandomAttitude(), setting=SETTING)
    noise = np.array([0.3, -1.2, 0.8, 2.0])
    context = fixed_context(generator, R_WB_nav=R.ravel(), rotation_noise=noise)
    assert_allclose(
        next_attitude(generator, context),
        matrix_from_quaternion(noise / np.linalg.norm(noise)),
        atol=1e-12,
    )


def test_algorithm_1_samples_are_uniform_rotations() -> None:
    """A uniform rotation maps b to a uniform direction: E[q_s q_sᵀ] = |b|²/3 I (Lemma 1)."""
    generator = RandomAttitudeGenerator(RandomAttitude(), setting=SETTING)
    context = fixed_context(generator, R_WB_nav=np.eye(3).ravel(), rotation_noise=np.ones(4))
    rng = np.random.default_rng(11)
    n = 5000
    outer = np.zeros((3, 3))
    for _ in range(n):
        generator.GetInputPort("rotation_noise").FixValue(context, rng.standard_normal(4))
        q_s = exp_so3(generator.GetOutputPort("u2_W").Eval(context) * T) @ b
        outer += np.outer(q_s, q_s) / n
    # Each entry of q_s q_sᵀ has variance ≤ |b|⁴ = 4; allow 5 standard errors.
    assert_allclose(outer, 2.0 / 3.0 * np.eye(3), atol=5 * 2 / np.sqrt(n))


def test_max_angular_rate_limits_the_command_along_the_same_axis() -> None:
    free = TrajectoryAttitudeGenerator(TrajectoryAttitude(), setting=SETTING)
    limited = TrajectoryAttitudeGenerator(TrajectoryAttitude(max_angular_rate=0.2), setting=SETTING)
    context_free = fixed_context(free, R_WB_nav=R.ravel())
    context_limited = fixed_context(limited, R_WB_nav=R.ravel())
    w_free = free.GetOutputPort("u2_W").Eval(context_free)
    w_limited = limited.GetOutputPort("u2_W").Eval(context_limited)
    assert np.linalg.norm(w_free) > 0.2
    assert np.linalg.norm(w_limited) == pytest.approx(0.2)
    assert_allclose(w_limited / 0.2, w_free / np.linalg.norm(w_free))


# -------------------------------------------------------------------- the attitude plan


@pytest.mark.parametrize("max_rate", [None, 0.3])
def test_trajectory_plan_is_the_next_two_attitudes(max_rate: float | None) -> None:
    generator = TrajectoryAttitudeGenerator(
        TrajectoryAttitude(max_angular_rate=max_rate), setting=SETTING
    )
    k = 17
    context = fixed_context(generator, R_WB_nav=R.ravel())
    context.SetTime(k * T)
    plan = generator.GetOutputPort("R_WB_plan").Eval(context)
    R1 = exp_so3(generator.GetOutputPort("u2_W").Eval(context) * T) @ R
    generator.GetInputPort("R_WB_nav").FixValue(context, R1.ravel())
    context.SetTime((k + 1) * T)
    R2 = exp_so3(generator.GetOutputPort("u2_W").Eval(context) * T) @ R1
    assert_allclose(plan, np.r_[R1.ravel(), R2.ravel()], atol=1e-12)


def test_random_plan_holds_the_next_attitude_and_fixed_holds_the_current() -> None:
    generator = RandomAttitudeGenerator(RandomAttitude(), setting=SETTING)
    context = fixed_context(generator, R_WB_nav=R.ravel(), rotation_noise=[0.3, -1.2, 0.8, 2.0])
    R1 = exp_so3(generator.GetOutputPort("u2_W").Eval(context) * T) @ R
    assert_allclose(
        generator.GetOutputPort("R_WB_plan").Eval(context),
        np.r_[R1.ravel(), R1.ravel()],
        atol=1e-12,
    )
    fixed = FixedAttitudeGenerator(FixedAttitude(), setting=SETTING)
    plan = fixed.GetOutputPort("R_WB_plan").Eval(fixed_context(fixed, R_WB_nav=R.ravel()))
    assert_allclose(plan, np.r_[R.ravel(), R.ravel()])
