"""The one builder of the closed loop: every system and logger named, every port wired here."""

from dataclasses import dataclass

import numpy as np
from pydrake.common import RandomDistribution
from pydrake.geometry import Meshcat
from pydrake.math import RollPitchYaw, RotationMatrix
from pydrake.systems.framework import Diagram, DiagramBuilder, LeafSystem
from pydrake.systems.primitives import LogVectorOutput, RandomSource, VectorLogSink

from drake_uuv.controllers import AttitudeGenerator, LqrTrackingController, TrackingController
from drake_uuv.estimators import RangeDifferenceKalmanFilter, RawRangeEstimator
from drake_uuv.estimators.filters_math import HandoverPolicy
from drake_uuv.plants import TargetRandomWalk, UuvPlant
from drake_uuv.primitives import NoiseHold
from drake_uuv.scenario import Scenario
from drake_uuv.sensors import DualSonar, SonarFaults

# Logger name → (system name, output port name). Each logs its port once per step.
LOGGED_PORTS: dict[str, tuple[str, str]] = {
    "uuv_state": ("uuv", "state"),
    "R_WB": ("uuv", "R_WB"),
    "target_state": ("target", "state"),
    "ranges": ("sonar", "ranges"),
    "Y": ("sonar", "Y"),
    "m": ("sonar", "m"),
    "Gamma": ("sonar", "Gamma"),
    "q_s": ("sonar", "q_s"),
    "x_hat": ("estimator", "x_hat"),
    "P": ("estimator", "P"),
    "u1_B": ("tracking_controller", "u1_B"),
    "w_W": ("attitude_generator", "w_W"),
    "a_W": ("tracking_controller", "a_W"),
    "sonar_status": ("sonar", "status"),
    "multipath": ("sonar", "multipath"),
    "measurement_status": ("estimator", "measurement_status"),
    "nis": ("estimator", "nis"),
}


@dataclass
class UuvDiagram:
    """The built diagram and handles a caller needs: its systems and loggers by name."""

    diagram: Diagram
    systems: dict[str, LeafSystem]
    loggers: dict[str, VectorLogSink]


def sonar_faults(scenario: Scenario) -> SonarFaults:
    """The sonar's fault model from ``scenario.sonar`` (all off in the paper scenario)."""
    s = scenario.sonar
    return SonarFaults(
        max_range=s.max_range,
        beam_half_angle=None
        if s.beam_half_angle_deg is None
        else np.radians(s.beam_half_angle_deg),
        dropout_probability=tuple(s.dropout_probability),
        outlier_probability=s.outlier_probability,
        outlier_scale=s.outlier_scale,
        search_sigma=s.search_sigma,
    )


def make_estimator(scenario: Scenario) -> LeafSystem:
    """The estimator named by ``estimator.type``."""
    e = scenario.estimator
    if e.type == "kf":
        return RangeDifferenceKalmanFilter(
            scenario.time_step,
            np.asarray(scenario.target.acceleration_covariance),
            np.asarray(e.initial_estimate),
            np.asarray(e.initial_covariance),
            e.gate_probability,
        )
    if e.type in ("ekf", "iekf"):
        return RawRangeEstimator(
            scenario.time_step,
            np.asarray(scenario.target.acceleration_covariance),
            np.asarray(e.initial_estimate),
            np.asarray(e.initial_covariance),
            np.asarray(scenario.sonar.noise_variances),
            scenario.sonar.samples_per_step,
            method=e.type,
            noise_model=e.noise_model,
            handover=HandoverPolicy(
                position_variance_threshold=e.linear_start_position_variance,
                max_linear_steps=e.linear_start_max_steps,
            ),
            gate_probability=e.gate_probability,
        )
    raise ValueError(f"estimator.type: unknown estimator, got {e.type!r}")


def make_tracking_controller(scenario: Scenario) -> LeafSystem:
    """The tracking law named by ``tracking.type`` (``lqr`` also reads the attitude plan)."""
    c = scenario.tracking
    q_star = np.asarray(c.desired_relative_position)
    if c.type == "paper":
        return TrackingController(scenario.time_step, c.alpha, q_star, c.max_acceleration)
    if c.type == "lqr":
        return LqrTrackingController(
            scenario.time_step,
            q_star,
            c.lqr_position_weight,
            c.lqr_velocity_weight,
            c.lqr_input_weight,
            c.max_acceleration,
            c.lqr_feedforward,
        )
    raise ValueError(f"tracking.type: unknown tracking law, got {c.type!r}")


