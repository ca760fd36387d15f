"""The plant slot's variants: the vehicle model, one dataclass each, chosen by its tag.

The vehicle's initial state is the scenario's ``uuv`` section, common to every plant. The
factory that builds the system of each variant is :func:`drake_uuv.plants.make_plant`.

``!HoveringAuv``: the 8-thruster hovering UUV, its thrusters and its low-level controller.

Every field has a YAML-loadable type and a default, and :meth:`HoveringAuv.validate` checks
them all. The defaults combine two sources:

* HoloOcean's HoveringAUV (engine source ``HoveringAUV.cpp``, "Perfect" configuration): the
  mass, neutral buoyancy, the centre of buoyancy 5 cm above the centre of mass, the thruster
  layout and the thrust limit. HoloOcean does not model this vehicle with Fossen's equations
  (it uses the game engine's damping), so
* the inertia, added mass and damping are those of the BlueROV2 Heavy (von Benzon et al.
  2022, *An Open-Source Benchmark Simulator: Control of a BlueROV2 Underwater Robot*, J. Mar.
  Sci. Eng. 10:1898, Table A1), scaled to this vehicle's mass by geometric similarity in the
  same water: with the mass ratio ``s = 31.02 / 13.5`` every length scales by ``s^(1/3)``, so

  ====================================================  ==================  ===========
  quantity                                              physical law        factor
  ====================================================  ==================  ===========
  translational added mass                              ρ L³                ``s``
  inertia, rotational added mass                        ρ L⁵                ``s^(5/3)``
  linear damping, force (viscous drag)                  μ L U               ``s^(1/3)``
  linear damping, moment                                μ L³ ω              ``s``
  quadratic damping, force (pressure drag)              ρ L² U²             ``s^(2/3)``
  quadratic damping, moment                             ρ L⁵ ω²             ``s^(5/3)``
  ====================================================  ==================  ===========

Frames: body x forward, y left, z up, origin U (the vehicle's reference point, here the centre
of gravity); world z up. Diagonal matrices are the same in Fossen's forward-starboard-down
body frame and in this one, so the BlueROV2 numbers carry over unchanged in sign.
"""

# No `from __future__ import annotations`: Drake's yaml loader needs the real field types.
import math
from dataclasses import dataclass, field
from typing import NoReturn

import numpy as np

from drake_uuv.models.marine_vehicle import MarineVehicleModel, rigid_body_mass_matrix
from drake_uuv.models.thrust_allocation import ThrustAllocator, allocation_matrix
from drake_uuv.scenario.validation import ScenarioError


@dataclass
class KinematicUuv:
    """The paper's vehicle, a world-frame double integrator driven by ``R u1`` whose attitude
    takes any commanded value in one step (its equations 1–2).

    ``max_speed`` [m/s]: a top speed, as every vehicle has (None: none, the paper's): the
    applied acceleration is limited so that ``|v(k+1)| ≤ max_speed``. The tracking law is
    told it (:meth:`top_speed`) and limits its command the same way, so that the acceleration
    it reports to the filter (``u1_W``) is the one the vehicle applies. For a stand-in of the
    hovering UUV, 0.76 m/s, its worst-direction top speed (HoloOcean's HoveringAUV thrust
    limit against the BlueROV2 drag scaled to its mass, :mod:`drake_uuv.models.vehicle_limits`);
    the BlueROV2 Heavy is rated at 1.5 m/s forward (Blue Robotics' specifications).
    """

    max_speed: float | None = None

    def validate(self, name: str) -> None:
        if self.max_speed is not None:
            if isinstance(self.max_speed, bool) or not isinstance(self.max_speed, int | float):
                raise ScenarioError(f"{name}.max_speed: must be a number, got {self.max_speed!r}")
            if not (math.isfinite(self.max_speed) and self.max_speed > 0.0):
                raise ScenarioError(f"{name}.max_speed: must be > 0, got {self.max_speed!r}")

    def top_speed(self) -> float | None:
        """The speed the plant never exceeds, which a tracking law must respect (None: none)."""
        return None if self.max_speed is None else float(self.max_speed)


ATTITUDE_REFERENCES = ("trajectory", "step")
INTEGRATORS = ("runge_kutta3", "runge_kutta5")
# The fixed step (one controller period h ≤ 1.5/controller_rate) must stay stable on the hull's
# fastest damping rate, 2 D_quad |ν| / M ≈ 16 s⁻¹ in roll at 3 rad/s: h λ ≤ 1.2, below RK3's
# 2.5, from 20 Hz on.
FIXED_STEP_MIN_RATE = 20.0

