"""Cost of the particle filter: 500-step paper runs in the Drake loop, and the numpy steps.

For each particle count, builds the closed loop with ``estimator=!ParticleFilter`` once and
times ``--runs`` seeded runs (simulation and metrics, ``wall_time_s`` as ``drake-uuv run``
reports it), interleaved with the same seeds' runs of the paper's KF loop, and prints the
ratio PF/KF of each pair (min and median): the target is 3× or less at the default count
(5000). Then it times the two numpy steps alone (:func:`pf_update`, the filtered output, and
:func:`pf_predict` with resampling, the periodic update) on a cloud of that size.

    python benchmarks/bench_particle_filter.py [--counts 1000 5000 20000 50000] [--runs 5]
"""

import argparse
import math
import statistics
import time

import numpy as np

from drake_uuv.models.motion import double_integrator
from drake_uuv.models.particle_filter import (
    ParticleFilterParameters,
    initial_particles,
    pf_predict,
    pf_update,
)
from drake_uuv.scenario import load_scenario
from drake_uuv.simulation import ClosedLoopSimulation


def numpy_step_ms(count: int, repeats: int = 20) -> tuple[float, float]:
    """Milliseconds of one update and one predict (resampling every time) for ``count``."""
    rng = np.random.default_rng(0)
    A, B = double_integrator(0.5)
    W = np.diag([0.004, 0.001, 0.001])
    x = np.array([-2.0, -2.0, 0.3, 0.0, 0.0, 0.0])
    particles = initial_particles(x, np.diag([0.1, 0.1, 0.1, 0.01, 0.01, 0.01]), count, rng)
    log_w = np.full(count, -math.log(count))
    q_s = np.array([-1.0, 1.0, 0.0])
    z = np.array([np.linalg.norm(x[:3] + q_s / 2), np.linalg.norm(x[:3] - q_s / 2)])
    R = np.diag([0.01, 0.01])
    params = ParticleFilterParameters(count=count, resample_threshold=1.0)
    start = time.perf_counter()
    for _ in range(repeats):
        *_, log_post = pf_update(particles, log_w, z, q_s, R)
    middle = time.perf_counter()
    for _ in range(repeats):
        pf_predict(particles, log_post, np.zeros(3), A, B, W, rng, params)
    end = time.perf_counter()
    return (middle - start) / repeats * 1e3, (end - middle) / repeats * 1e3


def run_seconds(simulation: ClosedLoopSimulation, seed: int) -> tuple[float, float]:
    """Wall seconds of one seeded run (simulation and metrics) and its position RMSE."""
    metrics = simulation.run(seed).metrics
    return metrics["wall_time_s"], metrics["position_rmse"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--counts", type=int, nargs="+", default=[1000, 5000, 20000, 50000])
    parser.add_argument("--runs", type=int, default=5)
    args = parser.parse_args()
    kf = ClosedLoopSimulation(load_scenario("paper"))
    run_seconds(kf, 0)  # the first run of a diagram pays for its first allocations
    print(
        f"{'count':>7} {'KF [s]':>7} {'PF [s]':>7} {'PF/KF min':>10} {'median':>7} "
        f"{'RMSE [m]':>9} {'update [ms]':>12} {'predict [ms]':>13}"
    )
    for count in args.counts:
        scenario = load_scenario(
            "paper", ["estimator=!ParticleFilter", f"estimator.particle_count={count}"]
        )
        simulation = ClosedLoopSimulation(scenario)
        run_seconds(simulation, 0)
        kf_walls, pf_walls, ratios, rmse = [], [], [], []
        for seed in range(1, args.runs + 1):
            kf_wall, _ = run_seconds(kf, seed)
            pf_wall, pf_rmse = run_seconds(simulation, seed)
            kf_walls.append(kf_wall)
            pf_walls.append(pf_wall)
            ratios.append(pf_wall / kf_wall)
            rmse.append(pf_rmse)
        update, predict = numpy_step_ms(count)
        print(
            f"{count:7d} {statistics.median(kf_walls):7.3f} {statistics.median(pf_walls):7.3f} "
            f"{min(ratios):10.2f} {statistics.median(ratios):7.2f} {np.mean(rmse):9.3f} "
            f"{update:12.2f} {predict:13.2f}",
            flush=True,
        )


if __name__ == "__main__":
    main()
