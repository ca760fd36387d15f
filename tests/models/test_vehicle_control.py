"""The low-level law's compiled rotation helpers against drake_uuv.models.so3 and numpy."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from drake_uuv.models.so3 import exp_so3, log_so3
from drake_uuv.models.vehicle_kernels import (
    _times3,
    _times_transpose3,
    exp_rotation,
    log_rotation,
)
from tests.models.test_marine_vehicle_model import RNG_SEED

ANGLES = [0.0, 1e-12, 1e-7, 0.3, 1.5, math.pi / 2 + 1e-3, 2.5, math.pi - 1e-6]


@pytest.mark.parametrize("angle", ANGLES)
def test_exp_and_log_agree_with_so3(angle: float) -> None:
    rng = np.random.default_rng(RNG_SEED)
    for _ in range(5):
        axis = rng.normal(size=3)
        w = angle * axis / np.linalg.norm(axis)
        R = exp_rotation(*w)
        assert_allclose(np.reshape(R, (3, 3)), exp_so3(w), rtol=0.0, atol=1e-15)
        # Up to a quarter turn from the skew part and the trace, beyond it via the quaternion.
        e = np.array(log_rotation(R))
        assert_allclose(e, log_so3(np.reshape(R, (3, 3))), rtol=0.0, atol=1e-14)
        assert_allclose(exp_so3(e), exp_so3(w), rtol=0.0, atol=2e-15)


def test_products_are_numpys() -> None:
    rng = np.random.default_rng(RNG_SEED + 1)
    A, B = rng.normal(size=(3, 3)), rng.normal(size=(3, 3))
    product = _times3(tuple(A.ravel()), tuple(B.ravel()))
    assert_allclose(np.reshape(product, (3, 3)), A @ B, rtol=1e-14, atol=1e-15)
    product = _times_transpose3(tuple(A.ravel()), tuple(B.ravel()))
    assert_allclose(np.reshape(product, (3, 3)), A @ B.T, rtol=1e-14, atol=1e-15)
