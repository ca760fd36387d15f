"""The vehicle's fast loop: the outer loop's acceleration and attitude step → 8 thrusts."""

import math

import numpy as np
from pydrake.systems.framework import Context, DiscreteValues, LeafSystem

from drake_uuv.models.vehicle_control import LowLevelLaw
from drake_uuv.models.vehicle_kernels import controller_runs
from drake_uuv.primitives.batch import batch_size_field, tiled
from drake_uuv.scenario.plants import HoveringAuv


class LowLevelController(LeafSystem):
    """Velocity and attitude tracking by computed torque, allocated to the thrusters.

    **Commands.** The outer loop runs at period t and, at its tick k, publishes ``u1_B`` (a
    body-frame acceleration) and ``u2_W`` (a world-frame angular velocity) for the paper's
    step ``X(k+1) = A X(k) + B R(k) u1``, ``R(k+1) = Exp(u2 t) R(k)``. Between its ticks those
    ports are direct-feedthrough outputs recomputed from the moving vehicle, so they are not
    commands: this system *latches* them, together with ``R(kt)`` and ``v_WU(kt)``, at every
    outer tick. The latch and the thrust computation are one periodic update at the fast
    period h, which latches first when its time is an outer tick, so the command of step k
    acts from ``kt`` on (two separate events at ``kt`` would both read the pre-update latch
    and apply command k one fast period late). ``h = t / round(t · controller_rate)``, the
    nearest period that divides t.

    **References** over ``τ ∈ [kt, (k+1)t)``, ``s = τ − kt``:

    - velocity ``v_ref = v_WU(kt) + a_W s`` with ``a_W = R(kt) u1_B`` fed forward, so perfect
      tracking reproduces the paper's double integrator over the step;
    - attitude, ``attitude_reference = "trajectory"``: ``R_ref = Exp(u2 s) R(kt)`` with the
      rate ``u2`` fed forward; it passes through ``R(k+1)`` at ``s = t``.
      ``"step"``: ``R_ref = R(k+1)`` from ``kt`` on, with zero rate.

    **Control law (computed torque).** With the attitude error ``e = Log(R_ref R_WBᵀ)`` (world
    frame) and ``ω_W = R_WB ω_B``, the desired accelerations are

        α_W = ω² e + 2ζω (ω_ref − ω_W),        a_W,cmd = a_W + ω_v (v_ref − v_WU),

    expressed in the body frame as ``ν̇_des = [R_WBᵀ a_W,cmd − ω_B × v_B, R_WBᵀ α_W]``
    (since ``v̇_W = R (v̇_B + ω_B × v_B)`` and ``ω̇_W = R ω̇_B``), and the body wrench is

        τ = M ν̇_des + C(ν) ν + D(ν) ν + g(η)

    with the model's M (rigid body *and* added mass), Coriolis, damping and restoring terms,
    the velocity-dependent ones taken at the mid-period velocity ``ν + ½ h ν̇_des`` because the
    wrench is held for h while the drag moves on (this cuts the per-step velocity error of a
    constant-acceleration command at 0.5 m/s tenfold, to 1e-4 m/s).
    Substituting τ into ``M ν̇ + C ν + D ν + g = τ`` gives ``ν̇ = ν̇_des``, so for a small error
    ``ë + 2ζω ė + ω² e = 0`` (the attitude error is a second-order system of natural frequency
    ω = ``attitude_bandwidth`` and damping ratio ζ = ``attitude_damping_ratio``) and the
    velocity error obeys ``ė_v = −ω_v e_v`` (``ω_v = velocity_bandwidth``). The gains are
    not tuned: in wrench terms they are ``M_rot ω²`` and ``2ζω M_rot`` [N m/rad, N m s/rad]
    and ``M_trans ω_v`` [N s/m], i.e. the vehicle's inertia times the chosen dynamics. The
    design holds while the hold and the thrust lag cost little phase at ω (checked by
    ``HoveringAuv.validate``) and the thrusters do not saturate.

    **Feedback.** The law reads the vehicle's own state (``R_WB``, ``nu_B``, inside the
    plant), not the navigation's ``R_WB_nav``: it is a fast inner loop, at the controller's
    rate 1/h, on a gyro-stabilised attitude, whose short-term error the gyros keep far below
    the AHRS's error per report. The navigation's errors enter through the outer loop, which
    computes ``u1_B`` and ``u2_W`` from ``R_WB_nav`` once per step t: the per-step AHRS error
    is what the outer loop sees.

    **Allocation.** ``τ`` goes to the thrusters through ``ThrustAllocator`` (weighted
    pseudo-inverse, attitude first under saturation); the thrusts are held for one fast
    period (discrete state). The parameters of the law are ``LowLevelLaw``
    (``drake_uuv/models/vehicle_control.py``), its arithmetic ``vehicle_kernels.py``.

    .. pydrake_system::

        name: LowLevelController
        input_ports:
        - u1_B
        - u2_W
        - R_WB
        - nu_B
        output_ports:
        - thrust_command
        - R_WB_command
        - w_WB_command
        - v_WU_command
        - wrench_command
        - allocation_scale
        - saturation_ticks

    - ``u1_B`` (3), ``u2_W`` (3): the outer loop's commands, read at outer ticks only.
    - ``R_WB`` (9, row-major), ``nu_B`` (6, ``[v_B, ω_B]``): the vehicle's state (its own
      feedback, see above).
    - ``thrust_command`` (n): held thrust commands [N].
    - ``R_WB_command`` (9): the attitude target in force, ``R(k+1) = Exp(u2 t) R(kt)``.
    - ``w_WB_command`` (3): the commanded world angular velocity ``u2`` in force [rad/s].
    - ``v_WU_command`` (3): the velocity reference at the last fast tick [m/s].
    - ``wrench_command`` (6): the body wrench τ asked of the allocation [N, N m].
    - ``allocation_scale`` (2): the scales the allocation applied to τ's force and moment
      parts (1, 1 when every thruster is within its limit).
    - ``saturation_ticks`` (4): counts since the start, of fast ticks and of those whose
      force, moment, or either, the allocation scaled down (the fraction of time saturated).

    Sizes are per run: with ``batch_size`` B every port and state holds B runs row-major
    (:mod:`drake_uuv.primitives.batch`), each run from ``initial_R_WB``. The tick of every
    run is one compiled kernel (``vehicle_kernels.controller_runs``); a run's saturation
    branches are its own.
    """

    def __init__(
        self,
        config: HoveringAuv,
        *,
        outer_period: float,
        initial_R_WB: np.ndarray,
        batch_size: int = 1,
    ) -> None:
        super().__init__()
        self.batch_size = B = batch_size_field(batch_size)
        self._law = low_level_law(config, outer_period)
        self._t, self._h = self._law.outer_period, self._law.period
        self._ratio = round(self._t / self._h)
        R0 = np.asarray(initial_R_WB, dtype=float)
        if R0.shape != (3, 3) or not np.allclose(R0.T @ R0, np.eye(3), atol=1e-9):
            raise ValueError(f"initial_R_WB: must be a rotation matrix, got {R0.tolist()!r}")
        self._u1_port = self.DeclareVectorInputPort("u1_B", 3 * B)
        self._u2_port = self.DeclareVectorInputPort("u2_W", 3 * B)
        self._R_port = self.DeclareVectorInputPort("R_WB", 9 * B)
        self._nu_port = self.DeclareVectorInputPort("nu_B", 6 * B)
        self._states = ControllerStates(self, self._law.allocator.num_thrusters, R0, B)
        self.DeclarePeriodicDiscreteUpdateEvent(self._h, 0.0, self._update)

    @property
    def period(self) -> float:
        """The fast period h [s]."""
        return self._h

    @property
    def outer_period(self) -> float:
        return self._t

    def gains(self) -> dict[str, np.ndarray]:
        """The wrench-level gains: ``M_rot ω²``, ``2ζω M_rot`` and ``M_trans ω_v`` (see above)."""
        return self._law.wrench_gains()

    def _update(self, context: Context, discrete_state: DiscreteValues) -> None:
        time, B, a = context.get_time(), self.batch_size, self._law.arrays
        # An outer tick (the same for every run): latch the fresh commands and use them at
        # once; otherwise the latch of the last one holds.
        fresh = round(time / self._h) % self._ratio == 0
        out = self._states.next_state(context)
        controller_runs(
            time,
            fresh,
            float_rows(self._R_port.Eval(context), B),
            float_rows(self._nu_port.Eval(context), B),
            float_rows(self._u1_port.Eval(context), B),
            float_rows(self._u2_port.Eval(context), B),
            self._states.saturation_counts(context),
            a.hull,
            a.values,
            a.columns,
            a.pinv,
            a.law,
            *out,
        )
        self._states.store(discrete_state, out)


