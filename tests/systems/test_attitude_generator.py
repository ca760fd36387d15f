import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pydrake.math import RollPitchYaw, RotationMatrix

from drake_uuv.controllers import AttitudeGenerator
from drake_uuv.controllers.attitude_generator import zeta
from drake_uuv.so3 import exp_so3, matrix_from_quaternion
from drake_uuv.testing import fixed_context

T = 0.5
b = np.array([-1.0, 1.0, 0.0])
R = RotationMatrix(RollPitchYaw(0.4, -0.3, 1.2)).matrix()


def next_attitude(generator: AttitudeGenerator, context) -> np.ndarray:
    """Applies the plant's eq. (2) with the generator's command."""
    return exp_so3(generator.GetOutputPort("w_W").Eval(context) * T) @ R


def test_ports_per_mode() -> None:
    for mode in ("fixed", "trajectory"):
        generator = AttitudeGenerator(mode, T, b)
        assert generator.num_input_ports() == 1 and generator.GetInputPort("R_WB").size() == 9
        assert generator.GetOutputPort("w_W").size() == 3
    assert AttitudeGenerator("random", T, b).GetInputPort("rotation_noise").size() == 4
    with pytest.raises(ValueError, match="attitude.mode.*'spin'"):
        AttitudeGenerator("spin", T, b)


def test_fixed_mode_commands_nothing() -> None:
    generator = AttitudeGenerator("fixed", T, b)
    assert_allclose(
        generator.GetOutputPort("w_W").Eval(fixed_context(generator, R_WB=R.ravel())), 0
    )


def test_zeta_is_the_papers_function() -> None:
    k = 7
    expected = math.sqrt(2) * np.array(
        [math.sin(k * math.pi / 24), math.cos(k * math.pi / 24), 0.5 * math.cos(k * math.pi / 6)]
    )
    assert_allclose(zeta(k, math.sqrt(2), 1 / 24, 0.5, 1 / 6), expected)


@pytest.mark.parametrize("k", [0, 1, 5, 13, 24, 37, 100])
def test_algorithm_2_makes_the_next_baseline_parallel_to_zeta(k: int) -> None:
    generator = AttitudeGenerator("trajectory", T, b)
    context = fixed_context(generator, R_WB=R.ravel())
    context.SetTime(k * T)
    q_s_next = next_attitude(generator, context) @ b
    direction = zeta(k, np.linalg.norm(b), 1 / 24, 0.5, 1 / 6)
    assert_allclose(np.cross(q_s_next, direction), 0, atol=1e-12)
    assert q_s_next @ direction > 0
    assert_allclose(np.linalg.norm(q_s_next), np.linalg.norm(b))


def test_algorithm_1_jumps_to_the_sampled_rotation() -> None:
    generator = AttitudeGenerator("random", T, b)
    noise = np.array([0.3, -1.2, 0.8, 2.0])
    context = fixed_context(generator, R_WB=R.ravel(), rotation_noise=noise)
    assert_allclose(
        next_attitude(generator, context),
        matrix_from_quaternion(noise / np.linalg.norm(noise)),
        atol=1e-12,
    )


def test_algorithm_1_samples_are_uniform_rotations() -> None:
    """A uniform rotation maps b to a uniform direction: E[q_s q_sᵀ] = |b|²/3 I (Lemma 1)."""
    generator = AttitudeGenerator("random", T, b)
    context = fixed_context(generator, R_WB=np.eye(3).ravel(), rotation_noise=np.ones(4))
    rng = np.random.default_rng(11)
    n = 5000
    outer = np.zeros((3, 3))
    for _ in range(n):
        generator.GetInputPort("rotation_noise").FixValue(context, rng.standard_normal(4))
        q_s = exp_so3(generator.GetOutputPort("w_W").Eval(context) * T) @ b
        outer += np.outer(q_s, q_s) / n
    # Each entry of q_s q_sᵀ has variance ≤ |b|⁴ = 4; allow 5 standard errors.
    assert_allclose(outer, 2.0 / 3.0 * np.eye(3), atol=5 * 2 / np.sqrt(n))


def test_max_angular_rate_limits_the_command_along_the_same_axis() -> None:
    free = AttitudeGenerator("trajectory", T, b)
    limited = AttitudeGenerator("trajectory", T, b, max_angular_rate=0.2)
    context_free = fixed_context(free, R_WB=R.ravel())
    context_limited = fixed_context(limited, R_WB=R.ravel())
    w_free = free.GetOutputPort("w_W").Eval(context_free)
    w_limited = limited.GetOutputPort("w_W").Eval(context_limited)
    assert np.linalg.norm(w_free) > 0.2
    assert np.linalg.norm(w_limited) == pytest.approx(0.2)
    assert_allclose(w_limited / 0.2, w_free / np.linalg.norm(w_free))
