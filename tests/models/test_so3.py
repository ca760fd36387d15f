"""SO(3) helpers against Drake's RotationMatrix and AngleAxis."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pydrake.common.eigen_geometry import AngleAxis
from pydrake.math import RollPitchYaw, RotationMatrix

from drake_uuv.models import so3

rng = np.random.default_rng(5)
VECTORS = [rng.standard_normal(3) * s for s in (1e-12, 1e-3, 0.5, 2.0, 3.1)] + [
    np.array([math.pi, 0, 0]),
    np.array([0, 0, math.pi - 1e-9]),
]


@pytest.mark.parametrize("w", VECTORS)
def test_exp_matches_drake(w: np.ndarray) -> None:
    angle = np.linalg.norm(w)
    expected = RotationMatrix(AngleAxis(angle, w / angle)).matrix() if angle > 0 else np.eye(3)
    assert_allclose(so3.exp_so3(w), expected, atol=1e-14)


@pytest.mark.parametrize(
    "rpy", [(0, 0, 0), (0.1, -0.2, 0.3), (3.0, 0.1, -3.0), (math.pi, 0, 0), (0, 1.5, 0)]
)
def test_log_matches_drake_and_inverts_exp(rpy: tuple[float, float, float]) -> None:
    R = RotationMatrix(RollPitchYaw(*rpy))
    angle_axis = R.ToAngleAxis()
    w = so3.log_so3(R.matrix())
    assert np.linalg.norm(w) == pytest.approx(angle_axis.angle(), abs=1e-12)
    assert_allclose(so3.exp_so3(w), R.matrix(), atol=1e-12)
    assert_allclose(
        so3.matrix_from_quaternion(so3.quaternion_from_matrix(R.matrix())), R.matrix(), atol=1e-14
    )


@pytest.mark.parametrize(
    "a, b",
    [
        ([-1, 1, 0], [0.3, 2.0, -0.5]),
        ([-1, 1, 0], [-2, 2, 0]),  # parallel
        ([-1, 1, 0], [1, -1, 0]),  # antiparallel
        ([0, 0, 1], [0, 0, -3]),  # antiparallel along an axis
    ],
)
def test_minimal_rotation(a: list[float], b: list[float]) -> None:
    a, b = np.asarray(a, float), np.asarray(b, float)
    R = so3.minimal_rotation(a, b)
    assert so3.is_rotation(R, 1e-12)
    assert_allclose(R @ a / np.linalg.norm(a), b / np.linalg.norm(b), atol=1e-12)
    # Least angle: the angle between the two directions.
    angle = math.atan2(np.linalg.norm(np.cross(a, b)), a @ b)
    assert np.linalg.norm(so3.log_so3(R)) == pytest.approx(angle, abs=1e-12)
