"""The particle cloud's cost per run over a batch: B runs of N particles stepped by a Simulator.

The cloud sits on a minimal host (``tests/estimators/cloud_host.py``: its inputs fixed, so the
figure is the cloud's own, with Drake's copies of its discrete state and a logger of the
filtered estimate), each run weighed by both ranges every step, with the paper scenario's
step, target acceleration covariance and range noise. The ranges stay the same from step to
step, so the cloud resamples at nearly every step: the worst case (the paper's particle-filter
run resamples at 279 steps of 477). Prints the CPU time per step and per 500-step run, per run
of the batch, and the share of steps that resampled; ``--kernel range_bearing`` times the
regularisation kernel in range-bearing coordinates (its trigonometry on every resampling).

    PYTHONPATH=. python benchmarks/bench_particle_batch.py 1x5000 100x5000 1000x5000 100x20000
    PYTHONPATH=. python benchmarks/bench_particle_batch.py 100x5000 --kernel range_bearing
"""

import argparse
import time

import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput

from drake_uuv.models.particle_filter import KERNELS
from tests.estimators.cloud_host import CloudHost, run_inputs, run_states

# The paper scenario's step, target acceleration covariance and per-sonar range variance.
T = 0.5
W = np.diag([0.004, 0.001, 0.001])
R = np.diag([0.01, 0.01])


def measure(batch: int, count: int, steps: int, kernel: str = "cartesian") -> dict[str, float]:
    builder = DiagramBuilder()
    host = builder.AddSystem(
        CloudHost(
            count,
            batch_size=batch,
            time_step=T,
            acceleration_covariance=W,
            range_covariance=R,
            kernel=kernel,
        )  # fmt: skip
    )
    LogVectorOutput(host.GetOutputPort("x_hat"), builder, T)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    host_context = host.GetMyMutableContextFromRoot(context)
    for name, value in run_inputs(batch).items():
        host.GetInputPort(name).FixValue(host_context, np.asarray(value, dtype=float).ravel())
    for group, value in enumerate(run_states(batch, count, spread=0.5)):
        host_context.SetDiscreteState(group, np.asarray(value, dtype=float).ravel())
    simulator.Initialize()
    simulator.AdvanceTo(2 * T)  # compiled kernels loaded, caches warm
    resampled = 0
    start_cpu, start_wall = time.process_time(), time.perf_counter()
    for k in range(steps):
        simulator.AdvanceTo((k + 3) * T)
        weights = host.cloud.log_weights(host_context)
        resampled += int(np.count_nonzero(np.ptp(weights, axis=1) == 0.0))
    cpu, wall = time.process_time() - start_cpu, time.perf_counter() - start_wall
    return {
        "cpu_step_run_us": cpu / steps / batch * 1e6,
        "wall_step_run_us": wall / steps / batch * 1e6,
        "cpu_run_ms": cpu / steps / batch * 500 * 1e3,
        "resampled": resampled / steps / batch,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cases", nargs="*", default=["1x5000", "100x5000"], help="BxN")
    parser.add_argument("--steps", type=int, default=50)
    parser.add_argument("--kernel", choices=KERNELS, default="cartesian")
    args = parser.parse_args()
    for case in args.cases:
        batch, count = (int(v) for v in case.split("x"))
        figures = measure(batch, count, args.steps, args.kernel)
        print(
            f"{args.kernel}, B={batch:5d} N={count:6d}: "
            f"{figures['cpu_step_run_us']:7.1f} µs CPU a step a run "
            f"({figures['wall_step_run_us']:7.1f} wall), {figures['cpu_run_ms']:6.1f} ms CPU a "
            f"500-step run; resampled {figures['resampled']:.0%} of steps"
        )


if __name__ == "__main__":
    main()
