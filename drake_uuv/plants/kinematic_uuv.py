"""The UUV of the paper: a discrete double integrator with a rotating attitude, eqs. (1)–(2)."""

from pydrake.systems.framework import Context, DiscreteValues, LeafSystem

from drake_uuv.models.motion import double_integrator_step
from drake_uuv.models.so3 import exp_so3_runs
from drake_uuv.models.tracking_laws import speed_limited_acceleration
from drake_uuv.plants.base import PlantSetting
from drake_uuv.primitives.batch import batch_size_field, per_run, tiled
from drake_uuv.scenario.plants import KinematicUuv


class KinematicUuvPlant(LeafSystem):
    """Kinematic UUV: ``X(k+1) = A X(k) + B R(k) u1(k)``, ``R(k+1) = Exp(u2(k) t) R(k)``.

    ``u1`` is a body-frame acceleration. The paper *left*-multiplies by ``Exp(u2 t)``, so ``u2``
    acts as a world-frame angular velocity (a body rate would be ``Rᵀ u2``); we keep the
    paper's equation and name the port ``u2_W`` accordingly.

    The attitude is held as the rotation matrix itself and re-orthonormalised every step with
    one Newton step of the polar decomposition, ``R ← R (3I − RᵀR) / 2``, which squares the
    orthogonality error each step: ``R_WB`` stays orthonormal to machine precision over any
    run length. Every output is a Drake state output port (no Python call per step).

    .. pydrake_system::

        name: KinematicUuvPlant
        input_ports:
        - u1_B
        - u2_W
        output_ports:
        - p_WU
        - v_WU
        - R_WB

    - ``u1_B`` (3): commanded acceleration in the body frame [m/s²].
    - ``u2_W`` (3): angular velocity command ``u2`` [rad/s], world frame (see above).
    - ``p_WU``, ``v_WU`` (3 each): position and velocity of the vehicle's body origin U (the
      midpoint of the sonars) in the world [m, m/s].
    - ``R_WB`` (9): attitude ``R`` (body to world), row-major.

    Sizes are per run: with ``batch_size`` B every port and state holds B runs row-major
    (:mod:`drake_uuv.primitives.batch`), each run from the setting's initial state.

    ``config`` (:class:`~drake_uuv.scenario.KinematicUuv`) gives the top speed ``max_speed``
    (None: none, the paper's): the applied world acceleration is limited so that
    ``|v(k+1)| ≤ max_speed`` (:func:`~drake_uuv.models.tracking_laws.speed_limited_acceleration`:
    the next velocity scaled onto that sphere). The period and the initial state are the
    ``setting``'s.
    """

    def __init__(self, config: KinematicUuv, *, setting: PlantSetting, batch_size: int = 1) -> None:
        super().__init__()
        self._time_step = setting.time_step
        self._max_speed = config.top_speed()
        self.batch_size = B = batch_size_field(batch_size)
        self._u1_port = self.DeclareVectorInputPort("u1_B", 3 * B)
        self._u2_port = self.DeclareVectorInputPort("u2_W", 3 * B)
        self._p_index = self.DeclareDiscreteState(tiled(setting.initial_position, B))
        self._v_index = self.DeclareDiscreteState(tiled(setting.initial_velocity, B))
        self._R_index = self.DeclareDiscreteState(tiled(setting.initial_R_WB, B))
        self.DeclarePeriodicDiscreteUpdateEvent(self._time_step, 0.0, self._update)
        self.DeclareStateOutputPort("p_WU", self._p_index)
        self.DeclareStateOutputPort("v_WU", self._v_index)
        self.DeclareStateOutputPort("R_WB", self._R_index)

    def _update(self, context: Context, discrete_state: DiscreteValues) -> None:
        state, B = context.get_discrete_state(), self.batch_size
        R = per_run(state.value(self._R_index), B, 3, 3)
        u1 = per_run(self._u1_port.Eval(context), B)
        a_W = (R @ u1[:, :, None])[:, :, 0]
        v = per_run(state.value(self._v_index), B)
        if self._max_speed is not None:
            a_W = speed_limited_acceleration(v, a_W, self._time_step, self._max_speed)
        p, v = double_integrator_step(
            per_run(state.value(self._p_index), B), v, a_W, self._time_step
        )
        R_next = exp_so3_runs(per_run(self._u2_port.Eval(context), B) * self._time_step) @ R
        R_next = 1.5 * R_next - 0.5 * (R_next @ (R_next.transpose(0, 2, 1) @ R_next))
        discrete_state.set_value(self._p_index, p.ravel())
        discrete_state.set_value(self._v_index, v.ravel())
        discrete_state.set_value(self._R_index, R_next.ravel())
