"""Thrust allocation: the matrix, the weighted least-norm inverse and attitude-first saturation."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from drake_uuv.models.thrust_allocation import (
    ThrustAllocator,
    allocation_matrix,
    weighted_pseudo_inverse,
)
from drake_uuv.scenario.plants import HoveringAuv

RNG_SEED = 7


@pytest.fixture
def allocator() -> ThrustAllocator:
    return HoveringAuv().allocator()


def null_space(A: np.ndarray) -> np.ndarray:
    _, s, Vt = np.linalg.svd(A)
    return Vt[np.sum(s > 1e-10) :].T


def test_columns_are_direction_and_moment_of_each_thruster(allocator: ThrustAllocator) -> None:
    A = allocator.A
    assert A.shape == (6, 8) and np.linalg.matrix_rank(A) == 6
    # Front-left vertical thruster at (0.25, 0.22, −0.04) pushing +z: moment r × z.
    assert_allclose(A[:, 0], [0, 0, 1, 0.22, -0.25, 0], atol=1e-15)
    # Front-left angled thruster at (0.14, 0.18, 0) pushing (1, −1, 0)/√2.
    h = math.sqrt(0.5)
    assert_allclose(A[:, 4], [h, -h, 0, 0, 0, h * (-0.14 - 0.18)], atol=1e-15)


def test_angled_thrusters_give_orthogonal_surge_sway_and_yaw(allocator: ThrustAllocator) -> None:
    planar = allocator.A[np.ix_([0, 1, 5], [4, 5, 6, 7])]
    gram = planar @ planar.T
    assert_allclose(gram - np.diag(np.diag(gram)), 0.0, atol=1e-15)
    assert np.all(np.diag(gram) > 0.2)
    # The vertical thrusters alone do heave, roll and pitch, also orthogonally.
    vertical = allocator.A[np.ix_([2, 3, 4], [0, 1, 2, 3])]
    gram = vertical @ vertical.T
    assert_allclose(gram - np.diag(np.diag(gram)), 0.0, atol=1e-15)


def test_a_layout_without_sway_authority_is_rejected() -> None:
    config = HoveringAuv()
    directions = [d[:] for d in config.thruster_directions]
    for i in range(4, 8):  # all four angled thrusters parallel: surge and sway dependent
        directions[i] = [math.sqrt(0.5), math.sqrt(0.5), 0.0]
    with pytest.raises(
        ValueError, match=r"^positions, directions: the allocation matrix has rank 5 < 6"
    ):
        ThrustAllocator(config.thruster_positions, directions, 77.55)


def test_unsaturated_wrench_asked_for_is_the_wrench_obtained(allocator: ThrustAllocator) -> None:
    rng = np.random.default_rng(RNG_SEED)
    for _ in range(100):
        wrench = rng.uniform(-1, 1, 6) * np.array([40, 40, 60, 8, 8, 8])
        f, force_scale, moment_scale = allocator.allocate(wrench)
        assert force_scale == 1.0 and moment_scale == 1.0
        assert np.abs(f).max() <= allocator.max_thrust
        assert_allclose(allocator.A @ f, wrench, atol=1e-11)


def test_weighted_pseudo_inverse_is_the_weighted_least_norm_solution() -> None:
    config = HoveringAuv()
    A = allocation_matrix(config.thruster_positions, config.thruster_directions)
    rng = np.random.default_rng(RNG_SEED + 1)
    weights = rng.uniform(0.5, 4.0, 8)
    N = null_space(A)
    assert N.shape == (8, 2)
    for _ in range(20):
        wrench = rng.normal(size=6)
        f = weighted_pseudo_inverse(A, weights) @ wrench
        assert_allclose(A @ f, wrench, atol=1e-12)
        # Optimality: the weighted thrust is orthogonal to the null space (no direction of
        # A f = τ lowers Σ w f²), and a random feasible alternative costs more.
        assert_allclose(N.T @ (weights * f), 0.0, atol=1e-12)
        other = f + N @ rng.normal(size=2)
        assert weights @ other**2 > weights @ f**2


def test_saturation_keeps_the_moment_and_the_force_direction(allocator: ThrustAllocator) -> None:
    wrench = np.array([400.0, -150.0, 80.0, 5.0, -6.0, 7.0])  # force far beyond the thrusters
    f, force_scale, moment_scale = allocator.allocate(wrench)
    obtained = allocator.A @ f
    assert moment_scale == 1.0 and 0.0 < force_scale < 1.0
    assert_allclose(obtained[3:], wrench[3:], atol=1e-11)
    assert_allclose(obtained[:3], force_scale * wrench[:3], atol=1e-11)
    # The largest scale: some thruster sits exactly at its limit, none beyond.
    assert_allclose(np.abs(f).max(), allocator.max_thrust, rtol=1e-12)


def test_an_infeasible_moment_is_scaled_and_the_force_dropped(allocator: ThrustAllocator) -> None:
    wrench = np.array([10.0, 0.0, 0.0, 0.0, 0.0, 500.0])  # yaw beyond 4 · 77.55 · 0.226 N m
    f, force_scale, moment_scale = allocator.allocate(wrench)
    obtained = allocator.A @ f
    assert force_scale == 0.0
    assert_allclose(moment_scale, 4 * allocator.max_thrust * 0.32 / math.sqrt(2) / 500.0)
    assert_allclose(obtained, [0, 0, 0, 0, 0, moment_scale * 500.0], atol=1e-10)
    assert_allclose(np.abs(f).max(), allocator.max_thrust, rtol=1e-12)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(max_thrust=0.0), r"^max_thrust: must be > 0, got 0\.0$"),
        (dict(max_thrust=float("nan")), r"^max_thrust: must be > 0, got nan$"),
        (dict(weights=np.ones(7)), r"^weights: must be 8 positive numbers, got \[1\.0, "),
        (
            dict(weights=np.array([1, 1, 1, 1, 1, 1, 1, -1.0])),
            r"^weights: must be 8 positive numbers",
        ),
    ],
)
def test_bad_allocator_arguments_name_the_parameter(kwargs: dict, message: str) -> None:
    config = HoveringAuv()
    args = dict(
        positions=config.thruster_positions,
        directions=config.thruster_directions,
        max_thrust=77.55,
    )
    with pytest.raises(ValueError, match=message):
        ThrustAllocator(**{**args, **kwargs})


def test_bad_geometry_names_the_parameter() -> None:
    with pytest.raises(
        ValueError, match=r"^positions: must be n×3 and finite, got \[1\.0, 2\.0\]$"
    ):
        allocation_matrix([1.0, 2.0], [[0, 0, 1]])
    with pytest.raises(
        ValueError, match=r"^directions: must be non-zero, got \[\[0\.0, 0\.0, 0\.0\]\]$"
    ):
        allocation_matrix([[0, 0, 0]], [[0, 0, 0]])
    with pytest.raises(ValueError, match=r"^directions: must be 1×3 and finite"):
        allocation_matrix([[0, 0, 0]], [[0, 0, 1], [0, 1, 0]])
