"""The hovering UUV and its low-level controller stepped together, once per outer step."""

import numpy as np
from pydrake.systems.framework import BasicVector, Context, DiscreteValues, LeafSystem

from drake_uuv.models.vehicle_kernels import stepped_runs
from drake_uuv.plants.base import PlantSetting
from drake_uuv.plants.low_level_controller import ControllerStates, float_rows, low_level_law
from drake_uuv.plants.marine_vehicle import declare_vehicle_outputs, vehicle_initial_state
from drake_uuv.primitives.batch import batch_size_field, tiled
from drake_uuv.scenario.plants import HoveringAuv

__all__ = ["SteppedHoveringAuv"]


class SteppedHoveringAuv(LeafSystem):
    """``LowLevelController`` and ``MarineVehicle`` as one discrete-time system (``runge_kutta3``).

    At each outer tick kt it latches the commands ``u1_B``, ``u2_W`` and then runs the
    controller's ticks of the step itself, ``τ_j = kt + j h`` (j = 0 … t/h − 1): at each, the
    controller's law (``LowLevelLaw``, as ``LowLevelController`` computes it) gives the
    thrusts, and one step of Kutta's third-order Runge–Kutta scheme
    (``VehicleDynamics.step``) carries the vehicle over ``[τ_j, τ_j + h]`` under them. This is
    what Drake's fixed-step ``RungeKutta3Integrator`` (step h) computes on the
    ``MarineVehicle`` + ``LowLevelController`` diagram, the thrust being constant over each
    step (the tests check the two against each other), without a Drake event per controller
    tick: the simulator of the closed loop sees one update per outer step.

    Its outputs are those of that diagram at the outer ticks, where the closed loop reads
    them: the vehicle's state at kt, and the controller's outputs of its last tick, kt − h.
    In between they do not move: from the update at kt on they show what it computed, the
    state at (k+1)t. A system that needs the motion between ticks (a live view) needs the
    continuous vehicle (``integrator: runge_kutta5``).

    Ports: ``HoveringAuvPlant``'s, the same names, sizes and meanings (its
    ``pydrake_system`` block lists them: the plant exports this system's ports one for one,
    so the list is kept in one place). With ``batch_size`` B every port and state holds B
    runs row-major; an outer step of all of them is one compiled kernel
    (``vehicle_kernels.stepped_runs``), which takes each run's whole step (latch, ticks,
    allocation under saturation, RK3 steps) in turn.
    """

    def __init__(self, config: HoveringAuv, *, setting: PlantSetting, batch_size: int = 1) -> None:
        super().__init__()
        self.batch_size = B = batch_size_field(batch_size)
        self._law = law = low_level_law(config, setting.time_step)
        self._h = law.period
        self._n = n = law.allocator.num_thrusters
        self._lag = config.thrust_time_constant > 0.0
        self._max_thrust = law.allocator.max_thrust
        R0 = setting.initial_R_WB
        x0 = vehicle_initial_state(
            setting.initial_position,
            setting.initial_velocity,
            R0,
            num_lag_states=n if self._lag else 0,
        )
        self._u1_port = self.DeclareVectorInputPort("u1_B", 3 * B)
        self._u2_port = self.DeclareVectorInputPort("u2_W", 3 * B)
        self._vehicle = self.DeclareDiscreteState(tiled(x0, B))
        state_only = {self.xd_ticket()}
        declare_vehicle_outputs(self, self._vehicle_state, state_only, B)
        self.DeclareVectorOutputPort("thrust", n * B, self._calc_thrust, state_only)
        self._states = ControllerStates(self, n, np.asarray(R0, dtype=float), B)
        self.DeclarePeriodicDiscreteUpdateEvent(law.outer_period, 0.0, self._update)

    @property
    def period(self) -> float:
        """The controller's period h [s]."""
        return self._h

    def _vehicle_state(self, context: Context) -> np.ndarray:
        return context.get_discrete_state(self._vehicle).value()

    def _calc_thrust(self, context: Context, output: BasicVector) -> None:
        if self._lag:
            x = self._vehicle_state(context).reshape(self.batch_size, -1)
            output.set_value(x[:, 13:].ravel())
        else:  # the held command, saturated as the vehicle applies it
            command = context.get_discrete_state(self._states.thrust).value()
            output.set_value(np.clip(command, -self._max_thrust, self._max_thrust))

    def _update(self, context: Context, discrete_state: DiscreteValues) -> None:
        B, a = self.batch_size, self._law.arrays
        x = float_rows(self._vehicle_state(context), B)
        x_next = np.empty_like(x)
        out = self._states.next_state(context)
        stepped_runs(
            context.get_time(),
            x,
            float_rows(self._u1_port.Eval(context), B),
            float_rows(self._u2_port.Eval(context), B),
            self._states.saturation_counts(context),
            *a,
            x_next,
            *out,
        )
        discrete_state.set_value(self._vehicle, x_next.ravel())
        self._states.store(discrete_state, out)
