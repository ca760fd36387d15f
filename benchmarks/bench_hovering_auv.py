"""Cost and tracking of the hovering UUV plant: in the closed loop against the paper's run, and
driven alone by a fixed outer-command pattern.

    python benchmarks/bench_hovering_auv.py --ratio [--repeats 5]
    python benchmarks/bench_hovering_auv.py --errors 10
    python benchmarks/bench_hovering_auv.py --closed-loop [--steps 500] [--set FIELD=VALUE ...]
    python benchmarks/bench_hovering_auv.py [--steps 500] [--max-angular-rate 0.5]
        [--acceleration 0.15] [--speed 0.4] [--accuracy 1e-6] [--attitude-reference step]
        [--figures DIR] [--sweep] [--limits]

``--ratio`` prints the cost of the flyable hovering-UUV run (``ClosedLoopSimulation`` of the
``hovering_auv`` scenario, what ``drake-uuv run --scenario hovering_auv`` simulates) over the
paper's run on its kinematic plant (the ``paper`` scenario), both built once and run
alternately ``--repeats`` times at the scenario's seed: CPU seconds per run (min and median;
CPU time is less inflated than wall time on a busy machine) and the median of the pairwise
ratios (target: at most 5). It does so for each integrator of the vehicle
(``plant.integrator``: the default fixed step ``runge_kutta3`` and the error-controlled
``runge_kutta5``) and for the same loop on the kinematic plant (``plant=KinematicUuv``: the
difference is the vehicle's cost), then prints ``--errors 1``.

``--errors N`` runs seeds 0 … N−1 of ``hovering_auv`` with each integrator against
``runge_kutta5`` at accuracy 1e-8 and prints, per seed and at most over the seeds, the
largest distance between the vehicle positions, the change of the position RMSE and the
largest relative change of any metric.

``--closed-loop`` times one run of the paper scenario with ``plant=!HoveringAuv`` (and any
``--set`` overrides), the whole diagram with sonar, filter and both controllers, built once
and run once, and prints the run's vehicle metrics.

Without either, the plant alone, on the continuous vehicle (``integrator: runge_kutta5``:
the figures read it between outer ticks). The outer commands at period t = 0.5 s are the
paper's Algorithm 2 attitude plan (the project's ``TrajectoryAttitudeGenerator``, optionally
rate-limited) and a bounded world acceleration ``a_W(τ) = a [cos(ωτ), cos(4ωτ/3), ½
cos(2ωτ)]``, ``ω = a/v``, sent as ``u1_B = R_WBᵀ a_W``; its velocity has amplitudes ``[v,
¾v, ¼v]``, so ``v`` keeps the speed under the vehicle's drag-limited 0.76 m/s while ``a``
sets the acceleration. Prints the wall and CPU time of the simulation alone and what the
figures need: the attitude error at each outer tick against the target ``R(k+1) = Exp(u2 t)
R(k)`` (mean, peak), the fraction of fast ticks at which the allocation had to scale the
wrench down, and the peak achieved angular rate, angular acceleration, acceleration and
speed. ``--sweep`` runs a grid of rate limits and accelerations instead; ``--limits`` prints
the worst-direction limits derived from the thrust limits and inertia
(``drake_uuv/models/vehicle_limits.py``) and what the vehicle reaches when asked for more;
``--figures`` writes the attitude-tracking and thrust figures.
"""

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import BasicVector, Context, Diagram, DiagramBuilder, LeafSystem
from pydrake.systems.primitives import ConstantVectorSource, LogVectorOutput, VectorLogSink

from drake_uuv import ClosedLoopSimulation
from drake_uuv.analysis.figures import save_figure
from drake_uuv.analysis.vehicle_figures import (
    attitude_errors,
    attitude_tracking_figure,
    thrust_figure,
)
from drake_uuv.attitude import TrajectoryAttitudeGenerator, attitude_setting
from drake_uuv.models.vehicle_limits import vehicle_limits
from drake_uuv.plants import PlantSetting
from drake_uuv.plants.hovering_auv import HoveringAuvPlant
from drake_uuv.scenario import TrajectoryAttitude, load_scenario
from drake_uuv.scenario.plants import HoveringAuv

OUTER_PERIOD = 0.5
#: From rest, upright, at the origin, stepped at the outer period.
AT_REST = PlantSetting(OUTER_PERIOD, np.zeros(3), np.zeros(3), np.eye(3))