# HoloOcean HoveringAUV.cpp: 31.02 kg; each thruster gives at most 10 · 31.02 / 4 = 77.55 N.
HOVERING_AUV_MASS = 31.02
HOVERING_AUV_MAX_THRUST = 10.0 * HOVERING_AUV_MASS / 4.0

# BlueROV2 Heavy, von Benzon et al. 2022, Table A1 (added mass as the positive −X_u̇, …).
BLUEROV2_MASS = 13.5
BLUEROV2_INERTIA = (0.26, 0.23, 0.37)
BLUEROV2_ADDED_MASS = (6.36, 7.12, 18.68, 0.189, 0.135, 0.222)
BLUEROV2_LINEAR_DAMPING = (13.7, 0.0, 33.0, 0.0, 0.8, 0.0)
BLUEROV2_QUADRATIC_DAMPING = (141.0, 217.0, 190.0, 1.19, 0.47, 1.5)

_S = HOVERING_AUV_MASS / BLUEROV2_MASS  # mass ratio; lengths scale by _S ** (1/3)


def _scaled(values: tuple[float, ...], force_power: float, moment_power: float) -> list[float]:
    """Force entries times ``_S**force_power``, moment entries times ``_S**moment_power``."""
    return [v * _S**force_power for v in values[:3]] + [v * _S**moment_power for v in values[3:]]


def _default_inertia() -> list[list[float]]:
    return np.diag([i * _S ** (5.0 / 3.0) for i in BLUEROV2_INERTIA]).tolist()


def _default_added_mass() -> list[list[float]]:
    return np.diag(_scaled(BLUEROV2_ADDED_MASS, 1.0, 5.0 / 3.0)).tolist()


_H = math.sqrt(0.5)


def _default_thruster_positions() -> list[list[float]]:
    # HoloOcean HoveringAUV: 4 vertical thrusters at (±0.25, ±0.22, −0.04) m, then 4 angled
    # ones at (±0.14, ±0.18, 0) m; order front-left, front-right, rear-right, rear-left.
    return [
        [0.25, 0.22, -0.04],
        [0.25, -0.22, -0.04],
        [-0.25, -0.22, -0.04],
        [-0.25, 0.22, -0.04],
        [0.14, 0.18, 0.0],
        [0.14, -0.18, 0.0],
        [-0.14, -0.18, 0.0],
        [-0.14, 0.18, 0.0],
    ]


def _default_thruster_directions() -> list[list[float]]:
    # Vertical thrusters push along body +z. The angled ones push along (1/√2, ±1/√2, 0) with
    # the sign −sign(x y): diagonally opposite thrusters are parallel (front-left ∥ rear-right
    # along (1, −1), front-right ∥ rear-left along (1, 1)). Then the surge, sway and yaw rows
    # of the allocation matrix are mutually orthogonal (surge 1, 1, 1, 1; sway −1, 1, −1, 1;
    # yaw −1, 1, 1, −1, times 1/√2 and a 0.32/√2 m lever), so the four give full planar
    # control. Any pattern with two thrusters of a side parallel leaves sway and surge
    # dependent or couples yaw with sway.
    return [
        [0.0, 0.0, 1.0],
        [0.0, 0.0, 1.0],
        [0.0, 0.0, 1.0],
        [0.0, 0.0, 1.0],
        [_H, -_H, 0.0],
        [_H, _H, 0.0],
        [_H, -_H, 0.0],
        [_H, _H, 0.0],
    ]


