"""An AHRS with a compass, a DVL and dead reckoning: what the vehicle believes of itself."""

from collections.abc import Callable

import numpy as np
from pydrake.common import RandomDistribution
from pydrake.common.value import AbstractValue
from pydrake.math import RollPitchYaw, RotationMatrix
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
from drake_uuv.scenario.navigation import InertialNavigation

_ZERO3 = np.zeros(3)
_ZERO3.setflags(write=False)


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
    into discrete state (the builder's ``set_random_context`` puts the seed's first draw in
    its hold before the simulator initializes), so the biases hold for the whole run.

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

    ``config`` (:class:`~drake_uuv.scenario.InertialNavigation`) gives the σ of each error (in
    degrees for the angles); the ``setting`` the period t.
    """

    def __init__(self, config: InertialNavigation, *, setting: NavigationSetting) -> None:
        super().__init__()
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

        self._p_port = self.DeclareVectorInputPort("p_WU", 3)
        self._v_port = self.DeclareVectorInputPort("v_WU", 3)
        self._R_port = self.DeclareVectorInputPort("R_WB", 9)
        gaussian = RandomDistribution.kGaussian
        self._noise_port = declare_random_input(self, "navigation_noise", 6, gaussian)
        self._bias_port = declare_random_input(self, "navigation_bias", 4, gaussian)
        self._bias_index = self.DeclareDiscreteState(4)
        self._dead_reckoning_index = self.DeclareDiscreteState(7)
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
            "p_WU_nav", 3, self._calc_position,
            {self._position_error.ticket(), self._p_port.ticket()},
        )  # fmt: skip
        self.DeclareVectorOutputPort(
            "v_WU_nav", 3, self._calc_velocity, {velocity_error, self._v_port.ticket()}
        )
        self.DeclareVectorOutputPort("R_WB_nav", 9, self._calc_R_WB_nav, {self._attitude.ticket()})

    def latched_bias(self, context: Context) -> tuple[float, np.ndarray]:
        """The run's ``(b_ψ [rad], b_v (3, body) [m/s])``, as latched at initialization."""
        bias = context.get_discrete_state(self._bias_index).get_value()
        return float(bias[0]), bias[1:].copy()

    def _declare_cache(self, description: str, calc: Callable, *tickets: object) -> CacheEntry:
        return self.DeclareCacheEntry(
            description,
            ValueProducer(allocate=AbstractValue.Make(object()).Clone, calc=calc),
            set(tickets),
        )

    def _latch_bias(self, context: Context, discrete_state: DiscreteValues) -> None:
        discrete_state.set_value(self._bias_index, self._bias_sigma * self._bias_port.Eval(context))
        discrete_state.set_value(self._dead_reckoning_index, np.zeros(7))

    def _calc_attitude(self, context: Context, value: AbstractValue) -> None:
        """``R_WB_nav`` (3×3)."""
        R = self._R_port.Eval(context).reshape(3, 3)
        if self._attitude_exact:
            value.set_value(R)
            return
        delta = self._attitude_sigma * self._noise_port.Eval(context)[:3]
        delta[2] += context.get_discrete_state(self._bias_index).get_value()[0]
        rpy = RollPitchYaw(RotationMatrix(R)).vector()
        value.set_value(RollPitchYaw(rpy + delta).ToRotationMatrix().matrix())

    def _calc_velocity_error(self, context: Context, value: AbstractValue) -> None:
        """``e_v = R_WB_nav (R_WBᵀ v_WU + b_v + n_v) − v_WU`` (3)."""
        R_nav = self._attitude.Eval(context)
        if self._attitude_exact:  # R_WB_nav = R_WB: the DVL's error alone
            value.set_value(_ZERO3 if self._velocity_exact else R_nav @ self._dvl_error(context))
            return
        R = self._R_port.Eval(context).reshape(3, 3)
        v = self._v_port.Eval(context)
        v_B = R.T @ v
        if not self._velocity_exact:
            v_B += self._dvl_error(context)
        value.set_value(R_nav @ v_B - v)

    def _dvl_error(self, context: Context) -> np.ndarray:
        """``b_v + n_v`` (3, body frame)."""
        b_v = context.get_discrete_state(self._bias_index).get_value()[1:]
        return b_v + self._velocity_sigma * self._noise_port.Eval(context)[3:]

    def _calc_position_error(self, context: Context, value: AbstractValue) -> None:
        """``e_p(k)`` (3): the trapezoid step from ``e_p(k−1)``, or 0 at k = 0."""
        state = context.get_discrete_state(self._dead_reckoning_index).get_value()
        if state[6] == 0.0:
            value.set_value(_ZERO3)
            return
        e_v = self._velocity_error.Eval(context)
        value.set_value(state[:3] + self._half_step * (state[3:6] + e_v))

    def _dead_reckon(self, context: Context, discrete_state: DiscreteValues) -> None:
        e_p, e_v = self._position_error.Eval(context), self._velocity_error.Eval(context)
        discrete_state.set_value(self._dead_reckoning_index, np.concatenate([e_p, e_v, [1.0]]))

    def _calc_position(self, context: Context, output: BasicVector) -> None:
        output.set_value(self._p_port.Eval(context) + self._position_error.Eval(context))

    def _calc_velocity(self, context: Context, output: BasicVector) -> None:
        output.set_value(self._v_port.Eval(context) + self._velocity_error.Eval(context))

    def _calc_R_WB_nav(self, context: Context, output: BasicVector) -> None:
        output.set_value(self._attitude.Eval(context).ravel())
