"""The 8-thruster hovering UUV and its low-level controller, as one plant for the outer loop."""

from pydrake.systems.analysis import ApplySimulatorConfig, Simulator, SimulatorConfig
from pydrake.systems.framework import Diagram, DiagramBuilder

from drake_uuv.plants.base import PlantSetting
from drake_uuv.plants.hovering_auv_stepped import SteppedHoveringAuv
from drake_uuv.plants.low_level_controller import ControllerStates, LowLevelController
from drake_uuv.plants.marine_vehicle import MarineVehicle
from drake_uuv.primitives.batch import batch_size_field
from drake_uuv.primitives.signal import Signal
from drake_uuv.scenario.plants import HoveringAuv

__all__ = ["HoveringAuvPlant", "configure_simulator"]


def configure_simulator(simulator: Simulator, config: HoveringAuv, outer_period: float) -> None:
    """Sets the integrator of a simulator whose diagram holds the continuous vehicle
    (``MarineVehicle``, outer period t), by ``config.integrator``.

    ``"runge_kutta5"``: Drake's RK5 (Dormand–Prince 5(4)) with error control at
    ``config.integrator_accuracy``, steps of at most one controller period, and that period
    as the first step. The vehicle is the only continuous state and it is not stiff (see
    ``MarineVehicle``), and its thrust is constant within a controller period, so the
    fifth-order step over a whole period meets the accuracy almost always: one step (7
    derivative evaluations) per period, with error control shortening steps only in violent
    transients. Against Drake's MultibodyPlant model of the same vehicle it stays within
    2e-7 m over 10 s of a thrust history that turns and moves the vehicle
    (``tests/plants/test_marine_vehicle.py``, tolerance 1e-6 m).

    ``"runge_kutta3"``: Drake's RK3 (Kutta's third order) without error control, one step
    per controller period: what ``SteppedHoveringAuv`` computes inside the plant, which is
    how ``HoveringAuvPlant`` runs it (three derivative evaluations per period, and no Drake
    event per period). Over a 500-step ``hovering_auv`` run its position stays within
    3e-5 m of RK5 at 1e-8 (seed 0, ``benchmarks/bench_hovering_auv.py --ratio``; 1.5e-4 m at
    most over seeds 0–9).
    """
    period = config.controller_period(outer_period)
    if config.integrator == "runge_kutta3":
        ApplySimulatorConfig(
            SimulatorConfig(
                integration_scheme="runge_kutta3", max_step_size=period, use_error_control=False
            ),
            simulator,
        )
        return
    ApplySimulatorConfig(
        SimulatorConfig(
            integration_scheme="runge_kutta5",
            accuracy=config.integrator_accuracy,
            max_step_size=period,
            use_error_control=True,
        ),
        simulator,
    )
    simulator.get_mutable_integrator().request_initial_step_size_target(period)