@dataclass
class HoveringAuv:
    """The 8-thruster hovering UUV, its thrusters and its low-level controller.

    Units: SI (kg, m, s, N, rad). Vectors are in the body frame (x forward, y left, z up)
    from the body origin U.
    """

    # --- Hull (HoloOcean HoveringAUV) -------------------------------------------------------
    mass: float = HOVERING_AUV_MASS
    # Inertia about the centre of gravity, body axes [kg m²]: BlueROV2 diag(0.26, 0.23, 0.37)
    # × s^(5/3) = diag(1.040, 0.920, 1.480).
    inertia: list[list[float]] = field(default_factory=_default_inertia)
    # Centre of gravity G and centre of buoyancy from U [m]; HoloOcean: CB 5 cm above the CM.
    center_of_gravity: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    center_of_buoyancy: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.05])
    # Buoyant force B [N]; None: neutrally buoyant, B = m g (HoloOcean's HoveringAUV).
    buoyancy: float | None = None
    gravity: float = 9.81
    # --- Hydrodynamics (BlueROV2 Heavy, scaled: see the module notes) ----------------------
    # M_A [kg, kg m²]: (6.36, 7.12, 18.68) × s = (14.61, 16.36, 42.92),
    # (0.189, 0.135, 0.222) × s^(5/3) = (0.756, 0.540, 0.888).
    added_mass: list[list[float]] = field(default_factory=_default_added_mass)
    # Diagonal of D_lin: (13.7, 0, 33.0) × s^(1/3) = (18.08, 0, 43.54) [N s/m],
    # (0, 0.8, 0) × s = (0, 1.838, 0) [N m s].
    linear_damping: list[float] = field(
        default_factory=lambda: _scaled(BLUEROV2_LINEAR_DAMPING, 1.0 / 3.0, 1.0)
    )
    # Diagonal of D_quad: (141, 217, 190) × s^(2/3) = (245.5, 377.8, 330.8) [N s²/m²],
    # (1.19, 0.47, 1.5) × s^(5/3) = (4.76, 1.88, 6.00) [N m s²].
    quadratic_damping: list[float] = field(
        default_factory=lambda: _scaled(BLUEROV2_QUADRATIC_DAMPING, 2.0 / 3.0, 5.0 / 3.0)
    )
    # --- Thrusters (HoloOcean HoveringAUV) --------------------------------------------------
    thruster_positions: list[list[float]] = field(default_factory=_default_thruster_positions)
    thruster_directions: list[list[float]] = field(default_factory=_default_thruster_directions)
    # Largest |thrust| of each thruster [N]: 10 · 31.02 / 4 = 77.55 (HoloOcean).
    max_thrust: float = HOVERING_AUV_MAX_THRUST
    # First-order lag from commanded to applied thrust [s]; 0: none (HoloOcean applies the
    # commanded force at once).
    thrust_time_constant: float = 0.0
    # Weights of the least-norm allocation Σ w_i f_i² (equal: no thruster preferred).
    allocation_weights: list[float] = field(default_factory=lambda: [1.0] * 8)
    # --- Low-level controller ----------------------------------------------------------------
    # Update rate [Hz]; the period used is the outer period divided by round(outer · rate).
    # 50 Hz: the hold's half-period delay costs 8 · 0.01 = 0.08 rad (5°) of phase at the
    # attitude bandwidth, and 25 updates per 0.5 s outer step stay within the speed budget.
    controller_rate: float = 50.0
    # Attitude loop: natural frequency ω [rad/s] and damping ratio ζ of the error dynamics.
    # 8 rad/s with ζ = 1: after a step change Δω of the commanded rate the attitude error
    # Δω τ e^(−ωτ) peaks at Δω/(e ω) and is down to e^(−ωt) = 1.8 % of the step Δω t at the
    # paper's t = 0.5 s; 90 % of an attitude step takes 3.89/ω = 0.49 s.
    attitude_bandwidth: float = 8.0
    attitude_damping_ratio: float = 1.0
    # Velocity loop bandwidth [rad/s] (first order: time constant 0.25 s, half an outer step).
    velocity_bandwidth: float = 4.0
    # "trajectory": follow R(τ) = Exp(u2 (τ − kt)) R(kt) with the rate u2 fed forward, which
    # passes through the outer loop's R(k+1) at τ = (k+1)t; "step": regulate to R(k+1) from kt.
    attitude_reference: str = "trajectory"
    # --- Integration ---------------------------------------------------------------------------
    # "runge_kutta3": Kutta's third-order step, one per controller period (the thrust is held
    # over it), taken inside the plant with its controller: one Drake event per outer step.
    # Over a 500-step hovering_auv run the position stays within 3e-5 m of RK5 at 1e-8
    # (seed 0; 1.5e-4 m at most over seeds 0-9), the position RMSE moves by at most 4e-6 m and
    # every metric by at most 6e-4 of its value; the run costs 3.7 paper (kinematic) runs.
    # "runge_kutta5": Drake's error-controlled RK5 on the continuous vehicle (5 times slower),
    # the reference; its outputs follow the motion between outer ticks. See
    # hovering_auv.configure_simulator and benchmarks/PROFILE.md.
    integrator: str = "runge_kutta3"
    # Target accuracy of Drake's error-controlled RK5 (integrator "runge_kutta5" only).
    integrator_accuracy: float = 1e-6

    @property
    def buoyant_force(self) -> float:
        """B [N]: ``buoyancy``, or the weight when the vehicle is neutrally buoyant."""
        return self.mass * self.gravity if self.buoyancy is None else self.buoyancy

    def controller_period(self, outer_period: float) -> float:
        """The fast period h: ``t / round(t · controller_rate)``, the nearest that divides t."""
        return outer_period / max(1, round(outer_period * self.controller_rate))

    def vehicle_model(self) -> MarineVehicleModel:
        """Fossen's model of this vehicle (see ``drake_uuv/models/marine_vehicle.py``)."""
        return MarineVehicleModel(
            mass=self.mass,
            inertia_G=np.asarray(self.inertia, dtype=float),
            r_BG=np.asarray(self.center_of_gravity, dtype=float),
            r_BB=np.asarray(self.center_of_buoyancy, dtype=float),
            added_mass=np.asarray(self.added_mass, dtype=float),
            linear_damping=np.asarray(self.linear_damping, dtype=float),
            quadratic_damping=np.asarray(self.quadratic_damping, dtype=float),
            weight=self.mass * self.gravity,
            buoyancy=self.buoyant_force,
        )

    def allocator(self) -> ThrustAllocator:
        """The thrust allocation of this layout (see ``drake_uuv/models/thrust_allocation.py``)."""
        return ThrustAllocator(
            np.asarray(self.thruster_positions, dtype=float),
            np.asarray(self.thruster_directions, dtype=float),
            self.max_thrust,
            np.asarray(self.allocation_weights, dtype=float),
        )

    def top_speed(self) -> float | None:
        """None: the vehicle's speed is its dynamics', not a limit the plant enforces."""
        return None

    def validate(self, prefix: str) -> None:
        """Raises ``ScenarioError(f"{prefix}.field: requirement, got {value!r}")`` on a bad field.

        Fields are checked in declaration order and the first bad one is reported.
        """
        check = _FieldChecks(self, prefix)
        self._validate_hull(check)
        self._validate_thrusters(check)
        self._validate_controller(check)

    def _validate_hull(self, check: "_FieldChecks") -> None:
        """The rigid body, the hydrostatics and the hydrodynamics."""
        check.positive("mass")
        inertia = check.matrix("inertia", (3, 3))
        if not np.allclose(inertia, inertia.T, rtol=0.0, atol=1e-12 * np.abs(inertia).max()):
            check.fail("inertia", "must be symmetric")
        moments = np.linalg.eigvalsh(inertia)
        if moments[0] <= 0.0:
            check.fail("inertia", "must be positive definite")
        # A rigid body's principal moments obey the triangle inequality (Drake checks it too).
        if moments[2] > moments[0] + moments[1] + 1e-12 * moments[2]:
            check.fail("inertia", "principal moments must satisfy the triangle inequality")
        check.matrix("center_of_gravity", (3,))
        check.matrix("center_of_buoyancy", (3,))
        if self.buoyancy is not None:
            check.positive("buoyancy")
        check.positive("gravity")
        added = check.matrix("added_mass", (6, 6))
        if not np.allclose(added, added.T, rtol=0.0, atol=1e-12 * max(np.abs(added).max(), 1.0)):
            check.fail("added_mass", "must be symmetric")
        for name in ("linear_damping", "quadratic_damping"):
            if np.any(check.matrix(name, (6,)) < 0.0):
                check.fail(name, "must be ≥ 0 (dissipative)")
        M = rigid_body_mass_matrix(self.mass, inertia, np.asarray(self.center_of_gravity)) + added
        smallest = np.linalg.eigvalsh(M)[0]
        if smallest <= 0.0:
            check.fail(
                "added_mass",
                f"M = M_RB + M_A must be positive definite (smallest eigenvalue {smallest:.4g}; "
                "added mass enters with Fossen's sign, +diag(−X_u̇, …))",
            )

    def _validate_thrusters(self, check: "_FieldChecks") -> None:
        """The layout (full 6-DOF control), the limit, the lag and the allocation weights."""
        n = len(self.thruster_positions) if isinstance(self.thruster_positions, list) else 0
        if n < 6:
            check.fail("thruster_positions", "must list at least 6 thrusters")
        check.matrix("thruster_positions", (n, 3))
        directions = check.matrix("thruster_directions", (n, 3))
        if np.any(np.linalg.norm(directions, axis=1) < 1e-9):
            check.fail("thruster_directions", "must be non-zero")
        A = allocation_matrix(np.asarray(self.thruster_positions), directions)
        if np.linalg.matrix_rank(A) < 6:
            check.fail(
                "thruster_directions",
                f"the allocation matrix must have rank 6 for full 6-DOF control (rank "
                f"{np.linalg.matrix_rank(A)})",
            )
        check.positive("max_thrust")
        check.positive("thrust_time_constant", strict=False)
        if np.any(check.matrix("allocation_weights", (n,)) <= 0.0):
            check.fail("allocation_weights", "must be > 0")

    def _validate_controller(self, check: "_FieldChecks") -> None:
        """The low-level controller's rate and bandwidths, its reference, the integrator."""
        rate = check.positive("controller_rate")
        if not 1.0 <= rate <= 1000.0:
            check.fail("controller_rate", "must be in [1, 1000] Hz")
        check.positive("attitude_bandwidth")
        if check.positive("attitude_damping_ratio") > 3.0:
            check.fail("attitude_damping_ratio", "must be in (0, 3]")
        check.positive("velocity_bandwidth")
        bandwidth = max(self.attitude_bandwidth, self.velocity_bandwidth)
        phase_lag = bandwidth * (0.5 / rate + self.thrust_time_constant)
        if phase_lag > 0.5:
            check.fail(
                "attitude_bandwidth",
                f"the hold (half a period) and thrust lag must cost ≤ 0.5 rad of phase at the "
                f"bandwidth: max(attitude, velocity bandwidth) · (0.5/controller_rate + "
                f"thrust_time_constant) = {phase_lag:.3g}",
            )
        if self.attitude_reference not in ATTITUDE_REFERENCES:
            check.fail("attitude_reference", f"must be one of {', '.join(ATTITUDE_REFERENCES)}")
        if self.integrator not in INTEGRATORS:
            check.fail("integrator", f"must be one of {', '.join(INTEGRATORS)}")
        if check.positive("integrator_accuracy") > 0.1:
            check.fail("integrator_accuracy", "must be in (0, 0.1]")
        if self.integrator == "runge_kutta3":
            self._validate_fixed_step(check)

    def _validate_fixed_step(self, check: "_FieldChecks") -> None:
        """One explicit step per controller period must be stable (see FIXED_STEP_MIN_RATE)."""
        if self.controller_rate < FIXED_STEP_MIN_RATE:
            check.fail(
                "controller_rate",
                f"must be ≥ {FIXED_STEP_MIN_RATE:g} Hz with integrator runge_kutta3 (one "
                "fixed step per period; runge_kutta5 has no such limit)",
            )
        if 0.0 < self.thrust_time_constant < 1.0 / self.controller_rate:
            check.fail(
                "thrust_time_constant",
                f"must be 0 or ≥ 1/controller_rate = {1.0 / self.controller_rate:.3g} s with "
                "integrator runge_kutta3 (one fixed step per period; runge_kutta5 has no such "
                "limit)",
            )