class BoundedAcceleration(LeafSystem):
    """``u1_B = R_WBᵀ a_W(kt)``, the pattern of the module notes (input ``R_WB``)."""

    def __init__(self, amplitude: float, speed: float) -> None:
        super().__init__()
        self._amplitude = amplitude
        # a cos(ω τ) has velocity amplitude a/ω: ω = a/v gives v on x, ¾v on y, ¼v on z.
        self._omega = amplitude / speed * np.array([1.0, 4.0 / 3.0, 2.0])
        self._R = self.DeclareVectorInputPort("R_WB", 9)
        self.DeclareVectorOutputPort("u1_B", 3, self._calc)

    def world_acceleration(self, time: float) -> np.ndarray:
        return self._amplitude * np.array([1.0, 1.0, 0.5]) * np.cos(self._omega * time)

    def _calc(self, context: Context, output: BasicVector) -> None:
        R = self._R.Eval(context).reshape(3, 3)
        output.set_value(R.T @ self.world_acceleration(context.get_time()))


def build(
    config: HoveringAuv, max_angular_rate: float | None, acceleration: float, speed: float
) -> tuple[Diagram, HoveringAuvPlant, dict[str, VectorLogSink], dict[str, VectorLogSink]]:
    """The plant, Algorithm 2 and the acceleration pattern, with loggers; returns the pieces."""
    builder = DiagramBuilder()
    plant = builder.AddNamedSystem("uuv", HoveringAuvPlant(config, setting=AT_REST))
    attitude = builder.AddNamedSystem(
        "attitude_generator",
        TrajectoryAttitudeGenerator(
            TrajectoryAttitude(max_angular_rate=max_angular_rate),
            setting=attitude_setting(load_scenario("paper")),  # t = 0.5 s, the paper's b
        ),
    )
    accel = builder.AddNamedSystem("acceleration", BoundedAcceleration(acceleration, speed))
    builder.Connect(plant.GetOutputPort("R_WB"), attitude.GetInputPort("R_WB"))
    builder.Connect(plant.GetOutputPort("R_WB"), accel.GetInputPort("R_WB"))
    builder.Connect(attitude.GetOutputPort("u2_W"), plant.GetInputPort("u2_W"))
    builder.Connect(accel.GetOutputPort("u1_B"), plant.GetInputPort("u1_B"))
    h = plant.period
    outer = {
        name: LogVectorOutput(plant.GetOutputPort(name), builder, OUTER_PERIOD)
        for name in ("R_WB", "R_WB_command", "w_WB", "w_WB_command")
    }
    fast = {
        name: LogVectorOutput(plant.GetOutputPort(name), builder, h)
        for name in ("thrust", "allocation_scale", "w_WB", "v_WU", "nu_B")
    }
    return builder.Build(), plant, outer, fast


