"""An AHRS with a compass, a DVL and dead reckoning: what the vehicle believes of itself."""

import math
from collections.abc import Callable

import numpy as np
from numba import njit
from pydrake.common import RandomDistribution
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import (
    BasicVector,
    CacheEntry,
    Context,
    DiscreteValues,
    LeafSystem,
    ValueProducer,
)

from drake_uuv.navigation.base import NavigationSetting
from drake_uuv.primitives import declare_random_input
from drake_uuv.primitives.batch import batch_size_field, per_run
from drake_uuv.scenario.navigation import InertialNavigation


class InertialNavigationSystem(LeafSystem):
    """The navigation of a UUV with an AHRS and compass, a DVL and dead reckoning, per tick k.

    With the run's biases ``b_ψ ~ N(0, σ_ψ²)`` (heading) and ``b_v ~ N(0, σ_b² I)`` (DVL, body
    frame), drawn once, and the step's white noise ``n ~ N(0, diag(σ_roll², σ_pitch², σ_yaw²))``
    and ``n_v ~ N(0, σ_v² I)``:

    - attitude: ``R_WB_nav = RotationMatrix(RollPitchYaw(rpy + n + [0, 0, b_ψ]))`` with
      ``rpy`` Drake's ``RollPitchYaw`` of ``R_WB``; yaw is the outermost of Drake's rotations,
      so the heading bias turns the whole navigated frame about world z;
    - velocity: the DVL measures ``v_B = R_WBᵀ v_WU + b_v + n_v`` in the body frame and the
      navigation puts it in the world with its own attitude, ``v_WU_nav = R_WB_nav v_B``;
    - position, dead reckoning from the known start: ``p_WU_nav = p_WU + e_p`` with
      ``e_p(0) = 0`` and ``e_p(k) = e_p(k−1) + ½ t (e_v(k−1) + e_v(k))``, the trapezoid
      integral of the velocity error ``e_v = v_WU_nav − v_WU`` (exact for the paper's
      piecewise-constant acceleration; taken on the error rather than on ``v_WU_nav`` so a
      continuous plant adds no quadrature error of its own).

    With every σ zero the outputs are the inputs exactly: the attitude skips the roll-pitch-yaw
    round trip (worth 1e-16 of rounding) and the velocity error is zero. Near pitch ±90° roll
    and yaw are ill-defined, and noise added to them is then not a small rotation: the model
    is the AHRS's, which reports roll-pitch-yaw.

    Noise enters through random input ports only: ``navigation_noise`` is read each step;
    ``navigation_bias`` is read once, by an initialization event that latches ``σ · draw``
    into discrete state (the port then holds the run's first draw of its source, a function
    of the run's seed), so the biases hold for the whole run.

    .. pydrake_system::

        name: InertialNavigationSystem
        input_ports:
        - p_WU
        - v_WU
        - R_WB
        - navigation_noise
        - navigation_bias
        output_ports:
        - p_WU_nav
        - v_WU_nav
        - R_WB_nav

    - ``p_WU``, ``v_WU`` (3 each), ``R_WB`` (9, row-major): the vehicle's true state.
    - ``navigation_noise`` (6, random, standard normal, fresh each step): the attitude
      noise's roll, pitch, yaw draws, then the DVL noise's x, y, z (body) draws.
    - ``navigation_bias`` (4, random, standard normal, read at initialization only): the
      heading bias's draw, then the DVL bias's x, y, z (body) draws.
    - ``p_WU_nav`` [m], ``v_WU_nav`` [m/s] (3 each), ``R_WB_nav`` (9, row-major): the
      navigated state. ``R_WB_nav`` depends on ``R_WB``, the noise and the biases only;
      ``v_WU_nav`` adds ``v_WU``; ``p_WU_nav`` adds ``p_WU`` and the dead reckoning's state.

    Discrete state: group 0, the latched biases ``[b_ψ, b_v]`` (4); group 1, dead reckoning
    ``[e_p(k−1), e_v(k−1), started]`` (7), written at each tick (``started`` is 0 at k = 0,
    where ``e_p = 0``).

    Sizes are per run: with ``batch_size`` B every port and state holds B runs row-major
    (:mod:`drake_uuv.primitives.batch`); each run latches its own biases from its own first
    draw, and takes its own branches (the roll-pitch-yaw round trip is a compiled loop over
    runs, Drake's ``RollPitchYaw`` algorithm written out).

    ``config`` (:class:`~drake_uuv.scenario.InertialNavigation`) gives the σ of each error (in
    degrees for the angles); the ``setting`` the period t.
    """

    def __init__(
        self, config: InertialNavigation, *, setting: NavigationSetting, batch_size: int = 1
    ) -> None:
        super().__init__()
        self.batch_size = B = batch_size_field(batch_size)
        config.validate("navigation")
        errors = config.error_figures()
        self._time_step = setting.time_step
        self._half_step = 0.5 * setting.time_step
        self._attitude_sigma = errors.attitude_noise
        self._bias_sigma = np.array([errors.heading_bias, *[errors.velocity_bias] * 3])
        self._velocity_sigma = errors.velocity_noise
        # Which errors are off for the whole run: their arithmetic is skipped, not done on zeros.
        self._attitude_exact = not (errors.attitude_noise.any() or errors.heading_bias > 0.0)
        self._velocity_exact = errors.velocity_noise == 0.0 and errors.velocity_bias == 0.0

        self._p_port = self.DeclareVectorInputPort("p_WU", 3 * B)
        self._v_port = self.DeclareVectorInputPort("v_WU", 3 * B)
        self._R_port = self.DeclareVectorInputPort("R_WB", 9 * B)
        gaussian = RandomDistribution.kGaussian
        self._noise_port = declare_random_input(self, "navigation_noise", 6, gaussian, batch_size=B)
        self._bias_port = declare_random_input(self, "navigation_bias", 4, gaussian, batch_size=B)
        self._bias_index = self.DeclareDiscreteState(4 * B)
        self._dead_reckoning_index = self.DeclareDiscreteState(7 * B)
        self.DeclareInitializationDiscreteUpdateEvent(self._latch_bias)
        self.DeclarePeriodicDiscreteUpdateEvent(self._time_step, 0.0, self._dead_reckon)

        bias = self.discrete_state_ticket(self._bias_index)
        R, noise = self._R_port.ticket(), self._noise_port.ticket()
        self._attitude = self._declare_cache(
            "navigated attitude", self._calc_attitude, R, noise, bias
        )
        self._velocity_error = self._declare_cache(
            "velocity error", self._calc_velocity_error,
            self._attitude.ticket(), R, self._v_port.ticket(), noise, bias,
        )  # fmt: skip
        velocity_error = self._velocity_error.ticket()
        dead_reckoning = self.discrete_state_ticket(self._dead_reckoning_index)
        self._position_error = self._declare_cache(
            "position error", self._calc_position_error, velocity_error, dead_reckoning
        )
        self.DeclareVectorOutputPort(
            "p_WU_nav", 3 * B, self._calc_position,
            {self._position_error.ticket(), self._p_port.ticket()},
        )  # fmt: skip
        self.DeclareVectorOutputPort(
            "v_WU_nav", 3 * B, self._calc_velocity, {velocity_error, self._v_port.ticket()}
        )
        self.DeclareVectorOutputPort(
            "R_WB_nav", 9 * B, self._calc_R_WB_nav, {self._attitude.ticket()}
        )

    def latched_bias(self, context: Context) -> tuple[np.ndarray, np.ndarray]:
        """Each run's ``(b_ψ (B,) [rad], b_v (B×3, body) [m/s])``, as latched at
        initialization."""
        bias = per_run(context.get_discrete_state(self._bias_index).get_value(), self.batch_size)
        return bias[:, 0].copy(), bias[:, 1:].copy()

    def _declare_cache(self, description: str, calc: Callable, *tickets: object) -> CacheEntry:
        return self.DeclareCacheEntry(
            description,
            ValueProducer(allocate=AbstractValue.Make(object()).Clone, calc=calc),
            set(tickets),
        )

    def _bias(self, context: Context) -> np.ndarray:
        """The latched biases ``[b_ψ, b_v]`` (B×4)."""
        return per_run(context.get_discrete_state(self._bias_index).get_value(), self.batch_size)

    def _noise(self, context: Context) -> np.ndarray:
        """The step's draws (B×6)."""
        return per_run(self._noise_port.Eval(context), self.batch_size)

    def _latch_bias(self, context: Context, discrete_state: DiscreteValues) -> None:
        B = self.batch_size
        draws = per_run(self._bias_port.Eval(context), B)
        discrete_state.set_value(self._bias_index, (self._bias_sigma * draws).ravel())
        discrete_state.set_value(self._dead_reckoning_index, np.zeros(7 * B))

    def _calc_attitude(self, context: Context, value: AbstractValue) -> None:
        """``R_WB_nav`` (B×3×3)."""
        R = per_run(self._R_port.Eval(context), self.batch_size, 3, 3)
        if self._attitude_exact:
            value.set_value(R)
            return
        R_nav = np.empty(R.shape)
        _attitude_kernel(R, self._noise(context), self._bias(context), self._attitude_sigma, R_nav)
        value.set_value(R_nav)

    def _calc_velocity_error(self, context: Context, value: AbstractValue) -> None:
        """``e_v = R_WB_nav (R_WBᵀ v_WU + b_v + n_v) − v_WU`` (B×3)."""
        B = self.batch_size
        if self._attitude_exact and self._velocity_exact:
            value.set_value(np.zeros((B, 3)))
            return
        e_v = np.empty((B, 3))
        _velocity_error_kernel(
            per_run(self._R_port.Eval(context), B, 3, 3),
            self._attitude.Eval(context),
            per_run(self._v_port.Eval(context), B),
            self._noise(context),
            self._bias(context),
            self._velocity_sigma,
            self._attitude_exact,
            self._velocity_exact,
            e_v,
        )
        value.set_value(e_v)

    def _calc_position_error(self, context: Context, value: AbstractValue) -> None:
        """``e_p(k)`` (B×3): the trapezoid step from ``e_p(k−1)``, or 0 at k = 0 (per run)."""
        state = per_run(
            context.get_discrete_state(self._dead_reckoning_index).get_value(), self.batch_size
        )
        e_p = np.empty((self.batch_size, 3))
        _trapezoid_kernel(state, self._velocity_error.Eval(context), self._half_step, e_p)
        value.set_value(e_p)

    def _dead_reckon(self, context: Context, discrete_state: DiscreteValues) -> None:
        e_p, e_v = self._position_error.Eval(context), self._velocity_error.Eval(context)
        started = np.ones((self.batch_size, 1))
        discrete_state.set_value(
            self._dead_reckoning_index, np.concatenate([e_p, e_v, started], axis=1).ravel()
        )

    def _calc_position(self, context: Context, output: BasicVector) -> None:
        p = per_run(self._p_port.Eval(context), self.batch_size)
        output.set_value((p + self._position_error.Eval(context)).ravel())

    def _calc_velocity(self, context: Context, output: BasicVector) -> None:
        v = per_run(self._v_port.Eval(context), self.batch_size)
        output.set_value((v + self._velocity_error.Eval(context)).ravel())

    def _calc_R_WB_nav(self, context: Context, output: BasicVector) -> None:
        output.set_value(self._attitude.Eval(context).ravel())


