"""Fossen's 6-DOF model in plain numpy: mass matrix, Coriolis, damping, restoring, kinematics."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pydrake.math import RollPitchYaw, RotationMatrix
from pydrake.multibody.tree import RotationalInertia, SpatialInertia

from drake_uuv.models.marine_vehicle import (
    MarineVehicleModel,
    coriolis_matrix,
    quaternion_derivative,
    restoring_force,
    rigid_body_mass_matrix,
    rotation_from_quaternion,
)
from drake_uuv.models.so3 import exp_so3, hat, quaternion_from_matrix
from drake_uuv.scenario.plants import HoveringAuv

RNG_SEED = 20240601


def random_model(rng: np.random.Generator, added: bool = True) -> MarineVehicleModel:
    """A vehicle with its centre of gravity off the origin and a full symmetric M_A."""
    L = rng.normal(size=(6, 6))
    return MarineVehicleModel(
        mass=12.0,
        inertia_G=np.array([[1.0, 0.1, -0.05], [0.1, 1.4, 0.02], [-0.05, 0.02, 1.8]]),
        r_BG=np.array([0.03, -0.02, -0.05]),
        r_BB=np.array([0.01, 0.02, 0.04]),
        added_mass=(L @ L.T + np.eye(6)) if added else np.zeros((6, 6)),
        linear_damping=rng.uniform(0.0, 20.0, 6),
        quadratic_damping=rng.uniform(0.0, 200.0, 6),
        weight=12.0 * 9.81,
        buoyancy=120.0,
    )


def test_default_mass_matrix_is_positive_definite_and_the_wrong_added_mass_sign_is_rejected() -> (
    None
):
    config = HoveringAuv()
    M = config.vehicle_model().M
    assert_allclose(M, M.T)
    assert np.linalg.eigvalsh(M)[0] > 0.0
    # Diagonal: m + M_A in translation, I + M_A in rotation (BlueROV2 scaled).
    assert_allclose(np.diag(M), [45.634, 47.380, 73.943, 1.7965, 1.4604, 2.3687], rtol=1e-4)
    # Public copies of Table A1 print the added mass with a negative sign; taken literally,
    # heave's 31.02 − 42.92 < 0 kg makes M indefinite.
    flipped = config.vehicle_model()
    with pytest.raises(ValueError, match=r"^added_mass: M = M_RB \+ M_A must be positive definite"):
        MarineVehicleModel(
            config.mass,
            np.asarray(config.inertia),
            np.zeros(3),
            np.zeros(3),
            -flipped.M_A,
            np.zeros(6),
            np.zeros(6),
            1.0,
            1.0,
        )


def test_rigid_body_mass_matrix_matches_drakes_spatial_inertia() -> None:
    inertia_G = np.array([[1.0, 0.1, 0.05], [0.1, 2.0, -0.02], [0.05, -0.02, 2.5]])
    r_BG = np.array([0.1, 0.2, 0.3])
    drake = SpatialInertia.MakeFromCentralInertia(
        2.0, r_BG, RotationalInertia(1.0, 2.0, 2.5, 0.1, 0.05, -0.02)
    ).CopyToFullMatrix6()  # ordered [rotation; translation]
    order = [3, 4, 5, 0, 1, 2]
    assert_allclose(rigid_body_mass_matrix(2.0, inertia_G, r_BG), drake[np.ix_(order, order)])


def test_coriolis_matrix_is_skew_symmetric_and_does_no_work() -> None:
    rng = np.random.default_rng(RNG_SEED)
    model = random_model(rng)
    for _ in range(20):
        nu = rng.normal(size=6)
        C = model.coriolis_matrix(nu)
        assert_allclose(C, -C.T, atol=1e-12)
        assert abs(nu @ C @ nu) < 1e-12 * (1.0 + np.abs(C).max() * nu @ nu)


def test_coriolis_force_kirchhoff_equals_the_matrix_form() -> None:
    rng = np.random.default_rng(RNG_SEED + 1)
    model = random_model(rng)
    for _ in range(20):
        nu = rng.normal(size=6)
        assert_allclose(model.coriolis_force(nu), model.coriolis_matrix(nu) @ nu, atol=1e-12)


def test_rigid_body_coriolis_equals_fossens_angular_velocity_parametrisation() -> None:
    # An independent parametrisation of C_RB (Fossen 2021, Ch. 3), which depends on ω only:
    # C_RB(ω) = [[m S(ω), −m S(ω) S(r_g)], [m S(r_g) S(ω), −S(I_b ω)]].
    rng = np.random.default_rng(RNG_SEED + 2)
    model = random_model(rng, added=False)
    m, r_g = model.mass, model.r_BG
    I_b = model.M_RB[3:, 3:]
    for _ in range(20):
        nu = rng.normal(size=6)
        w = nu[3:]
        C = np.block([[m * hat(w), -m * hat(w) @ hat(r_g)], [m * hat(r_g) @ hat(w), -hat(I_b @ w)]])
        assert_allclose(coriolis_matrix(model.M_RB, nu) @ nu, C @ nu, atol=1e-12)


def test_added_mass_coriolis_gives_the_munk_moment() -> None:
    # A body translating with (u, v) in its own x-y plane feels the Munk moment
    # N = −(A22 − A11) u v (Newman, Marine Hydrodynamics, 1977): C_A ν holds +(A22 − A11) u v.
    A = np.diag([6.0, 20.0, 30.0, 0.5, 0.6, 0.7])
    u, v = 0.7, -0.4
    force = coriolis_matrix(A, np.array([u, v, 0.0, 0.0, 0.0, 0.0])) @ np.array(
        [u, v, 0.0, 0.0, 0.0, 0.0]
    )
    assert_allclose(force, [0.0, 0.0, 0.0, 0.0, 0.0, (20.0 - 6.0) * u * v], atol=1e-15)


def gvect(W: float, B: float, theta: float, phi: float, r_bg: np.ndarray, r_bb: np.ndarray):
    """Fossen's restoring forces in NED (PythonVehicleSimulator ``lib/gnc.py``, ``gvect``)."""
    sth, cth, sphi, cphi = math.sin(theta), math.cos(theta), math.sin(phi), math.cos(phi)
    return np.array(
        [
            (W - B) * sth,
            -(W - B) * cth * sphi,
            -(W - B) * cth * cphi,
            -(r_bg[1] * W - r_bb[1] * B) * cth * cphi + (r_bg[2] * W - r_bb[2] * B) * cth * sphi,
            (r_bg[2] * W - r_bb[2] * B) * sth + (r_bg[0] * W - r_bb[0] * B) * cth * cphi,
            -(r_bg[0] * W - r_bb[0] * B) * cth * sphi - (r_bg[1] * W - r_bb[1] * B) * sth,
        ]
    )