def run(
    config: HoveringAuv,
    steps: int,
    max_angular_rate: float | None,
    acceleration: float,
    speed: float,
) -> tuple[dict[str, float], dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Simulates ``steps`` outer steps: the figures printed by ``main``, the logs at the outer
    and at the controller's period (dicts keyed by port name, plus ``time``)."""
    start = time.perf_counter()
    diagram, plant, outer, fast = build(config, max_angular_rate, acceleration, speed)
    simulator = Simulator(diagram)
    plant.configure_simulator(simulator)
    simulator.Initialize()
    built, cpu = time.perf_counter(), time.process_time()
    simulator.AdvanceTo(steps * OUTER_PERIOD)
    wall, cpu = time.perf_counter() - built, time.process_time() - cpu
    context = simulator.get_context()
    log = {name: logger.FindLog(context).data().T for name, logger in outer.items()}
    log["time"] = outer["R_WB"].FindLog(context).sample_times()
    fast_log = {name: logger.FindLog(context).data().T for name, logger in fast.items()}
    fast_log["time"] = fast["thrust"].FindLog(context).sample_times()
    # Row k of the outer logs is step k before its update: R_WB_command there is R(k) as
    # commanded at step k − 1, so row-by-row differences are the tracking error at each tick.
    errors = attitude_errors(log)[1:]
    scale = fast_log["allocation_scale"]
    h = plant.period
    w = fast_log["w_WB"]
    v = fast_log["v_WU"]
    integrator = simulator.get_integrator()
    return (
        {
            "wall_s": wall,
            "cpu_s": cpu,
            "build_s": built - start,
            "attitude_error_mean_rad": float(np.mean(errors)),
            "attitude_error_peak_rad": float(np.max(errors)),
            "scaled_fraction": float(np.mean(np.any(scale < 1.0 - 1e-12, axis=1))),
            "at_limit_fraction": float(
                np.mean(
                    np.any(np.abs(fast_log["thrust"]) >= config.max_thrust * (1 - 1e-9), axis=1)
                )
            ),
            "peak_rate_cmd_rad_s": float(np.max(np.linalg.norm(log["w_WB_command"], axis=1))),
            "peak_rate_rad_s": float(np.max(np.linalg.norm(w, axis=1))),
            "peak_angular_acceleration_rad_s2": float(
                np.max(np.linalg.norm(np.diff(w, axis=0), axis=1)) / h
            ),
            "peak_acceleration_m_s2": float(np.max(np.linalg.norm(np.diff(v, axis=0), axis=1)) / h),
            "peak_speed_m_s": float(np.max(np.linalg.norm(v, axis=1))),
            "derivative_evaluations": integrator.get_num_derivative_evaluations(),
            "integrator_steps": integrator.get_num_steps_taken(),
        },
        log,
        fast_log,
    )


def check_limits(config: HoveringAuv) -> None:
    """Prints the derived worst-direction limits and what the vehicle reaches when pushed."""
    limits = vehicle_limits(config.vehicle_model(), config.allocator())
    cases = (  # (what, u1_B, u2_W, seconds)
        ("yaw rate", np.zeros(3), np.array([0.0, 0.0, 6.0]), 8.0),
        ("sway speed", np.array([0.0, 3.0, 0.0]), np.zeros(3), 8.0),
        ("diagonal acceleration", np.array([4.0, 4.0, 0.0]), np.zeros(3), 0.5),
    )
    print("derived worst-direction limits (pseudo-inverse allocation):")
    for name, value in vars(limits).items():
        print(f"  {name:22s} {value:.3f}")
    print("reached in simulation when commanded beyond them (from rest, upright):")
    for what, u1, u2, seconds in cases:
        builder = DiagramBuilder()
        plant = builder.AddSystem(HoveringAuvPlant(config, setting=AT_REST))
        for name, value in (("u1_B", u1), ("u2_W", u2)):
            source = builder.AddSystem(ConstantVectorSource(value))
            builder.Connect(source.get_output_port(), plant.GetInputPort(name))
        h = plant.period
        w_log = LogVectorOutput(plant.GetOutputPort("w_WB"), builder, h)
        v_log = LogVectorOutput(plant.GetOutputPort("v_WU"), builder, h)
        simulator = Simulator(builder.Build())
        plant.configure_simulator(simulator)
        simulator.AdvanceTo(seconds)
        w = np.linalg.norm(w_log.FindLog(simulator.get_context()).data().T, axis=1)
        v = v_log.FindLog(simulator.get_context()).data().T
        if what == "yaw rate":
            print(
                f"  yaw rate after {seconds:g} s  {w[-1]:.3f} rad/s; peak angular "
                f"acceleration {np.max(np.diff(w)) / h:.2f} rad/s²"
            )
        elif what == "sway speed":
            print(f"  sway speed after {seconds:g} s  {np.linalg.norm(v[-1]):.3f} m/s")
        else:
            a = np.linalg.norm(np.diff(v, axis=0), axis=1) / h
            print(
                f"  acceleration along body (1, 1, 0)/√2: {a[0]:.3f} m/s² over the first "
                f"period, {a[: round(0.1 / h)].mean():.3f} m/s² over 0.1 s (drag grows)"
            )


def closed_loop(steps: int, overrides: list[str]) -> None:
    """Prints the build, wall and CPU time of one closed-loop run of the paper scenario on the
    vehicle (``ClosedLoopSimulation``), with the run's vehicle metrics."""
    scenario = load_scenario("paper", ["plant=!HoveringAuv", f"steps={steps}", *overrides])
    start = time.perf_counter()
    simulation = ClosedLoopSimulation(scenario)
    built, cpu = time.perf_counter(), time.process_time()
    metrics = simulation.run().metrics
    wall, cpu = time.perf_counter() - built, time.process_time() - cpu
    print(
        f"closed loop, paper scenario on !HoveringAuv, {steps} steps "
        f"({steps * scenario.time_step:g} s), overrides {overrides or 'none'}"
    )
    print(f"  {'build_s':36s} {built - start:.4g}")
    print(f"  {'run_wall_s (target < 20)':36s} {wall:.4g}")
    print(f"  {'run_cpu_s':36s} {cpu:.4g}")
    for name in (
        "position_rmse",
        "nees_mean",
        "attitude_error_mean",
        "thrust_saturated_fraction",
        "model_acceleration_rmse",
    ):
        print(f"  {name:36s} {metrics[name]:.4g}")


def cpu_seconds(simulation: ClosedLoopSimulation) -> float:
    """The CPU time of one run of ``simulation`` at its scenario's seed."""
    start = time.process_time()
    simulation.run()
    return time.process_time() - start


def ratio(repeats: int) -> None:
    """Prints the hovering_auv run's cost over the paper's, per integrator and for the same loop
    on the kinematic plant, and the default integrator's largest position difference from RK5
    at accuracy 1e-8 (see the notes)."""
    paper = ClosedLoopSimulation(load_scenario("paper"))
    variants = {
        name: ClosedLoopSimulation(load_scenario("hovering_auv", overrides))
        for name, overrides in (
            ("hovering_auv, runge_kutta3 (default)", []),
            ("hovering_auv, runge_kutta5, accuracy 1e-6", ["plant.integrator=runge_kutta5"]),
            ("hovering_auv's loop on KinematicUuv", ["plant=KinematicUuv"]),
        )
    }
    for simulation in (paper, *variants.values()):
        simulation.run()  # warm-up: first-call costs out of the figures
    cpu = {name: [] for name in ("paper", *variants)}
    for _ in range(repeats):
        for name, simulation in (("paper", paper), *variants.items()):
            cpu[name].append(cpu_seconds(simulation))
    paper_cpu = np.array(cpu.pop("paper"))
    print(f"{repeats} interleaved runs each, CPU seconds per 500-step run (min, median)")
    print(f"  {'paper (kinematic)':44s} {paper_cpu.min():.3f}  {np.median(paper_cpu):.3f}")
    for name, seconds in cpu.items():
        seconds = np.array(seconds)
        print(
            f"  {name:44s} {seconds.min():.3f}  {np.median(seconds):.3f}  "
            f"ratio {np.median(seconds / paper_cpu):.2f} (target ≤ 5)"
        )
    errors(range(1))


def errors(seeds: range) -> None:
    """Prints, per seed of the hovering_auv run, how far the default fixed step and RK5 at the
    default accuracy 1e-6 are from RK5 at 1e-8: the largest distance between the vehicle
    positions, the change of the position RMSE and the largest relative change of a metric."""
    simulations = {
        name: ClosedLoopSimulation(load_scenario("hovering_auv", overrides))
        for name, overrides in (
            ("runge_kutta3", []),
            ("runge_kutta5 at 1e-6", ["plant.integrator=runge_kutta5"]),
            ("reference", ["plant.integrator=runge_kutta5", "plant.integrator_accuracy=1e-8"]),
        )
    }
    reference = simulations.pop("reference")
    worst = {name: np.zeros(3) for name in simulations}
    print("against runge_kutta5 at 1e-8: largest |Δp_WU| [m], Δ position_rmse [m], worst metric")
    for seed in seeds:
        truth = reference.run(seed=seed)
        for name, simulation in simulations.items():
            result = simulation.run(seed=seed)
            distance = np.linalg.norm(result.log["p_WU"] - truth.log["p_WU"], axis=1).max()
            relative = {
                key: abs(result.metrics[key] - value) / abs(value)
                for key, value in truth.metrics.items()
                if key != "wall_time_s" and isinstance(value, float) and value != 0.0
            }
            metric = max(relative, key=relative.get)
            rmse = result.metrics["position_rmse"] - truth.metrics["position_rmse"]
            figures = np.array([distance, abs(rmse), relative[metric]])
            worst[name] = np.maximum(worst[name], figures)
            print(
                f"  seed {seed} {name:22s} {distance:.2e}  {rmse:+.2e}  "
                f"{metric} {relative[metric]:.1e} relative"
            )
    for name, (distance, rmse, metric) in worst.items():
        print(
            f"  {name:30s} at most {distance:.2e} m, position RMSE {rmse:.1e} m, "
            f"a metric {metric:.1e} of its value (seeds {seeds.start}-{seeds.stop - 1})"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=500)
    parser.add_argument("--max-angular-rate", type=float, default=None)
    parser.add_argument("--acceleration", type=float, default=0.15, help="a [m/s²]")
    parser.add_argument("--speed", type=float, default=0.4, help="v [m/s]")
    parser.add_argument("--accuracy", type=float, default=None)
    parser.add_argument("--rate", type=float, default=None, help="controller rate [Hz]")
    parser.add_argument("--attitude-reference", choices=("trajectory", "step"), default=None)
    parser.add_argument("--figures", type=Path, default=None, help="directory for the figures")
    parser.add_argument("--sweep", action="store_true", help="rate limits × accelerations")
    parser.add_argument("--limits", action="store_true", help="derived limits, checked")
    parser.add_argument(
        "--closed-loop", action="store_true", help="time drake-uuv's closed loop on the vehicle"
    )
    parser.add_argument(
        "--ratio", action="store_true", help="hovering_auv run over the paper run, per integrator"
    )
    parser.add_argument("--repeats", type=int, default=5, help="interleaved runs for --ratio")
    parser.add_argument(
        "--errors", type=int, default=None, metavar="SEEDS", help="integrator errors, seeds 0.."
    )
    parser.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="FIELD=VALUE",
        help="scenario override for --closed-loop (repeatable)",
    )
    args = parser.parse_args()
    if args.ratio:
        ratio(args.repeats)
        return
    if args.errors is not None:
        errors(range(args.errors))
        return
    if args.closed_loop:
        closed_loop(args.steps, args.overrides)
        return
    # The figures read the motion between outer ticks: the continuous vehicle.
    config = HoveringAuv(integrator="runge_kutta5")
    if args.accuracy is not None:
        config.integrator_accuracy = args.accuracy
    if args.rate is not None:
        config.controller_rate = args.rate
    if args.attitude_reference is not None:
        config.attitude_reference = args.attitude_reference
    if args.limits:
        check_limits(config)
        return
    if args.sweep:
        print(f"{args.steps} steps, speed amplitude {args.speed} m/s; attitude error [rad]")
        print("max_rate  accel   err_mean  err_peak  scaled  peak_rate  peak_acc  cpu_s")
        for rate in (None, 1.0, 0.5, 0.3):
            for acceleration in (0.15, 0.5, 1.0):
                f, _, _ = run(config, args.steps, rate, acceleration, args.speed)
                print(
                    f"{rate!s:8s}  {acceleration:5.2f}  {f['attitude_error_mean_rad']:8.2e}  "
                    f"{f['attitude_error_peak_rad']:8.2e}  {f['scaled_fraction']:6.3f}  "
                    f"{f['peak_rate_rad_s']:9.2f}  {f['peak_acceleration_m_s2']:8.2f}  "
                    f"{f['cpu_s']:5.1f}"
                )
        return
    figures, log, fast_log = run(
        config, args.steps, args.max_angular_rate, args.acceleration, args.speed
    )
    print(
        f"{args.steps} outer steps ({args.steps * OUTER_PERIOD:g} s), controller "
        f"{config.controller_rate:g} Hz, RK5 accuracy {config.integrator_accuracy:g}, "
        f"attitude reference {config.attitude_reference}, max angular rate "
        f"{args.max_angular_rate}, acceleration amplitude {args.acceleration} m/s², speed "
        f"amplitude {args.speed} m/s"
    )
    for name, value in figures.items():
        print(f"  {name:36s} {value:.4g}")
    if args.figures is not None:
        # The figures read the window's start and the thrust limit from a scenario.
        scenario = dataclasses.replace(
            load_scenario("paper", ["steady_state_start=0"]), plant=config
        )
        save_figure(
            attitude_tracking_figure(log, scenario), args.figures / "vehicle_attitude", ("png",)
        )
        save_figure(thrust_figure(fast_log, scenario), args.figures / "vehicle_thrusts", ("png",))
        print(f"  figures in {args.figures}/")


if __name__ == "__main__":
    main()