@njit(cache=True)
def _trapezoid_kernel(
    state: np.ndarray, e_v: np.ndarray, half_step: float, out: np.ndarray
) -> None:
    """Each run's ``e_p(k) = e_p(k−1) + ½ t (e_v(k−1) + e_v(k))``, or 0 where not started."""
    for n in range(state.shape[0]):
        for i in range(3):
            if state[n, 6] == 0.0:
                out[n, i] = 0.0
            else:
                out[n, i] = state[n, i] + half_step * (state[n, 3 + i] + e_v[n, i])


@njit(cache=True)
def _attitude_kernel(
    R: np.ndarray, noise: np.ndarray, bias: np.ndarray, sigma: np.ndarray, out: np.ndarray
) -> None:
    """Each run's ``R_WB_nav``: roll-pitch-yaw of ``R`` plus ``σ n`` and the heading bias."""
    for n in range(R.shape[0]):
        roll, pitch, yaw = _roll_pitch_yaw(R[n])
        _rotation_from_roll_pitch_yaw(
            roll + sigma[0] * noise[n, 0],
            pitch + sigma[1] * noise[n, 1],
            yaw + (sigma[2] * noise[n, 2] + bias[n, 0]),
            out[n],
        )


@njit(cache=True)
def _velocity_error_kernel(
    R: np.ndarray,
    R_nav: np.ndarray,
    v: np.ndarray,
    noise: np.ndarray,
    bias: np.ndarray,
    sigma_v: float,
    attitude_exact: bool,
    velocity_exact: bool,
    out: np.ndarray,
) -> None:
    """Each run's ``e_v = R_WB_nav (R_WBᵀ v + b_v + n_v) − v``; with the attitude exact
    (``R_WB_nav = R_WB``) the DVL's error alone, ``R_WB (b_v + n_v)``."""
    v_B = np.empty(3)
    for n in range(R.shape[0]):
        for i in range(3):
            dvl = 0.0 if velocity_exact else bias[n, 1 + i] + sigma_v * noise[n, 3 + i]
            if attitude_exact:
                v_B[i] = dvl
            else:
                v_B[i] = R[n, 0, i] * v[n, 0] + R[n, 1, i] * v[n, 1] + R[n, 2, i] * v[n, 2]
                if not velocity_exact:
                    v_B[i] += dvl
        for i in range(3):
            turned = R_nav[n, i, 0] * v_B[0] + R_nav[n, i, 1] * v_B[1] + R_nav[n, i, 2] * v_B[2]
            out[n, i] = turned if attitude_exact else turned - v[n, i]


