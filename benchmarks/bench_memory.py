"""What a built closed loop keeps in memory after it is dropped, per configuration.

pydrake 1.51 never frees a LeafSystem written in Python: the callbacks it stores in C++ (a
port's calc, an event's handler, a cache entry's producer) hold the system, a cycle Python's
collector cannot see (RobotLocomotion/drake issues 23930 and 24162). So every
``ClosedLoopSimulation`` built stays in the process's memory, its batch's declared state with
it. A study's local pool bounds what a worker keeps by replacing its workers
(``drake_uuv.studies.execution.TASKS_PER_WORKER``); a long-lived process (a notebook, a Dask
worker, ``--workers 1``) keeps every one it builds.

For each configuration this builds the loop ``--builds`` times at its study batch size
(:func:`drake_uuv.studies.runner.max_batch_size`), dropping each and collecting garbage, and
prints the resident memory kept per build and whether the dropped diagram is still alive.
A pydrake that frees Python systems prints about 0 MB and ``False``.

    python benchmarks/bench_memory.py
    python benchmarks/bench_memory.py --builds 5 --configs paper late_pf
"""

import argparse
import gc
import weakref

from drake_uuv.scenario import load_scenario
from drake_uuv.simulation import ClosedLoopSimulation
from drake_uuv.studies.runner import max_batch_size

LATE = ["sonar.latency=0.2", "estimator.vehicle_motion=navigation"]
CONFIGS = {
    "paper": ("paper", []),
    "ekf": ("paper", ["estimator=Ekf"]),
    "late_pf": ("paper", ["estimator=ParticleFilter", *LATE]),
    "hovering_auv": ("hovering_auv", []),
}


def resident_mb() -> float:
    """This process's resident memory now [MB] (Linux)."""
    with open("/proc/self/status") as status:
        line = next(line for line in status if line.startswith("VmRSS"))
    return int(line.split()[1]) / 1024


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--configs", nargs="+", choices=list(CONFIGS), default=list(CONFIGS))
    parser.add_argument("--builds", type=int, default=4)
    args = parser.parse_args()
    print("configuration  batch  MB kept a build  diagram alive after drop")
    for name in args.configs:
        base, overrides = CONFIGS[name]
        scenario = load_scenario(base, overrides)
        batch = max_batch_size(scenario)
        # The first build also loads modules and kernels: measure from the second on.
        ClosedLoopSimulation(scenario, log="metrics", batch_size=batch)
        gc.collect()
        before = resident_mb()
        for _ in range(args.builds):
            simulation = ClosedLoopSimulation(scenario, log="metrics", batch_size=batch)
            alive = weakref.ref(simulation.diagram)
            del simulation
            gc.collect()
        kept = (resident_mb() - before) / args.builds
        print(f"{name:13s} {batch:6d}  {kept:15.0f}  {alive() is not None}")


if __name__ == "__main__":
    main()
