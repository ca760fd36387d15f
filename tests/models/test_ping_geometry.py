"""The geometry between ticks: exact for the paper's constant acceleration and world rate."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from drake_uuv.models.ping_geometry import (
    interpolate_attitude,
    interpolate_position,
    interpolate_velocity,
)
from drake_uuv.models.so3 import exp_so3
from tests.conftest import T


@pytest.mark.parametrize("s", [0.0, 0.1, 0.5, 0.77, 1.0])
def test_constant_acceleration_is_reproduced_exactly(s: float) -> None:
    rng = np.random.default_rng(3)
    p0, v0, a = rng.normal(size=3), rng.normal(size=3), rng.normal(size=3) * 5.0
    p1, v1 = p0 + T * v0 + 0.5 * T * T * a, v0 + T * a
    tau = s * T
    assert_allclose(interpolate_position(p0, v0, p1, v1, s, T), p0 + tau * v0 + 0.5 * tau**2 * a,
                    rtol=1e-13, atol=1e-13)  # fmt: skip
    assert_allclose(interpolate_velocity(p0, v0, p1, v1, s, T), v0 + tau * a, rtol=1e-12,
                    atol=1e-12)  # fmt: skip


@pytest.mark.parametrize("s", [0.0, 0.3, 0.5, 1.0])
def test_a_constant_world_rate_is_reproduced_exactly(s: float) -> None:
    R0 = exp_so3(np.array([0.4, -0.2, 1.1]))
    u2 = np.array([0.9, 2.5, -1.7])  # |u2 t| = 1.6 rad < π
    assert np.linalg.norm(u2 * T) < math.pi
    R1 = exp_so3(u2 * T) @ R0
    assert_allclose(interpolate_attitude(R0, R1, s), exp_so3(u2 * s * T) @ R0, atol=1e-13)
