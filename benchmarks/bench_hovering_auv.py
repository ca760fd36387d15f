"""Wall time and tracking of the hovering UUV plant driven by a fixed outer-command pattern.

    python benchmarks/bench_hovering_auv.py [--steps 500] [--max-angular-rate 0.5]
        [--acceleration 0.15] [--accuracy 1e-6] [--attitude-reference step]

The outer commands at period t = 0.5 s are the paper's Algorithm 2 attitude plan (the
project's ``AttitudeGenerator``, optionally rate-limited) and a bounded world acceleration
``a_W(τ) = a [cos(2πτ/20), cos(2πτ/15), ½ cos(2πτ/10)]`` (sent as ``u1_B = R_WBᵀ a_W``), whose
velocity ``a [3.18, 2.39, 0.80] s`` stays under the vehicle's drag-limited speed (0.76 m/s in
sway) for the default ``a = 0.15 m/s²``. Prints the wall time of the
simulation alone and its CPU time (which a busy machine inflates less; target: under ~10 s
for 500 steps, so that a full closed loop stays under 20 s), and what the figures need: the attitude error at each outer tick against the target
``R(k+1) = Exp(u2 t) R(k)`` (mean, peak), the fraction of fast ticks at which the
allocation had to scale the wrench down or a thruster ran at its limit, and the peak
achieved angular rate and acceleration.
"""

import argparse
import math
import time

import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import BasicVector, Context, DiagramBuilder, LeafSystem
from pydrake.systems.primitives import LogVectorOutput

from drake_uuv.controllers.attitude_generator import AttitudeGenerator
from drake_uuv.plants.hovering_auv import HoveringAuvPlant, configure_simulator
from drake_uuv.plants.hovering_auv_config import HoveringAuv
from drake_uuv.so3 import log_so3

OUTER_PERIOD = 0.5
BASELINE = np.array([-1.0, 1.0, 0.0])


class BoundedAcceleration(LeafSystem):
    """``u1_B = R_WBᵀ a_W(kt)``, the pattern of the module notes (input ``R_WB``)."""

    def __init__(self, amplitude: float) -> None:
        super().__init__()
        self._amplitude = amplitude
        self._R = self.DeclareVectorInputPort("R_WB", 9)
        self.DeclareVectorOutputPort("u1_B", 3, self._calc)

    def world_acceleration(self, time: float) -> np.ndarray:
        return self._amplitude * np.array(
            [
                math.cos(2 * math.pi * time / 20.0),
                math.cos(2 * math.pi * time / 15.0),
                0.5 * math.cos(2 * math.pi * time / 10.0),
            ]
        )

    def _calc(self, context: Context, output: BasicVector) -> None:
        R = self._R.Eval(context).reshape(3, 3)
        output.set_value(R.T @ self.world_acceleration(context.get_time()))


def build(config: HoveringAuv, max_angular_rate: float | None, acceleration: float):
    """The plant, Algorithm 2 and the acceleration pattern, with loggers; returns the pieces."""
    builder = DiagramBuilder()
    plant = builder.AddNamedSystem(
        "uuv", HoveringAuvPlant(config, OUTER_PERIOD, np.zeros(3), np.zeros(3), np.zeros(3))
    )
    attitude = builder.AddNamedSystem(
        "attitude_generator",
        AttitudeGenerator(
            "trajectory", OUTER_PERIOD, BASELINE, max_angular_rate=max_angular_rate
        ),
    )
    accel = builder.AddNamedSystem("acceleration", BoundedAcceleration(acceleration))
    builder.Connect(plant.GetOutputPort("R_WB"), attitude.GetInputPort("R_WB"))
    builder.Connect(plant.GetOutputPort("R_WB"), accel.GetInputPort("R_WB"))
    builder.Connect(attitude.GetOutputPort("w_W"), plant.GetInputPort("u2_W"))
    builder.Connect(accel.GetOutputPort("u1_B"), plant.GetInputPort("u1_B"))
    h = plant.controller.period
    outer = {
        name: LogVectorOutput(plant.GetOutputPort(name), builder, OUTER_PERIOD)
        for name in ("R_WB", "R_WB_command", "w_WB_command")
    }
    fast = {
        name: LogVectorOutput(plant.GetOutputPort(name), builder, h)
        for name in ("thrust", "allocation_scale", "w_WB", "v_WU", "nu_B")
    }
    return builder.Build(), plant, outer, fast


def run(
    config: HoveringAuv, steps: int, max_angular_rate: float | None, acceleration: float
) -> dict[str, float]:
    """Simulates ``steps`` outer steps and returns the figures printed by ``main``."""
    start = time.perf_counter()
    diagram, plant, outer, fast = build(config, max_angular_rate, acceleration)
    simulator = Simulator(diagram)
    configure_simulator(simulator, config, OUTER_PERIOD)
    simulator.Initialize()
    built, cpu = time.perf_counter(), time.process_time()
    simulator.AdvanceTo(steps * OUTER_PERIOD)
    wall, cpu = time.perf_counter() - built, time.process_time() - cpu
    context = simulator.get_context()
    log = {name: logger.FindLog(context).data().T for name, logger in {**outer, **fast}.items()}
    # Row k of the outer logs is step k before its update: R_WB_command there is R(k) as
    # commanded at step k − 1, so row-by-row differences are the tracking error at each tick.
    errors = [
        np.linalg.norm(log_so3(c.reshape(3, 3) @ a.reshape(3, 3).T))
        for c, a in zip(log["R_WB_command"][1:], log["R_WB"][1:], strict=True)
    ]
    scale = log["allocation_scale"]
    h = plant.controller.period
    w = log["w_WB"]
    v = log["v_WU"]
    integrator = simulator.get_integrator()
    return {
        "wall_s": wall,
        "cpu_s": cpu,
        "build_s": built - start,
        "attitude_error_mean_rad": float(np.mean(errors)),
        "attitude_error_peak_rad": float(np.max(errors)),
        "scaled_fraction": float(np.mean(np.any(scale < 1.0 - 1e-12, axis=1))),
        "at_limit_fraction": float(
            np.mean(np.any(np.abs(log["thrust"]) >= config.max_thrust * (1 - 1e-9), axis=1))
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
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=500)
    parser.add_argument("--max-angular-rate", type=float, default=None)
    parser.add_argument("--acceleration", type=float, default=0.15)
    parser.add_argument("--accuracy", type=float, default=None)
    parser.add_argument("--rate", type=float, default=None, help="controller rate [Hz]")
    parser.add_argument("--attitude-reference", choices=("trajectory", "step"), default=None)
    args = parser.parse_args()
    config = HoveringAuv()
    if args.accuracy is not None:
        config.integrator_accuracy = args.accuracy
    if args.rate is not None:
        config.controller_rate = args.rate
    if args.attitude_reference is not None:
        config.attitude_reference = args.attitude_reference
    figures = run(config, args.steps, args.max_angular_rate, args.acceleration)
    print(
        f"{args.steps} outer steps ({args.steps * OUTER_PERIOD:g} s), controller "
        f"{config.controller_rate:g} Hz, RK5 accuracy {config.integrator_accuracy:g}, "
        f"attitude reference {config.attitude_reference}, max angular rate "
        f"{args.max_angular_rate}, acceleration amplitude {args.acceleration} m/s²"
    )
    for name, value in figures.items():
        print(f"  {name:36s} {value:.4g}")


if __name__ == "__main__":
    main()