def test_restoring_force_equals_fossens_gvect_after_the_change_of_frames() -> None:
    # NED world = z-up world turned by π about x; forward-starboard-down body likewise.
    F = np.diag([1.0, -1.0, -1.0])
    rng = np.random.default_rng(RNG_SEED + 3)
    for _ in range(20):
        R_WB = RotationMatrix(RollPitchYaw(rng.uniform(-1.2, 1.2, 3))).matrix()
        r_bg, r_bb = rng.normal(scale=0.1, size=3), rng.normal(scale=0.1, size=3)
        W, B = 300.0, rng.uniform(250.0, 350.0)
        R_ned = F @ R_WB @ F
        phi, theta = math.atan2(R_ned[2, 1], R_ned[2, 2]), -math.asin(R_ned[2, 0])
        g_ned = gvect(W, B, theta, phi, F @ r_bg, F @ r_bb)
        expected = np.concatenate([F @ g_ned[:3], F @ g_ned[3:]])
        assert_allclose(restoring_force(W, B, r_bg, r_bb, R_WB), expected, atol=1e-12)


@pytest.mark.parametrize("axis", [0, 1])
def test_restoring_moment_of_a_small_tilt_is_buoyancy_times_metacentric_height(axis: int) -> None:
    # G at U, the centre of buoyancy z_BG = 5 cm above: a tilt θ about body x (roll) or y
    # (pitch) is met by a moment B z_BG sin θ against it (g holds it on the left-hand side).
    config = HoveringAuv()
    model = config.vehicle_model()
    B, z_BG, theta = config.buoyant_force, 0.05, 0.02
    rotation_vector = np.zeros(3)
    rotation_vector[axis] = theta
    g = model.restoring_force(exp_so3(rotation_vector))
    expected = np.zeros(6)
    expected[3 + axis] = B * z_BG * math.sin(theta)
    assert_allclose(g, expected, atol=1e-12)