class _FieldChecks:
    """One-line errors ``{prefix}.{field}: requirement, got {value!r}`` on a config's fields."""

    def __init__(self, config: object, prefix: str) -> None:
        self._config, self._prefix = config, prefix

    def fail(self, name: str, requirement: str) -> NoReturn:
        value = getattr(self._config, name)
        raise ScenarioError(f"{self._prefix}.{name}: {requirement}, got {value!r}")

    def matrix(self, name: str, shape: tuple[int, ...]) -> np.ndarray:
        """The field as a finite float array of ``shape``."""
        value = getattr(self._config, name)
        try:
            array = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            self.fail(name, f"must be a {'×'.join(map(str, shape))} array of numbers")
        if array.shape != shape or not np.all(np.isfinite(array)):
            self.fail(name, f"must be a finite {'×'.join(map(str, shape))} array")
        return array

    def positive(self, name: str, strict: bool = True) -> float:
        """The field, if it is a finite number > 0 (≥ 0 unless ``strict``)."""
        value = getattr(self._config, name)
        if not (math.isfinite(value) and (value > 0.0 if strict else value >= 0.0)):
            self.fail(name, "must be > 0" if strict else "must be ≥ 0")
        return value


#: The plant slot. The first member is the default of an untagged section.
PlantConfig = KinematicUuv | HoveringAuv
