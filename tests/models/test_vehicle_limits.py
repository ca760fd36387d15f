"""Vehicle limits against their closed forms for the default layout, and the budget's bound."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from drake_uuv.models.vehicle_limits import sphere_directions, utilisation_budget, vehicle_limits
from drake_uuv.scenario.plants import HoveringAuv

F = 77.55  # N per thruster
HORIZONTAL = 2 * math.sqrt(2) * F  # |Fx| + |Fy| + |Mz|/0.32 m ≤ this (angled group)
VERTICAL = 4 * F  # |Fz| + |Mx|/0.22 m + |My|/0.25 m ≤ this (vertical group)


@pytest.fixture(scope="module")
def vehicle():
    config = HoveringAuv()
    return config.vehicle_model(), config.allocator()


def test_utilisation_is_the_closed_form_of_the_two_thruster_groups(vehicle) -> None:
    _, allocator = vehicle
    rng = np.random.default_rng(11)
    for wrench in rng.normal(scale=[50, 50, 50, 5, 5, 5], size=(20, 6)):
        fx, fy, fz, mx, my, mz = wrench
        expected = max(
            (abs(fx) + abs(fy) + abs(mz) / 0.32) / HORIZONTAL,
            (abs(fz) + abs(mx) / 0.22 + abs(my) / 0.25) / VERTICAL,
        )
        assert_allclose(allocator.utilisation(wrench), expected, rtol=1e-12)


def test_sphere_directions_are_unit_and_spread() -> None:
    d = sphere_directions(500)
    assert_allclose(np.linalg.norm(d, axis=1), 1.0)
    assert_allclose(d.mean(axis=0), 0.0, atol=0.01)


def test_limits_match_their_closed_forms(vehicle) -> None:
    model, allocator = vehicle
    limits = vehicle_limits(model, allocator)
    m = np.diag(model.M)
    # Worst acceleration: diagonal in the horizontal plane, (m_x |d_x| + m_y |d_y|) a = 2√2 F.
    assert limits.acceleration == pytest.approx(HORIZONTAL / math.hypot(m[0], m[1]), rel=1e-3)
    # Worst angular acceleration: yaw, M_zz α = 0.32 · 2√2 F (roll-pitch's worst is 30.9 rad/s²).
    assert limits.angular_acceleration == pytest.approx(0.32 * HORIZONTAL / m[5], rel=1e-3)
    # Drag-limited speed: horizontal, near sway (377.8 v² = 2√2 F gives 0.762 m/s; a little
    # surge adds its linear drag first): the least over headings θ of the v solving
    # D_x(v cos θ) + D_y(v sin θ) = 2√2 F.
    dl, dq = model.linear_damping, model.quadratic_damping
    theta = np.linspace(0.0, math.pi / 2, 20001)
    c, s = np.cos(theta), np.sin(theta)
    # (dq_x c² + dq_y s²) v² + (dl_x c + dl_y s) v − 2√2 F = 0, per heading.
    a2, a1 = dq[0] * c**2 + dq[1] * s**2, dl[0] * c + dl[1] * s
    v = (-a1 + np.sqrt(a1**2 + 4 * a2 * HORIZONTAL)) / (2 * a2)
    assert limits.speed == pytest.approx(v.min(), rel=1e-3)
    assert v.min() < math.sqrt(HORIZONTAL / dq[1])
    # Steady rate: yaw, 6.00 ω² = 0.32 · 2√2 F.
    assert limits.angular_rate == pytest.approx(
        math.sqrt(0.32 * HORIZONTAL / model.quadratic_damping[5]), rel=1e-3
    )


def test_budget_parts_and_their_bound(vehicle) -> None:
    model, allocator = vehicle
    limits = vehicle_limits(model, allocator)
    kwargs = dict(attitude_bandwidth=8.0, attitude_damping_ratio=1.0)
    zero = dict(acceleration=0.0, speed=0.0, angular_rate=0.0, rate_step=0.0, tilt=0.0)
    parts = utilisation_budget(model, allocator, **{**zero, "acceleration": 1.0}, **kwargs)
    # The budget samples 400 directions, the limits 2000: agreement to the lattice's 0.5 %.
    assert parts["acceleration"] == pytest.approx(1.0 / limits.acceleration, rel=5e-3)
    assert parts["total"] == pytest.approx(parts["acceleration"])
    # A rate step Δω meets the attitude loop's rate gain: M_rot 2ζω Δω.
    parts = utilisation_budget(model, allocator, **{**zero, "rate_step": 0.5}, **kwargs)
    assert parts["rate_step"] == pytest.approx(0.5 * 16.0 / limits.angular_acceleration, rel=5e-3)
    # Tilted 90°, the restoring moment is B z_BG = 15.2 N m about a horizontal axis.
    parts = utilisation_budget(model, allocator, **{**zero, "tilt": math.pi / 2}, **kwargs)
    B = model.buoyancy
    worst = max(
        B * 0.05 * math.hypot(1 / 0.22, 1 / 0.25) / VERTICAL,  # about the diagonal axis
        B * 0.05 / 0.22 / VERTICAL,
    )
    assert parts["tilt"] == pytest.approx(worst, rel=1e-2)
    # The total bounds the sum of the loads and is no more than the sum of the parts.
    envelope = dict(acceleration=0.5, speed=0.3, angular_rate=0.5, rate_step=0.5, tilt=0.5)
    parts = utilisation_budget(model, allocator, **envelope, **kwargs)
    names = ("acceleration", "speed", "angular_rate", "coupling", "rate_step", "tilt")
    assert max(parts[n] for n in names) <= parts["total"] <= sum(parts[n] for n in names)
