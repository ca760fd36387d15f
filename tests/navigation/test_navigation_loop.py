"""The navigation in the closed loop: exactness, seeded statistics, biases, dead reckoning.

Statistics use the paper scenario with the LQR tracking law (the paper's law, whose velocity
mode is undamped, runs away once the attitude it acts on is noisy), and tolerances from the
sample size: a sample mean of N draws of N(0, σ²) within 4 standard errors ``4 σ/√N`` of 0,
and its mean square within the χ²(N) 99.9 % interval ``σ² [χ²₀.₀₀₀₅(N), χ²₀.₉₉₉₅(N)] / N``.
"""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pydrake.math import RollPitchYaw, RotationMatrix

from drake_uuv.diagram import make_uuv_diagram
from drake_uuv.models.statistics import chi2_ppf
from drake_uuv.scenario import load_scenario
from drake_uuv.simulation import ClosedLoopSimulation

NAV = ("p_WU_nav", "v_WU_nav", "R_WB_nav")
TRUTH = ("p_WU", "v_WU", "R_WB")
LQR = "tracking=!LqrTracking"


def _inertial(attitude=(0.0, 0.0, 0.0), heading=0.0, noise=0.0, bias=0.0) -> str:
    return (
        f"navigation=!InertialNavigation {{attitude_noise_deg: {[float(a) for a in attitude]}, "
        f"heading_bias_deg: {heading}, velocity_noise: {noise}, velocity_bias: {bias}}}"
    )


def _log(*overrides: str, steps: int = 60, seed: int = 1) -> dict[str, np.ndarray]:
    start = f"steady_state_start={min(10, steps - 1)}"
    scenario = load_scenario("paper", [*overrides, f"steps={steps}", start], seed=seed)
    return ClosedLoopSimulation(scenario).run().log


def _check_normal(samples: np.ndarray, sigma: float) -> None:
    """Each column of ``samples`` (N × m) is N(0, σ²) by its mean and its mean square."""
    n = len(samples)
    assert np.all(np.abs(samples.mean(axis=0)) <= 4.0 * sigma / math.sqrt(n)), samples.mean(0)
    low, high = (sigma**2 * chi2_ppf(p, n) / n for p in (0.0005, 0.9995))
    mean_square = np.mean(samples**2, axis=0)
    assert np.all((low <= mean_square) & (mean_square <= high)), (low, mean_square, high)


def _rpy(R_rows: np.ndarray) -> np.ndarray:
    return np.array([RollPitchYaw(RotationMatrix(R)).vector() for R in R_rows])


def _body_velocity_error(log: dict[str, np.ndarray]) -> np.ndarray:
    """``R_WBᵀ (v_WU_nav − v_WU)`` per step: the DVL's error when the attitude is exact."""
    return np.einsum("kji,kj->ki", log["R_WB"], log["v_WU_nav"] - log["v_WU"])


# ---------------------------------------------------------------- who reads the navigation


@pytest.mark.parametrize("motion", ["commanded", "navigation"])
def test_the_vehicles_own_systems_read_the_navigation_and_the_sonar_the_truth(motion) -> None:
    scenario = load_scenario(
        "paper", ["navigation=!InertialNavigation", f"estimator.vehicle_motion={motion}"]
    )
    built = make_uuv_diagram(scenario, log=False)
    owner = {id(system): name for name, system in built.systems.items()}
    read: dict[str, dict[str, str]] = {}
    for (reader, port), (producer, _) in built.diagram.connection_map().items():
        if id(reader) in owner and id(producer) in owner:
            name = reader.get_input_port(port).get_name()
            read.setdefault(owner[id(reader)], {})[name] = owner[id(producer)]
    for name in ("estimator", "attitude_generator", "tracking_controller"):
        assert "uuv" not in read[name].values(), (name, read[name])
        assert read[name]["R_WB_nav"] == "navigation"
    if motion == "navigation":
        assert read["estimator"]["p_WU_nav"] == read["estimator"]["v_WU_nav"] == "navigation"
    assert read["sonar"]["R_WB"] == read["sonar"]["p_WU"] == "uuv"
    assert read["navigation"] == {"p_WU": "uuv", "v_WU": "uuv", "R_WB": "uuv"}


def test_the_tracking_law_applies_its_command_with_the_navigated_attitude() -> None:
    """``u1_W = R_WB_nav u1_B``: the acceleration the vehicle believes it applies, which is
    not the one it applies with its true attitude."""
    log = _log(LQR, _inertial((1, 1, 1), 1))
    believed = np.einsum("kij,kj->ki", log["R_WB_nav"], log["u1_B"])
    assert_allclose(log["u1_W"], believed, rtol=0, atol=1e-12)
    applied = np.einsum("kij,kj->ki", log["R_WB"], log["u1_B"])
    assert np.max(np.abs(applied - believed)) > 1e-3


# ------------------------------------------------------------------------------ exactness


def test_perfect_navigation_is_the_truth_over_a_run() -> None:
    log = _log()
    for navigated, truth in zip(NAV, TRUTH, strict=True):
        np.testing.assert_array_equal(log[navigated], log[truth])


def test_inertial_navigation_with_every_sigma_zero_is_the_perfect_run_bit_for_bit() -> None:
    """The truth exactly, and so the whole run: the navigation's random sources, seeded last,
    leave every other draw of the seed as it was."""
    perfect, zero = _log(LQR), _log(LQR, _inertial())
    for navigated, truth in zip(NAV, TRUTH, strict=True):
        np.testing.assert_array_equal(zero[navigated], zero[truth])
    assert set(zero) == set(perfect)
    for name in perfect:
        np.testing.assert_array_equal(zero[name], perfect[name], err_msg=name)