def float_rows(vector: np.ndarray, batch_size: int) -> np.ndarray:
    """A batched port or state vector as a writable C-contiguous ``(B, n)`` float copy (the
    compiled kernels' one signature)."""
    return np.array(vector, dtype=float).reshape(batch_size, -1)


def low_level_law(config: HoveringAuv, outer_period: float) -> LowLevelLaw:
    """The law of ``config``'s controller for an outer period t (validated, > 0)."""
    config.validate("config")
    if not (math.isfinite(outer_period) and outer_period > 0.0):
        raise ValueError(f"outer_period: must be > 0, got {outer_period!r}")
    omega, zeta = config.attitude_bandwidth, config.attitude_damping_ratio
    return LowLevelLaw(
        config.vehicle_model(),
        config.allocator(),
        period=config.controller_period(outer_period),
        outer_period=float(outer_period),
        gains=(omega * omega, 2.0 * zeta * omega, config.velocity_bandwidth),
        trajectory=config.attitude_reference == "trajectory",
        thrust_time_constant=config.thrust_time_constant,
    )


class ControllerStates:
    """The controller's discrete state on ``system`` and the outputs that publish it.

    Groups, declared in this order, each per run (B runs row-major): the latch
    ``[a_W, v_WU(kt), R_WB(kt) (9), kt]`` (16), the target ``R(k+1)`` (9), the rate ``u2``
    (3), the velocity reference (3), the thrusts (n), the wrench (6), the allocation's
    scales (2), the saturation counts (4); every group but the latch is published by a state
    output port (``LowLevelController``'s outputs).
    """

    #: The state output ports, in the order of the groups they publish.
    OUTPUTS = (
        "thrust_command",
        "R_WB_command",
        "w_WB_command",
        "v_WU_command",
        "wrench_command",
        "allocation_scale",
        "saturation_ticks",
    )

    def __init__(
        self, system: LeafSystem, num_thrusters: int, initial_R_WB: np.ndarray, batch_size: int
    ) -> None:
        B, R0 = batch_size, initial_R_WB.ravel()
        self.batch_size = B
        self.latch_group = system.DeclareDiscreteState(
            tiled(np.concatenate([np.zeros(6), R0, [0.0]]), B)
        )
        self.target = system.DeclareDiscreteState(tiled(R0, B))
        self.rate = system.DeclareDiscreteState(3 * B)
        self.velocity = system.DeclareDiscreteState(3 * B)
        self.thrust = system.DeclareDiscreteState(num_thrusters * B)
        self.wrench = system.DeclareDiscreteState(6 * B)
        self.scale = system.DeclareDiscreteState(np.ones(2 * B))
        # Counts for the run's statistics: fast ticks, and those whose force, moment, either
        # the allocation had to scale down (a thruster at its limit).
        self.saturation = system.DeclareDiscreteState(np.zeros(4 * B))
        # The groups a kernel writes, in its argument order (controller_runs, stepped_runs).
        self.written = (
            self.latch_group, self.target, self.rate, self.velocity, self.thrust, self.wrench,
            self.scale, self.saturation,
        )  # fmt: skip
        published = (
            self.thrust, self.target, self.rate, self.velocity, self.wrench, self.scale,
            self.saturation,
        )  # fmt: skip
        for name, group in zip(self.OUTPUTS, published, strict=True):
            system.DeclareStateOutputPort(name, group)

    def next_state(self, context: Context) -> list[np.ndarray]:
        """Writable ``(B, size)`` copies of the groups a kernel writes, holding their values
        now (a kernel that does not latch leaves the latch as it was)."""
        return [
            float_rows(context.get_discrete_state(group).value(), self.batch_size)
            for group in self.written
        ]

    def saturation_counts(self, context: Context) -> np.ndarray:
        """The counts so far, ``(B, 4)``."""
        return float_rows(context.get_discrete_state(self.saturation).value(), self.batch_size)

    def store(self, discrete_state: DiscreteValues, values: list[np.ndarray]) -> None:
        """Writes ``values`` (as from :meth:`next_state`, after the kernel) to the groups."""
        for group, value in zip(self.written, values, strict=True):
            discrete_state.set_value(group, value.ravel())