def perturbed_attitudes(R: np.ndarray, delta: np.ndarray) -> np.ndarray:
    """``RotationMatrix(RollPitchYaw(rpy(R) + δ))`` (B×3×3) of attitudes ``R`` (B×3×3) and
    angle increments ``δ`` (B×3, roll, pitch, yaw) [rad]: Drake's ``RollPitchYaw`` of a
    rotation matrix (from its quaternion and the matrix, robust near pitch ±90°) and its
    rotation matrix, written out as a compiled loop over runs (rounding may differ from
    Drake's in the last bits)."""
    R = np.ascontiguousarray(R, dtype=float).reshape(-1, 3, 3)
    delta = np.ascontiguousarray(delta, dtype=float).reshape(-1, 3)
    out = np.empty(R.shape)
    _attitude_kernel(R, delta, np.zeros((len(R), 1)), np.ones(3), out)  # 1·δ + 0 = δ exactly
    return out


@njit(cache=True)
def _roll_pitch_yaw(M: np.ndarray) -> tuple[float, float, float]:
    """Drake's ``RollPitchYaw(RotationMatrix(M))``: pitch from the matrix, roll and yaw from
    its canonical quaternion (exact at pitch ±90°, where the matrix alone loses them)."""
    trace = M[0, 0] + M[1, 1] + M[2, 2]
    if trace >= M[0, 0] and trace >= M[1, 1] and trace >= M[2, 2]:
        w, x, y, z = 1.0 + trace, M[2, 1] - M[1, 2], M[0, 2] - M[2, 0], M[1, 0] - M[0, 1]
    elif M[0, 0] >= M[1, 1] and M[0, 0] >= M[2, 2]:
        w, x = M[2, 1] - M[1, 2], 1.0 - (trace - 2.0 * M[0, 0])
        y, z = M[0, 1] + M[1, 0], M[0, 2] + M[2, 0]
    elif M[1, 1] >= M[2, 2]:
        w, x = M[0, 2] - M[2, 0], M[0, 1] + M[1, 0]
        y, z = 1.0 - (trace - 2.0 * M[1, 1]), M[1, 2] + M[2, 1]
    else:
        w, x = M[1, 0] - M[0, 1], M[0, 2] + M[2, 0]
        y, z = M[1, 2] + M[2, 1], 1.0 - (trace - 2.0 * M[2, 2])
    norm = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / norm, x / norm, y / norm, z / norm
    if w < 0.0:
        w, x, y, z = -w, -x, -y, -z
    R22, R21, R10, R00 = M[2, 2], M[2, 1], M[1, 0], M[0, 0]
    pitch = math.atan2(-M[2, 0], math.sqrt((R22 * R22 + R21 * R21 + R10 * R10 + R00 * R00) / 2))
    y_a, x_a, y_b, x_b = x + z, w - y, z - x, w + y
    eps = 2.220446049250313e-16
    z_a = 0.0 if abs(y_a) <= eps and abs(x_a) <= eps else math.atan2(y_a, x_a)
    z_b = 0.0 if abs(y_b) <= eps and abs(x_b) <= eps else math.atan2(y_b, x_b)
    roll, yaw = z_a - z_b, z_a + z_b
    if roll > math.pi:
        roll -= 2.0 * math.pi
    if roll < -math.pi:
        roll += 2.0 * math.pi
    if yaw > math.pi:
        yaw -= 2.0 * math.pi
    if yaw < -math.pi:
        yaw += 2.0 * math.pi
    return roll, pitch, yaw


@njit(cache=True)
def _rotation_from_roll_pitch_yaw(roll: float, pitch: float, yaw: float, out: np.ndarray) -> None:
    """Drake's ``RollPitchYaw(roll, pitch, yaw).ToRotationMatrix()``: ``Rz Ry Rx`` (the same
    bits)."""
    c0, c1, c2 = math.cos(roll), math.cos(pitch), math.cos(yaw)
    s0, s1, s2 = math.sin(roll), math.sin(pitch), math.sin(yaw)
    c2_s1, s2_s1 = c2 * s1, s2 * s1
    out[0, 0] = c2 * c1
    out[0, 1] = c2_s1 * s0 - s2 * c0
    out[0, 2] = c2_s1 * c0 + s2 * s0
    out[1, 0] = s2 * c1
    out[1, 1] = s2_s1 * s0 + c2 * c0
    out[1, 2] = s2_s1 * c0 - c2 * s0
    out[2, 0] = -s1
    out[2, 1] = c1 * s0
    out[2, 2] = c1 * c0