def make_uuv_diagram(
    scenario: Scenario, builder: DiagramBuilder | None = None, meshcat: Meshcat | None = None
) -> UuvDiagram:
    """Builds the paper's closed loop from a validated scenario.

    Systems: ``uuv``, ``target``, ``sonar``, ``estimator``, ``attitude_generator``,
    ``tracking_controller``, and one named ``RandomSource`` per random input port
    (``target_noise``, ``range_noise``, ``rotation_noise``), each followed by a ``NoiseHold``
    (``<name>_hold``) so that publishes and updates of one step see the same draw. Loggers are
    ``log_<name>`` for each entry of :data:`LOGGED_PORTS`, sampled once per step so column k
    holds the value at step k, before that step's update.

    Pass a ``builder`` to add systems of your own before building, and ``meshcat`` to draw the
    scene live (a ``LiveMeshcatVisualizer`` named ``meshcat_visualizer``).
    """
    t = scenario.time_step
    builder = builder or DiagramBuilder()
    R0 = RotationMatrix(RollPitchYaw(np.asarray(scenario.uuv.initial_rpy))).matrix()

    systems: dict[str, LeafSystem] = {
        "uuv": UuvPlant(
            t,
            np.asarray(scenario.uuv.initial_position),
            np.asarray(scenario.uuv.initial_velocity),
            R0,
        ),
        "target": TargetRandomWalk(
            t,
            np.asarray(scenario.target.acceleration_covariance),
            np.asarray(scenario.target.initial_position),
            np.asarray(scenario.target.initial_velocity),
        ),
        "sonar": DualSonar(
            np.asarray(scenario.sonar.baseline),
            np.asarray(scenario.sonar.noise_variances),
            scenario.sonar.samples_per_step,
            scenario.estimator.noise_model,
            sonar_faults(scenario),
        ),
        "estimator": make_estimator(scenario),
        "attitude_generator": AttitudeGenerator(
            scenario.attitude.mode,
            t,
            np.asarray(scenario.sonar.baseline),
            scenario.attitude.rho,
            scenario.attitude.h_amplitude,
            scenario.attitude.h_frequency,
            scenario.attitude.max_angular_rate,
        ),
        "tracking_controller": make_tracking_controller(scenario),
    }
    for name, system in systems.items():
        builder.AddNamedSystem(name, system)
    uuv, target, sonar = systems["uuv"], systems["target"], systems["sonar"]
    estimator, attitude, controller = (
        systems["estimator"],
        systems["attitude_generator"],
        systems["tracking_controller"],
    )

    connect = builder.Connect
    connect(uuv.GetOutputPort("state"), sonar.GetInputPort("uuv_state"))
    connect(uuv.GetOutputPort("R_WB"), sonar.GetInputPort("R_WB"))
    connect(target.GetOutputPort("state"), sonar.GetInputPort("target_state"))
    for port in ("Y", "m", "Gamma", "q_s", "range_samples"):
        if estimator.HasInputPort(port):
            connect(sonar.GetOutputPort(port), estimator.GetInputPort(port))
    connect(sonar.GetOutputPort("status"), estimator.GetInputPort("sonar_status"))
    if sonar.HasInputPort("x_prior"):  # pan-tilts point at the prediction
        connect(estimator.GetOutputPort("x_prior"), sonar.GetInputPort("x_prior"))
        connect(estimator.GetOutputPort("P_prior"), sonar.GetInputPort("P_prior"))
    connect(controller.GetOutputPort("a_W"), estimator.GetInputPort("a_W"))
    connect(estimator.GetOutputPort("x_hat"), controller.GetInputPort("x_hat"))
    connect(uuv.GetOutputPort("R_WB"), controller.GetInputPort("R_WB"))
    if controller.HasInputPort("R_WB_plan"):
        connect(attitude.GetOutputPort("R_WB_plan"), controller.GetInputPort("R_WB_plan"))
    connect(uuv.GetOutputPort("R_WB"), attitude.GetInputPort("R_WB"))
    connect(controller.GetOutputPort("u1_B"), uuv.GetInputPort("u1_B"))
    connect(attitude.GetOutputPort("w_W"), uuv.GetInputPort("w_W"))

    # Every random input port gets its own named, seeded source sampled once per step.
    random_ports = {
        "target_noise": target.GetInputPort("acceleration_noise"),
        "range_noise": sonar.GetInputPort("range_noise"),
    }
    if attitude.HasInputPort("rotation_noise"):
        random_ports["rotation_noise"] = attitude.GetInputPort("rotation_noise")
    distributions = {"fault_uniform": RandomDistribution.kUniform,
                     "multipath_noise": RandomDistribution.kExponential}  # fmt: skip
    for name in distributions:
        if sonar.HasInputPort(name):
            random_ports[name] = sonar.GetInputPort(name)
    for name, port in random_ports.items():
        distribution = distributions.get(name, RandomDistribution.kGaussian)
        source = builder.AddNamedSystem(name, RandomSource(distribution, port.size(), t))
        hold = builder.AddNamedSystem(f"{name}_hold", NoiseHold(port.size(), t))
        connect(source.get_output_port(), hold.get_input_port())
        connect(hold.get_output_port(), port)

    loggers = {}
    for name, (system_name, port_name) in LOGGED_PORTS.items():
        logger = LogVectorOutput(systems[system_name].GetOutputPort(port_name), builder, t)
        logger.set_name(f"log_{name}")
        loggers[name] = logger

    if meshcat is not None:
        from drake_uuv.visualization import add_live_meshcat_visualizer

        add_live_meshcat_visualizer(
            builder,
            meshcat,
            np.asarray(scenario.sonar.baseline),
            t,
            uuv_state=uuv.GetOutputPort("state"),
            R_WB=uuv.GetOutputPort("R_WB"),
            target_state=target.GetOutputPort("state"),
            x_hat=estimator.GetOutputPort("x_hat"),
            P=estimator.GetOutputPort("P"),
        ).set_name("meshcat_visualizer")

    diagram = builder.Build()
    diagram.set_name("uuv_closed_loop")
    return UuvDiagram(diagram=diagram, systems=systems, loggers=loggers)