def test_float_bias_force_equals_the_sum_of_its_terms() -> None:
    rng = np.random.default_rng(RNG_SEED + 4)
    model = random_model(rng)
    for _ in range(20):
        nu = rng.normal(size=6)
        R = RotationMatrix(RollPitchYaw(rng.uniform(-3, 3, 3))).matrix()
        expected = (
            model.coriolis_matrix(nu) @ nu + model.damping_force(nu) + model.restoring_force(R)
        )
        assert_allclose(model.bias_force(nu, R), expected, atol=1e-10)
        tau = rng.normal(size=6)
        assert_allclose(model.M @ model.acceleration(nu, R, tau), tau - expected, atol=1e-9)


def test_damping_dissipates_in_every_degree_of_freedom() -> None:
    model = HoveringAuv().vehicle_model()
    rng = np.random.default_rng(RNG_SEED + 5)
    for _ in range(20):
        nu = rng.normal(size=6)
        power = nu * model.damping_force(nu)  # per degree of freedom
        assert np.all(power >= 0.0) and power.sum() > 0.0


def test_damping_and_inertia_reject_bad_values() -> None:
    args = dict(
        mass=1.0, inertia_G=np.eye(3), r_BG=np.zeros(3), r_BB=np.zeros(3),
        added_mass=np.zeros((6, 6)), linear_damping=np.zeros(6), quadratic_damping=np.zeros(6),
        weight=1.0, buoyancy=1.0,
    )  # fmt: skip
    with pytest.raises(ValueError, match=r"^mass: must be > 0, got -1\.0$"):
        MarineVehicleModel(**{**args, "mass": -1.0})
    with pytest.raises(ValueError, match=r"^linear_damping: must be ≥ 0 \(dissipative\)"):
        MarineVehicleModel(**{**args, "linear_damping": np.array([1, 1, -1, 0, 0, 0.0])})
    asymmetric = np.zeros((6, 6))
    asymmetric[0, 1] = 1.0
    with pytest.raises(ValueError, match=r"^added_mass: must be symmetric"):
        MarineVehicleModel(**{**args, "added_mass": asymmetric})


def test_quaternion_derivative_is_the_attitude_kinematics() -> None:
    # Ṙ = R S(ω_B): compare a central difference of R(q(t)) with it.
    rng = np.random.default_rng(RNG_SEED + 6)
    for _ in range(10):
        R = RotationMatrix(RollPitchYaw(rng.uniform(-3, 3, 3))).matrix()
        q, w_B = quaternion_from_matrix(R), rng.normal(size=3)
        q_dot, eps = quaternion_derivative(q, w_B), 1e-6
        R_dot = (
            rotation_from_quaternion(q + eps * q_dot) - rotation_from_quaternion(q - eps * q_dot)
        ) / (2 * eps)
        assert_allclose(R_dot, R @ hat(w_B), atol=1e-8)


def test_quaternion_derivative_pulls_the_norm_back_to_one() -> None:
    q = 1.1 * quaternion_from_matrix(exp_so3(np.array([0.3, -0.2, 1.0])))
    q_dot = quaternion_derivative(q, np.array([0.4, 2.0, -1.0]))
    # d|q|²/dt = 2 qᵀq̇ = 2λ(1 − |q|²)|q|² with λ = 1: shrinks a long quaternion.
    assert_allclose(2 * q @ q_dot, 2 * (1 - 1.21) * 1.21, rtol=1e-12)
    # On the unit sphere the term vanishes.
    unit = q / 1.1
    assert abs(unit @ quaternion_derivative(unit, np.array([0.4, 2.0, -1.0]))) < 1e-15


def test_rotation_from_a_long_quaternion_is_a_rotation() -> None:
    R = exp_so3(np.array([0.3, -0.2, 1.0]))
    assert_allclose(rotation_from_quaternion(1.3 * quaternion_from_matrix(R)), R, atol=1e-15)


def test_energy_of_a_vehicle_at_rest_and_in_motion() -> None:
    model = HoveringAuv().vehicle_model()
    nu = np.array([0.3, 0.0, 0.0, 0.0, 0.0, 1.0])
    assert_allclose(model.kinetic_energy(nu), 0.5 * (45.634 * 0.09 + 2.3687), rtol=1e-4)
    # Neutral, G at U, CB 5 cm up: upright the CB sits 5 cm above U; capsized, 5 cm below.
    B = model.buoyancy
    assert_allclose(model.potential_energy(np.zeros(3), np.eye(3)), -B * 0.05)
    capsized = exp_so3(np.array([math.pi, 0.0, 0.0]))
    assert_allclose(model.potential_energy(np.zeros(3), capsized), B * 0.05)