class HoveringAuvPlant(Diagram):
    """The hovering UUV and its low-level controller: fills the diagram's plant slot.

    The outer loop commands, at period t, a body acceleration ``u1_B`` and a world angular
    velocity ``u2_W`` exactly as for the paper's kinematic plant; the low-level controller
    latches them at each outer tick and makes the vehicle follow ``v_WU(kt) + R(kt) u1 (τ −
    kt)`` and ``Exp(u2 (τ − kt)) R(kt)`` with its thrusters (see ``LowLevelController``).

    Systems inside, by ``config.integrator``:

    - ``"runge_kutta3"`` (the default): ``stepped_vehicle``, a ``SteppedHoveringAuv``, which
      runs the controller's ticks and one fixed RK3 step of the vehicle per tick at each
      outer tick; its outputs change at outer ticks only.
    - ``"runge_kutta5"``: ``vehicle`` (``MarineVehicle``, continuous) and
      ``low_level_controller`` (``LowLevelController``, discrete at the controller's
      period), each controller input wired to the vehicle output of the same name;
      integrated by Drake's error-controlled RK5, so the outputs are the motion at any time.

    .. pydrake_system::

        name: HoveringAuvPlant
        input_ports:
        - u1_B
        - u2_W
        output_ports:
        - p_WU
        - v_WU
        - R_WB
        - w_WB
        - nu_B
        - thrust
        - thrust_command
        - R_WB_command
        - w_WB_command
        - v_WU_command
        - wrench_command
        - allocation_scale
        - saturation_ticks

    - ``u1_B`` (3) [m/s²], ``u2_W`` (3) [rad/s]: the outer commands (read at outer ticks).
    - ``p_WU``, ``v_WU`` (3 each), ``R_WB`` (9, row-major): the plant contract.
    - ``w_WB`` (3): achieved angular velocity, world frame; ``nu_B`` (6): body velocity.
    - ``thrust`` (8): applied thrusts [N]; ``thrust_command`` (8): the controller's.
    - ``R_WB_command`` (9): the attitude target in force, ``Exp(u2 t) R(kt)``;
      ``w_WB_command`` (3): ``u2`` in force; ``v_WU_command`` (3): the velocity reference.
    - ``wrench_command`` (6), ``allocation_scale`` (2): the body wrench asked for and the
      scales saturation applied to its force and moment parts.
    - ``saturation_ticks`` (4): fast ticks so far, and those with the force, the moment, or
      either scaled down by saturation.

    ``config`` (:class:`~drake_uuv.scenario.HoveringAuv`) is the vehicle, its thrusters, its
    controller and its integrator; the ``setting`` gives the outer period and the initial
    state (at rest in rotation). Simulate with :meth:`configure_simulator` (the closed loop's
    simulation calls it). :data:`extra_signals` are logged with the closed loop's signals.

    Sizes are per run: with ``batch_size`` B every port and state holds B runs row-major
    (:mod:`drake_uuv.primitives.batch`), each from the setting's initial state. With the
    default ``runge_kutta3`` each run's numbers are its own, the same bits whatever its
    batch (no continuous state; ``configure_simulator`` does nothing). With ``runge_kutta5``
    the error-controlled integrator chooses one step for the whole batch (see
    ``MarineVehicle``): a run then agrees with itself alone to the integrator's accuracy.
    """

    #: The outputs beyond the plant contract that a run logs (once per outer step).
    extra_signals = (
        Signal("w_WB", "uuv", (3,), "achieved angular velocity of B in W [rad/s]"),
        Signal("thrust", "uuv", (-1,), "applied thrusts [N]"),
        Signal("R_WB_command", "uuv", (3, 3), "attitude target in force, Exp(u2 t) R(kt)"),
        Signal("w_WB_command", "uuv", (3,), "commanded angular velocity u2 in force [rad/s]"),
        Signal("allocation_scale", "uuv", (2,), "scales saturation applied to force, moment"),
        Signal("saturation_ticks", "uuv", (4,), "fast ticks; with force, moment, either scaled"),
    )

    def __init__(self, config: HoveringAuv, *, setting: PlantSetting, batch_size: int = 1) -> None:
        super().__init__()
        config.validate("config")
        self.batch_size = batch_size_field(batch_size)
        builder = DiagramBuilder()
        if config.integrator == "runge_kutta3":
            stepped = builder.AddNamedSystem(
                "stepped_vehicle",
                SteppedHoveringAuv(config, setting=setting, batch_size=self.batch_size),
            )
            inputs = outputs = stepped
            self._vehicle = self._controller = None
            self._period = stepped.period
        else:
            outputs, inputs = self._add_continuous(builder, config, setting)
            self._period = self._controller.period
        for name in ("u1_B", "u2_W"):
            builder.ExportInput(inputs.GetInputPort(name), name)
        for name in ("p_WU", "v_WU", "R_WB", "w_WB", "nu_B", "thrust"):
            builder.ExportOutput(outputs.GetOutputPort(name), name)
        for name in ControllerStates.OUTPUTS:  # the controller's, from either system
            builder.ExportOutput(inputs.GetOutputPort(name), name)
        builder.BuildInto(self)
        self._config, self._time_step = config, setting.time_step

    def _add_continuous(
        self, builder: DiagramBuilder, config: HoveringAuv, setting: PlantSetting
    ) -> tuple[MarineVehicle, LowLevelController]:
        """Adds and wires ``vehicle`` and ``low_level_controller`` (``runge_kutta5``)."""
        R0 = setting.initial_R_WB
        vehicle = builder.AddNamedSystem(
            "vehicle",
            MarineVehicle(
                config,
                initial_position=setting.initial_position,
                initial_velocity=setting.initial_velocity,
                initial_R_WB=R0,
                batch_size=self.batch_size,
            ),
        )
        controller = builder.AddNamedSystem(
            "low_level_controller",
            LowLevelController(
                config,
                outer_period=setting.time_step,
                initial_R_WB=R0,
                batch_size=self.batch_size,
            ),
        )
        builder.Connect(controller.GetOutputPort("thrust_command"), vehicle.get_input_port())
        for name in ("R_WB", "nu_B"):
            builder.Connect(vehicle.GetOutputPort(name), controller.GetInputPort(name))
        self._vehicle, self._controller = vehicle, controller
        return vehicle, controller

    def configure_simulator(self, simulator: Simulator) -> None:
        """The integrator this vehicle needs (:func:`configure_simulator`); none when it is
        stepped inside the plant (``runge_kutta3``: no continuous state)."""
        if self._vehicle is not None:
            configure_simulator(simulator, self._config, self._time_step)

    @property
    def period(self) -> float:
        """The low-level controller's period h [s]."""
        return self._period

    @property
    def vehicle(self) -> MarineVehicle | None:
        """The continuous vehicle (``runge_kutta5``), else None."""
        return self._vehicle

    @property
    def controller(self) -> LowLevelController | None:
        """The controller's system (``runge_kutta5``), else None."""
        return self._controller
