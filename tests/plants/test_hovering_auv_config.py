"""HoveringAuv: cited defaults, the scaling rule, YAML loading and one-line validation errors."""

import dataclasses
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pydrake.common.yaml import yaml_load_typed

from drake_uuv.scenario import ScenarioError, load_scenario
from drake_uuv.scenario.plants import HoveringAuv


def test_defaults_are_valid_and_cited() -> None:
    config = HoveringAuv()
    config.validate("uuv")
    assert config.mass == 31.02 and config.max_thrust == pytest.approx(77.55)
    assert config.buoyant_force == pytest.approx(31.02 * 9.81)  # neutrally buoyant
    assert config.center_of_buoyancy == [0.0, 0.0, 0.05]
    s = 31.02 / 13.5  # BlueROV2 Heavy → this vehicle, geometric similarity
    assert_allclose(np.diag(config.inertia), np.array([0.26, 0.23, 0.37]) * s ** (5 / 3))
    assert_allclose(
        np.diag(config.added_mass),
        np.concatenate(
            [np.array([6.36, 7.12, 18.68]) * s, np.array([0.189, 0.135, 0.222]) * s ** (5 / 3)]
        ),
    )
    assert_allclose(
        config.linear_damping,
        np.concatenate([np.array([13.7, 0, 33.0]) * s ** (1 / 3), np.array([0, 0.8, 0]) * s]),
    )
    assert_allclose(
        config.quadratic_damping,
        np.concatenate(
            [np.array([141, 217, 190]) * s ** (2 / 3), np.array([1.19, 0.47, 1.5]) * s ** (5 / 3)]
        ),
    )


def test_fields_have_yaml_types_and_load_with_drake() -> None:
    allowed = {float, int, bool, str, list[float], list[list[float]], float | None}
    for f in dataclasses.fields(HoveringAuv):
        assert f.type in allowed, f.name
    config = yaml_load_typed(
        schema=HoveringAuv,
        data="mass: 20.0\nbuoyancy: 200.0\ncenter_of_buoyancy: [0, 0, 0.1]\n",
        defaults=HoveringAuv(),
    )
    assert config.mass == 20.0 and config.buoyant_force == 200.0
    assert config.center_of_buoyancy == [0.0, 0.0, 0.1]
    config.validate("uuv")


def test_controller_period_divides_the_outer_period() -> None:
    assert HoveringAuv(controller_rate=50.0).controller_period(0.5) == pytest.approx(0.02)
    assert HoveringAuv(controller_rate=30.0).controller_period(0.5) == pytest.approx(0.5 / 15)
    assert HoveringAuv(controller_rate=1.0).controller_period(0.1) == pytest.approx(0.1)


def flipped_heave() -> list[list[float]]:
    added = np.asarray(HoveringAuv().added_mass)
    return (-added).tolist()


