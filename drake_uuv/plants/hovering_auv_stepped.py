"""The hovering UUV and its low-level controller stepped together, once per outer step."""

import numpy as np
from pydrake.systems.framework import BasicVector, Context, DiscreteValues, LeafSystem

from drake_uuv.models.marine_vehicle import rotation_rows
from drake_uuv.models.vehicle_dynamics import VehicleDynamics
from drake_uuv.plants.base import PlantSetting
from drake_uuv.plants.low_level_controller import (
    ControllerStates,
    low_level_law,
    saturation_counts,
)
from drake_uuv.plants.marine_vehicle import declare_vehicle_outputs, vehicle_initial_state
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
    so the list is kept in one place).
    """

    def __init__(self, config: HoveringAuv, *, setting: PlantSetting) -> None:
        super().__init__()
        self._law = low_level_law(config, setting.time_step)
        self._dynamics = VehicleDynamics(
            self._law.model, self._law.allocator, config.thrust_time_constant
        )
        self._h = self._law.period
        self._ticks = round(self._law.outer_period / self._h)
        n = self._dynamics.num_thrusters
        R0 = setting.initial_R_WB
        x0 = vehicle_initial_state(
            setting.initial_position,
            setting.initial_velocity,
            R0,
            num_lag_states=n if self._dynamics.lag else 0,
        )
        self._u1_port = self.DeclareVectorInputPort("u1_B", 3)
        self._u2_port = self.DeclareVectorInputPort("u2_W", 3)
        self._vehicle = self.DeclareDiscreteState(x0)
        state_only = {self.xd_ticket()}
        declare_vehicle_outputs(self, self._vehicle_state, state_only)
        self.DeclareVectorOutputPort("thrust", n, self._calc_thrust, state_only)
        self._states = ControllerStates(self, n, np.asarray(R0, dtype=float))
        self.DeclarePeriodicDiscreteUpdateEvent(self._law.outer_period, 0.0, self._update)

    @property
    def period(self) -> float:
        """The controller's period h [s]."""
        return self._h

    def _vehicle_state(self, context: Context) -> np.ndarray:
        return context.get_discrete_state(self._vehicle).value()

    def _calc_thrust(self, context: Context, output: BasicVector) -> None:
        if self._dynamics.lag:
            output.set_value(self._vehicle_state(context)[13:])
        else:
            command = context.get_discrete_state(self._states.thrust).value().tolist()
            output.set_value(self._dynamics.saturate(command))

    def _update(self, context: Context, discrete_state: DiscreteValues) -> None:
        law, step, h = self._law, self._dynamics.step, self._h
        x = self._vehicle_state(context).tolist()
        u1, u2 = self._u1_port.Eval(context).tolist(), self._u2_port.Eval(context).tolist()
        latch = law.latch(context.get_time(), rotation_rows(x[3:7]), x[7:13], u1, u2)
        ticks = []
        for j in range(self._ticks):
            tick = law.tick(j * h, rotation_rows(x[3:7]), x[7:13], latch)
            x = step(x, tick.thrust, h)
            ticks.append(tick)
        discrete_state.set_value(self._vehicle, x)
        self._states.store(context, discrete_state, tick, latch, saturation_counts(ticks))
