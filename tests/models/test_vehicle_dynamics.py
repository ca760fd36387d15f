"""VehicleDynamics: the compiled state equation against the numpy model, and the RK3 tableau."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from drake_uuv.models.marine_vehicle import quaternion_derivative, rotation_from_quaternion
from drake_uuv.models.vehicle_dynamics import VehicleDynamics
from drake_uuv.models.vehicle_kernels import _times, sparse_rows
from drake_uuv.scenario.plants import HoveringAuv
from tests.models.test_marine_vehicle_model import RNG_SEED, random_model

F_MAX = HoveringAuv().max_thrust


def random_state(rng: np.random.Generator, lag_states: int = 0) -> np.ndarray:
    """A state off the unit quaternion sphere (as an integrator leaves it), moving and turning."""
    q = rng.normal(size=4)
    q *= 1.02 / np.linalg.norm(q)
    return np.concatenate(
        [rng.normal(size=3), q, rng.normal(0.0, 0.5, 6), rng.normal(0.0, 30.0, lag_states)]
    )


@pytest.mark.parametrize("diagonal", [True, False])
def test_the_sparse_product_is_the_matrix_product(diagonal: bool) -> None:
    rng = np.random.default_rng(RNG_SEED)
    if diagonal:
        matrix = np.diag(rng.normal(size=6))
    else:  # with zeros, as in M⁻¹ A, which the rows skip
        matrix = rng.normal(size=(6, 8)) * (rng.uniform(size=(6, 8)) < 0.6)
    v = rng.normal(size=matrix.shape[1])
    out = np.empty(6)
    values, columns = sparse_rows([np.eye(6), matrix])
    _times(values, columns, 1, v, out)
    assert_allclose(out, matrix @ v, rtol=1e-14, atol=1e-14)


@pytest.mark.parametrize("general_mass", [False, True], ids=["hovering-auv", "full-M"])
def test_derivative_is_fossens_equation(general_mass: bool) -> None:
    # ṗ = R v_B, q̇ from quaternion_derivative, M ν̇ = A sat(f) − C ν − D ν − g: each from the
    # numpy model (MarineVehicleModel.acceleration), a separate implementation.
    rng = np.random.default_rng(RNG_SEED + 1)
    config = HoveringAuv()
    model = random_model(rng) if general_mass else config.vehicle_model()
    allocator = config.allocator()
    dynamics = VehicleDynamics(model, allocator, 0.0)
    command = rng.normal(0.0, 60.0, 8)
    command[0] = 200.0  # beyond the limit: saturated inside
    applied = np.clip(command, -F_MAX, F_MAX)
    for _ in range(5):
        x = random_state(rng)
        x_dot = np.array(dynamics.derivative(x.tolist(), command.tolist()))
        R = rotation_from_quaternion(x[3:7])
        assert_allclose(x_dot[:3], R @ x[7:10], rtol=1e-13, atol=1e-14)
        assert_allclose(x_dot[3:7], quaternion_derivative(x[3:7], x[10:13]), atol=1e-14)
        nu_dot = model.acceleration(x[7:13], R, allocator.A @ applied)
        assert_allclose(x_dot[7:13], nu_dot, rtol=1e-11, atol=1e-11)


def test_the_lag_moves_the_applied_thrust_toward_the_saturated_command() -> None:
    rng = np.random.default_rng(RNG_SEED + 2)
    config = HoveringAuv()
    model, allocator = config.vehicle_model(), config.allocator()
    dynamics = VehicleDynamics(model, allocator, 0.05)
    assert dynamics.num_states == 21
    x = random_state(rng, 8)
    command = np.full(8, 500.0)
    x_dot = np.array(dynamics.derivative(x.tolist(), command.tolist()))
    assert_allclose(x_dot[13:], (F_MAX - x[13:]) / 0.05, rtol=1e-14)
    # The hull is driven by the lag state, not by the command.
    R = rotation_from_quaternion(x[3:7])
    assert_allclose(x_dot[7:13], model.acceleration(x[7:13], R, allocator.A @ x[13:]), atol=1e-11)


def test_step_is_kuttas_third_order_tableau() -> None:
    # One step against the tableau written out with the numpy derivative.
    rng = np.random.default_rng(RNG_SEED + 3)
    config = HoveringAuv()
    dynamics = VehicleDynamics(config.vehicle_model(), config.allocator(), 0.05)
    x, command, h = random_state(rng, 8), rng.normal(0.0, 40.0, 8).tolist(), 0.02

    def F(y: np.ndarray) -> np.ndarray:
        return np.array(dynamics.derivative(y.tolist(), command))

    k1 = F(x)
    k2 = F(x + 0.5 * h * k1)
    k3 = F(x - h * k1 + 2.0 * h * k2)
    expected = x + h / 6.0 * (k1 + 4.0 * k2 + k3)
    assert_allclose(dynamics.step(x.tolist(), command, h), expected, rtol=1e-13, atol=1e-13)