BAD = [
    ("mass", 0.0, r"uuv\.mass: must be > 0, got 0\.0"),
    ("mass", math.inf, r"uuv\.mass: must be > 0, got inf"),
    ("inertia", [[1.0, 0.0], [0.0, 1.0]], r"uuv\.inertia: must be a finite 3×3 array"),
    ("inertia", [[1.0, 0.5, 0], [0, 1.0, 0], [0, 0, 1.0]], r"uuv\.inertia: must be symmetric"),
    (
        "inertia",
        [[1.0, 0, 0], [0, 1.0, 0], [0, 0, 3.0]],
        r"uuv\.inertia: principal moments must satisfy the triangle inequality",
    ),
    (
        "inertia",
        [[1.0, 0, 0], [0, -1.0, 0], [0, 0, 1.0]],
        r"uuv\.inertia: must be positive definite",
    ),
    ("center_of_buoyancy", [0.0, 0.05], r"uuv\.center_of_buoyancy: must be a finite 3 array"),
    ("buoyancy", -1.0, r"uuv\.buoyancy: must be > 0, got -1\.0"),
    (
        "added_mass",
        flipped_heave(),
        r"uuv\.added_mass: M = M_RB \+ M_A must be positive definite \(smallest eigenvalue -11\.9",
    ),
    (
        "linear_damping",
        [1, 1, 1, 1, 1, -1.0],
        r"uuv\.linear_damping: must be ≥ 0 \(dissipative\), got \[1, 1, 1, 1, 1, -1\.0\]",
    ),
    (
        "thruster_positions",
        [[0, 0, 0]] * 5,
        r"uuv\.thruster_positions: must list at least 6 thrusters",
    ),
    (
        "thruster_directions",
        [[0, 0, 1.0]] * 8,
        r"uuv\.thruster_directions: the allocation matrix must have rank 6 for full 6-DOF control \(rank 3\)",
    ),
    ("max_thrust", -77.55, r"uuv\.max_thrust: must be > 0, got -77\.55"),
    ("thrust_time_constant", -0.1, r"uuv\.thrust_time_constant: must be ≥ 0, got -0\.1"),
    ("allocation_weights", [1.0] * 7, r"uuv\.allocation_weights: must be a finite 8 array"),
    ("controller_rate", 5000.0, r"uuv\.controller_rate: must be in \[1, 1000\] Hz, got 5000\.0"),
    ("attitude_damping_ratio", 0.0, r"uuv\.attitude_damping_ratio: must be > 0, got 0\.0"),
    (
        "attitude_bandwidth",
        60.0,
        r"uuv\.attitude_bandwidth: the hold \(half a period\) and thrust lag must cost ≤ 0\.5 rad of phase .* = 0\.6, got 60\.0",
    ),
    (
        "attitude_reference",
        "ramp",
        r"uuv\.attitude_reference: must be one of trajectory, step, got 'ramp'",
    ),
    (
        "integrator",
        "euler",
        r"uuv\.integrator: must be one of runge_kutta3, runge_kutta5, got 'euler'",
    ),
    ("integrator_accuracy", 0.5, r"uuv\.integrator_accuracy: must be in \(0, 0\.1\], got 0\.5"),
    (
        "controller_rate",
        10.0,
        r"uuv\.controller_rate: must be ≥ 20 Hz with integrator runge_kutta3 \(one fixed step per "
        r"period; runge_kutta5 has no such limit\), got 10\.0$",
    ),
    (
        "thrust_time_constant",
        0.01,
        r"uuv\.thrust_time_constant: must be 0 or ≥ 1/controller_rate = 0\.02 s with integrator "
        r"runge_kutta3 .*, got 0\.01$",
    ),
]


@pytest.mark.parametrize("field, value, message", BAD, ids=[f"{b[0]}={b[1]!r}"[:40] for b in BAD])
def test_validate_names_the_first_bad_field_and_its_value(
    field: str, value: object, message: str
) -> None:
    config = dataclasses.replace(HoveringAuv(), **{field: value})
    with pytest.raises(ScenarioError, match=f"^{message}"):
        config.validate("uuv")


def test_the_fixed_step_limits_bind_only_the_fixed_step() -> None:
    # One RK3 step per controller period: a slow controller or a lag shorter than the period
    # would make it unstable; the error-controlled RK5 shortens its steps instead.
    for config in (HoveringAuv(controller_rate=10.0), HoveringAuv(thrust_time_constant=0.01)):
        dataclasses.replace(config, integrator="runge_kutta5").validate("uuv")
    HoveringAuv(thrust_time_constant=0.02).validate("uuv")  # exactly one period


def test_the_default_integrator_is_the_fixed_step() -> None:
    assert HoveringAuv().integrator == "runge_kutta3"
    with pytest.raises(
        ScenarioError,
        match=r"^plant\.integrator: must be one of runge_kutta3, runge_kutta5, got 'rk4'$",
    ):
        load_scenario("hovering_auv", ["plant.integrator=rk4"])
    accurate = load_scenario("hovering_auv", ["plant.integrator=runge_kutta5"]).plant
    assert accurate.integrator == "runge_kutta5"


def test_thrust_lag_counts_against_the_bandwidth() -> None:
    HoveringAuv(thrust_time_constant=0.05).validate("uuv")  # 8 · (0.01 + 0.05) = 0.48
    with pytest.raises(ScenarioError, match=r"^uuv\.attitude_bandwidth: .* = 0\.88, got 8\.0$"):
        HoveringAuv(thrust_time_constant=0.1).validate("uuv")