def test_a_seed_draws_the_same_target_and_sonar_noise_whatever_the_navigation() -> None:
    paper, inertial = load_scenario("paper"), load_scenario("paper", [_inertial((1, 1, 1), 1)])
    draws = []
    for scenario in (paper, inertial):
        built = make_uuv_diagram(scenario, log=False)
        context = built.diagram.CreateDefaultContext()
        built.set_random_context(context, 4)
        draws.append({
            name: hold.get_output_port().Eval(hold.GetMyContextFromRoot(context)).copy()
            for name in ("acceleration_noise", "range_noise")
            for hold in [built.diagram.GetSubsystemByName(name)]
        })  # fmt: skip
    for name, value in draws[0].items():
        np.testing.assert_array_equal(draws[1][name], value)
    log = _log(_inertial((1, 1, 1), 1))
    np.testing.assert_array_equal(log["p_WT"], _log()["p_WT"])


def test_a_run_is_reproducible_from_its_seed() -> None:
    first, again, other = (
        _log(LQR, _inertial((1, 1, 1), 1, 0.01, 0.01), seed=s) for s in (3, 3, 4)
    )
    for name in NAV:
        np.testing.assert_array_equal(first[name], again[name])
        assert not np.array_equal(first[name], other[name])


# ---------------------------------------------------------------------- seeded statistics


@pytest.mark.slow
def test_attitude_noise_per_axis_is_white_with_its_sigma() -> None:
    """2000 steps of roll, pitch and yaw errors, ``rpy(R_WB_nav) − rpy(R_WB)`` (wrapped), with
    the heading bias off. Algorithm 2 keeps |pitch| < 80° (checked): far from the gimbal lock
    where roll-pitch-yaw, and so the model, is singular."""
    sigma = np.array([0.5, 1.0, 2.0])
    log = _log(LQR, _inertial(sigma), steps=2000, seed=11)
    truth, navigated = _rpy(log["R_WB"]), _rpy(log["R_WB_nav"])
    assert np.max(np.abs(truth[:, 1])) < math.radians(80.0)
    error = (navigated - truth + math.pi) % (2.0 * math.pi) - math.pi
    for axis in range(3):
        _check_normal(error[:, axis : axis + 1], math.radians(sigma[axis]))


@pytest.mark.slow
def test_dvl_noise_per_body_axis_is_white_with_its_sigma() -> None:
    log = _log(LQR, _inertial(noise=0.01), steps=2000, seed=12)
    _check_normal(_body_velocity_error(log), 0.01)


@pytest.mark.slow
def test_the_biases_over_many_seeds_have_their_sigma() -> None:
    """1000 seeds' latched biases: the heading's and each DVL axis's are N(0, σ²)."""
    scenario = load_scenario("paper", [_inertial(heading=2.0, bias=0.005)])
    built = make_uuv_diagram(scenario, log=False)
    navigation = built.systems["navigation"]
    heading, dvl = [], []
    for seed in range(1000):
        context = built.diagram.CreateDefaultContext()
        built.set_random_context(context, seed)
        built.diagram.ExecuteInitializationEvents(context)
        (b_psi,), (b_v,) = navigation.latched_bias(navigation.GetMyContextFromRoot(context))
        heading.append(b_psi)
        dvl.append(b_v)
    _check_normal(np.array(heading)[:, None], math.radians(2.0))
    _check_normal(np.array(dvl), 0.005)


# ------------------------------------------------------------------- biases over one run


def test_the_heading_bias_turns_the_navigated_frame_about_z_by_one_angle_per_run() -> None:
    angles = []
    for seed in (1, 2):
        log = _log(LQR, _inertial(heading=2.0), seed=seed)
        error = np.einsum("kij,klj->kil", log["R_WB_nav"], log["R_WB"])  # R_nav Rᵀ
        angle = np.arctan2(error[:, 1, 0], error[:, 0, 0])
        c, s = np.cos(angle[0]), np.sin(angle[0])
        about_z = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        assert_allclose(error, np.broadcast_to(about_z, error.shape), rtol=0, atol=1e-14)
        assert_allclose(angle, angle[0], rtol=0, atol=1e-14)
        angles.append(angle[0])
    assert 0.0 < abs(angles[0]) < math.radians(10.0) and angles[0] != angles[1]


def test_the_dvl_bias_is_one_body_vector_per_run() -> None:
    biases = []
    for seed in (1, 2):
        error = _body_velocity_error(_log(LQR, _inertial(bias=0.005), seed=seed))
        assert_allclose(error, np.broadcast_to(error[0], error.shape), rtol=0, atol=1e-15)
        biases.append(error[0])
    assert np.all(biases[0] != 0.0) and np.all(biases[0] != biases[1])


def test_dead_reckoning_is_the_trapezoid_sum_of_the_velocity_errors() -> None:
    """``e_p(k) = Σ_{j<k} ½ t (e_v(j) + e_v(j+1))`` from the logged errors, every error on."""
    log = _log(LQR, "navigation=!InertialNavigation", steps=200, seed=5)
    e_v = log["v_WU_nav"] - log["v_WU"]
    trapezoids = 0.5 * 0.5 * (e_v[:-1] + e_v[1:])
    expected = np.vstack([np.zeros(3), np.cumsum(trapezoids, axis=0)])
    e_p = log["p_WU_nav"] - log["p_WU"]
    assert np.max(np.abs(e_p[-1])) > 1e-2  # the DVL's bias has accumulated
    assert_allclose(e_p, expected, rtol=0, atol=1e-12)
