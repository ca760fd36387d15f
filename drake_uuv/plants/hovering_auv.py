"""The 8-thruster hovering UUV and its low-level controller, as one plant for the outer loop."""

from pydrake.systems.analysis import ApplySimulatorConfig, Simulator, SimulatorConfig
from pydrake.systems.framework import Diagram, DiagramBuilder

from drake_uuv.plants.base import PlantSetting
from drake_uuv.plants.low_level_controller import LowLevelController
from drake_uuv.plants.marine_vehicle import MarineVehicle
from drake_uuv.primitives.signal import Signal
from drake_uuv.scenario.plants import HoveringAuv

__all__ = ["HoveringAuvPlant", "configure_simulator"]


def configure_simulator(simulator: Simulator, config: HoveringAuv, outer_period: float) -> None:
    """Sets the integrator of a simulator whose diagram holds this vehicle (outer period t).

    Drake's RK5 (Dormand–Prince 5(4)) with error control at ``config.integrator_accuracy``,
    steps of at most one controller period, and that period as the first step. The vehicle
    is the only continuous state and it is not stiff (see ``MarineVehicle``), and its thrust
    is constant within a controller period, so the fifth-order step over a whole period
    meets the accuracy almost always: one step (7 derivative evaluations) per period, with
    error control shortening steps only in violent transients. Against Drake's
    MultibodyPlant model of the same vehicle it stays within 2e-7 m over 10 s of a
    thrust history that turns and moves the vehicle (``tests/plants/test_marine_vehicle.py``,
    tolerance 1e-6 m). Error-controlled RK3 needs an accuracy of about 1e-6 for the same
    agreement and then takes 12 evaluations per period: 500 outer steps would cost about
    10 s of CPU instead of about 6 s (``benchmarks/bench_hovering_auv.py``).
    """
    period = config.controller_period(outer_period)
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
    """``MarineVehicle`` driven by ``LowLevelController``: fills the diagram's plant slot.

    The outer loop commands, at period t, a body acceleration ``u1_B`` and a world angular
    velocity ``u2_W`` exactly as for the paper's kinematic plant; the low-level controller
    latches them at each outer tick and makes the vehicle follow ``v_WU(kt) + R(kt) u1 (τ −
    kt)`` and ``Exp(u2 (τ − kt)) R(kt)`` with its thrusters (see ``LowLevelController``).
    Systems inside: ``vehicle`` and ``low_level_controller``; each controller input is wired
    to the vehicle output of the same name.

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

    ``config`` (:class:`~drake_uuv.scenario.HoveringAuv`) is the vehicle, its thrusters and
    its controller; the ``setting`` gives the outer period and the initial state (at rest in
    rotation). Simulate with :func:`configure_simulator` (in the closed loop, the simulation
    calls this plant's :meth:`configure_simulator`). :data:`extra_signals` are logged with
    the closed loop's signals.
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

    def __init__(self, config: HoveringAuv, *, setting: PlantSetting) -> None:
        super().__init__()
        config.validate("config")
        R0 = setting.initial_R_WB
        builder = DiagramBuilder()
        vehicle = builder.AddNamedSystem(
            "vehicle",
            MarineVehicle(
                config,
                initial_position=setting.initial_position,
                initial_velocity=setting.initial_velocity,
                initial_R_WB=R0,
            ),
        )
        controller = builder.AddNamedSystem(
            "low_level_controller",
            LowLevelController(config, outer_period=setting.time_step, initial_R_WB=R0),
        )
        builder.Connect(controller.GetOutputPort("thrust_command"), vehicle.get_input_port())
        for name in ("R_WB", "nu_B"):
            builder.Connect(vehicle.GetOutputPort(name), controller.GetInputPort(name))
        for name in ("u1_B", "u2_W"):
            builder.ExportInput(controller.GetInputPort(name), name)
        for name in ("p_WU", "v_WU", "R_WB", "w_WB", "nu_B", "thrust"):
            builder.ExportOutput(vehicle.GetOutputPort(name), name)
        for name in (
            "thrust_command",
            "R_WB_command",
            "w_WB_command",
            "v_WU_command",
            "wrench_command",
            "allocation_scale",
            "saturation_ticks",
        ):
            builder.ExportOutput(controller.GetOutputPort(name), name)
        builder.BuildInto(self)
        self._vehicle, self._controller = vehicle, controller
        self._config, self._time_step = config, setting.time_step

    def configure_simulator(self, simulator: Simulator) -> None:
        """The integrator this vehicle needs (:func:`configure_simulator`)."""
        configure_simulator(simulator, self._config, self._time_step)

    @property
    def vehicle(self) -> MarineVehicle:
        return self._vehicle

    @property
    def controller(self) -> LowLevelController:
        return self._controller
