"""How far the sonar's interpolation between ticks puts a ping from the hovering UUV's truth.

    python benchmarks/bench_ping_interpolation.py [--steps 500] [--offset 0.25] [--seed 1]

The sonar computes a ping between ticks from the two ticks' states (cubic Hermite positions,
geodesic attitude: :mod:`drake_uuv.models.ping_geometry`), which is exact for the kinematic
plant and the target but not for the hovering UUV, a continuous plant. This runs the flyable
configuration (the vehicle study's ``feasible`` overrides) on ``!HoveringAuv`` (its continuous
vehicle, ``plant.integrator=runge_kutta5``) with sonar 2 pinging ``--offset`` seconds after
each tick (``sonar.ping_offsets=[0, τ]``), stops the simulator at every ping time to read the
vehicle's true state there, and prints the largest
differences over the run between the sonar's ping (its logged ``p_TS_W``) and that truth:
the sonar's position [m], the attitude [rad] and the range [m]. The target's position at the
ping is its constant-acceleration formula (exact: its acceleration is held over a step).

Stopping at the ping times barely moves the trajectory (the low-level controller's ticks,
every 0.05 s, already stop the integrator there): printed, the largest difference of the
logged vehicle position from the same run without stops.
"""

import argparse
import importlib
from pathlib import Path

import numpy as np
from pydrake.systems.analysis import Simulator

from drake_uuv import ClosedLoopSimulation, load_scenario
from drake_uuv.models.ping_geometry import interpolate_attitude
from drake_uuv.models.so3 import log_so3
from drake_uuv.simulation import log_from_loggers
from drake_uuv.studies import load_studies


def feasible_overrides() -> list[str]:
    """The flyable configuration: the vehicle study's ``feasible`` overrides (the LQR loop the
    vehicle can fly and its angular-rate limit), read from the repository's ``studies/``."""
    studies = load_studies(Path(__file__).resolve().parents[1] / "studies")
    vehicle = importlib.import_module(f"{studies.__name__}.vehicle")
    return [*vehicle.VEHICLE_LOOP, f"attitude.max_angular_rate={vehicle.VEHICLE_ANGULAR_RATE}"]


def run_with_stops(
    simulation: ClosedLoopSimulation, seed: int, offset: float
) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray]:
    """The run's log, and the vehicle's true ``p_WU`` and ``R_WB`` at each ping time
    ``k t + offset`` (k = 0 … N − 2), read with the simulator stopped there."""
    scenario, built = simulation.scenario, simulation.built
    t, steps = scenario.time_step, scenario.steps
    simulator = Simulator(built.diagram)
    built.systems["uuv"].configure_simulator(simulator)
    context = simulator.get_mutable_context()
    built.set_random_context(context, seed)
    simulator.Initialize()
    uuv = built.systems["uuv"]
    uuv_context = uuv.GetMyContextFromRoot(context)
    positions, attitudes = [], []
    for k in range(steps - 1):
        simulator.AdvanceTo(k * t + offset)
        positions.append(np.array(uuv.GetOutputPort("p_WU").Eval(uuv_context)))
        attitudes.append(np.array(uuv.GetOutputPort("R_WB").Eval(uuv_context)).reshape(3, 3))
    simulator.AdvanceTo((steps - 1) * t)
    return log_from_loggers(built, context, steps), np.array(positions), np.array(attitudes)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--steps", type=int, default=500)
    parser.add_argument("--offset", type=float, default=0.25)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    # The continuous vehicle (runge_kutta5): the truth is read between ticks, where the
    # default stepped plant's outputs do not move.
    overrides = [
        "plant=!HoveringAuv",
        "plant.integrator=runge_kutta5",
        f"sonar.ping_offsets=[0.0, {args.offset}]",
    ]
    scenario = load_scenario("paper", [*feasible_overrides(), *overrides, f"steps={args.steps}"])
    simulation = ClosedLoopSimulation(scenario)
    log, p_WU, R_WB = run_with_stops(simulation, args.seed, args.offset)
    t, tau, b = scenario.time_step, args.offset, np.asarray(scenario.sonar.baseline)

    # Sonar 2's ping of step k arrives at tick k + 1; its true geometry at k t + τ.
    a_T = np.diff(log["v_WT"], axis=0) / t
    p_WT = log["p_WT"][:-1] + tau * log["v_WT"][:-1] + 0.5 * tau * tau * a_T
    p_TS_true = p_WU - 0.5 * R_WB @ b - p_WT
    p_TS_ping = log["p_TS_W"][1:, 3:]
    position = np.linalg.norm(p_TS_ping - p_TS_true, axis=1)
    ranges = np.abs(np.linalg.norm(p_TS_ping, axis=1) - np.linalg.norm(p_TS_true, axis=1))
    R_ping = [
        interpolate_attitude(log["R_WB"][k], log["R_WB"][k + 1], tau / t) for k in range(len(R_WB))
    ]
    angle = [np.linalg.norm(log_so3(R @ R_true.T)) for R, R_true in zip(R_ping, R_WB, strict=True)]
    plain = simulation.run(args.seed).log
    print(f"hovering UUV, feasible configuration, {args.steps} steps, seed {args.seed}, "
          f"ping {tau:g} s after the tick")  # fmt: skip
    print(f"  sonar position error  max {position.max():.3g} m, RMS "
          f"{np.sqrt(np.mean(position**2)):.3g} m")  # fmt: skip
    print(f"  attitude error        max {max(angle):.3g} rad")
    print(f"  range error           max {ranges.max():.3g} m, RMS "
          f"{np.sqrt(np.mean(ranges**2)):.3g} m")  # fmt: skip
    print(f"  the stops moved the logged p_WU by at most "
          f"{np.abs(plain['p_WU'] - log['p_WU']).max():.3g} m")  # fmt: skip


if __name__ == "__main__":
    main()
