"""The vehicle's fast loop: the outer loop's acceleration and attitude step → 8 thrusts."""

import math

import numpy as np
from pydrake.systems.framework import Context, DiscreteValues, LeafSystem

from drake_uuv.models.so3 import cross, exp_so3, log_so3
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
    period (discrete state).

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
    """

    def __init__(
        self, config: HoveringAuv, *, outer_period: float, initial_R_WB: np.ndarray
    ) -> None:
        super().__init__()
        config.validate("config")
        if not (math.isfinite(outer_period) and outer_period > 0.0):
            raise ValueError(f"outer_period: must be > 0, got {outer_period!r}")
        self._t = float(outer_period)
        self._h = config.controller_period(self._t)
        self._ratio = round(self._t / self._h)
        self._half_h = 0.5 * self._h
        self._model = config.vehicle_model()
        self._allocator = config.allocator()
        n = self._allocator.num_thrusters
        omega, zeta = config.attitude_bandwidth, config.attitude_damping_ratio
        self._kp = omega * omega  # [1/s²] on the attitude error
        self._kd = 2.0 * zeta * omega  # [1/s] on the rate error
        self._kv = config.velocity_bandwidth  # [1/s] on the velocity error
        self._trajectory = config.attitude_reference == "trajectory"
        R0 = np.asarray(initial_R_WB, dtype=float)
        if R0.shape != (3, 3) or not np.allclose(R0.T @ R0, np.eye(3), atol=1e-9):
            raise ValueError(f"initial_R_WB: must be a rotation matrix, got {R0.tolist()!r}")

        self._u1_port = self.DeclareVectorInputPort("u1_B", 3)
        self._u2_port = self.DeclareVectorInputPort("u2_W", 3)
        self._R_port = self.DeclareVectorInputPort("R_WB", 9)
        self._nu_port = self.DeclareVectorInputPort("nu_B", 6)
        # Latched at the outer tick: a_W (3), v_WU(kt) (3), R_WB(kt) (9), kt (1).
        self._latch = self.DeclareDiscreteState(np.concatenate([np.zeros(6), R0.ravel(), [0.0]]))
        self._target = self.DeclareDiscreteState(R0.ravel())
        self._rate = self.DeclareDiscreteState(3)
        self._velocity = self.DeclareDiscreteState(3)
        self._thrust = self.DeclareDiscreteState(n)
        self._wrench = self.DeclareDiscreteState(6)
        self._scale = self.DeclareDiscreteState(np.ones(2))
        # Counts for the run's statistics: fast ticks, and those whose force, moment, either
        # the allocation had to scale down (a thruster at its limit).
        self._saturation = self.DeclareDiscreteState(np.zeros(4))
        self.DeclarePeriodicDiscreteUpdateEvent(self._h, 0.0, self._update)
        self.DeclareStateOutputPort("thrust_command", self._thrust)
        self.DeclareStateOutputPort("R_WB_command", self._target)
        self.DeclareStateOutputPort("w_WB_command", self._rate)
        self.DeclareStateOutputPort("v_WU_command", self._velocity)
        self.DeclareStateOutputPort("wrench_command", self._wrench)
        self.DeclareStateOutputPort("allocation_scale", self._scale)
        self.DeclareStateOutputPort("saturation_ticks", self._saturation)

    @property
    def period(self) -> float:
        """The fast period h [s]."""
        return self._h

    @property
    def outer_period(self) -> float:
        return self._t

    def gains(self) -> dict[str, np.ndarray]:
        """The wrench-level gains: ``M_rot ω²``, ``2ζω M_rot`` and ``M_trans ω_v`` (see above)."""
        M = self._model.M
        return {
            "attitude_stiffness": self._kp * M[3:, 3:],
            "attitude_damping": self._kd * M[3:, 3:],
            "velocity": self._kv * M[:3, :3],
        }

    def _update(self, context: Context, discrete_state: DiscreteValues) -> None:
        time = context.get_time()
        R = self._R_port.Eval(context).reshape(3, 3)
        nu = self._nu_port.Eval(context)
        v_B, w_B = nu[:3], nu[3:]
        v_W, w_W = R @ v_B, R @ w_B
        if round(time / self._h) % self._ratio == 0:
            # An outer tick: latch the fresh commands and use them at once.
            u2 = self._u2_port.Eval(context).copy()
            a_W = R @ self._u1_port.Eval(context)
            v_k, R_k, t_k = v_W, R, time
            R_target = exp_so3(u2 * self._t) @ R_k
            discrete_state.set_value(self._latch, np.concatenate([a_W, v_k, R_k.ravel(), [t_k]]))
            discrete_state.set_value(self._target, R_target.ravel())
            discrete_state.set_value(self._rate, u2)
        else:
            latch = context.get_discrete_state(self._latch).get_value()
            a_W, v_k, R_k, t_k = latch[:3], latch[3:6], latch[6:15].reshape(3, 3), latch[15]
            u2 = context.get_discrete_state(self._rate).get_value()
            R_target = context.get_discrete_state(self._target).get_value().reshape(3, 3)
        s = time - t_k
        if self._trajectory:
            R_ref, w_ref = exp_so3(u2 * s) @ R_k, u2
        else:
            R_ref, w_ref = R_target, 0.0
        v_ref = v_k + a_W * s
        alpha_W = self._kp * log_so3(R_ref @ R.T) + self._kd * (w_ref - w_W)
        a_cmd_W = a_W + self._kv * (v_ref - v_W)
        # Rows [a_cmd_W, α_W] @ R = [R_WBᵀ a_cmd_W, R_WBᵀ α_W]; then v̇_B = R_WBᵀ v̇_W − ω_B × v_B.
        nu_dot = (np.array([a_cmd_W, alpha_W]) @ R).ravel()
        nu_dot[:3] -= cross(w_B, v_B)
        # The thrust is held for h while ν moves on: the bias at mid-period, ν + ½h ν̇_des,
        # makes the held wrench right to second order in h (drag grows with the speed).
        wrench = self._model.M @ nu_dot + self._model.bias_force(nu + self._half_h * nu_dot, R)
        thrust, force_scale, moment_scale = self._allocator.allocate(wrench)
        discrete_state.set_value(self._thrust, thrust)
        discrete_state.set_value(self._velocity, v_ref)
        discrete_state.set_value(self._wrench, wrench)
        discrete_state.set_value(self._scale, np.array([force_scale, moment_scale]))
        scaled = (1.0, force_scale < 1.0, moment_scale < 1.0, min(force_scale, moment_scale) < 1.0)
        discrete_state.set_value(
            self._saturation, context.get_discrete_state(self._saturation).value() + scaled
        )
