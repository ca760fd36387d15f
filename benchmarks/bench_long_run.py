"""A long paper-scenario run: no NaN or Inf, bounded error, orthonormal attitude, flat memory.

    python benchmarks/bench_long_run.py [--steps 100000] [--set tracking=!LqrTracking ...]

Prints the error over successive windows (it must not grow), the largest attitude
orthonormality error, and the resident memory against the size of the logs: the loggers are
the only thing that may grow with the run length.
"""

import argparse
import resource
import time

import numpy as np

from drake_uuv import ClosedLoopSimulation, load_scenario
from drake_uuv.metrics import errors


def rss_mb() -> float:
    """Peak resident memory of this process [MB] (Linux reports kB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=100_000)
    parser.add_argument("--set", dest="overrides", action="append", default=[])
    args = parser.parse_args()
    scenario = load_scenario(
        "paper", [f"steps={args.steps}", "steady_state_start=200", *args.overrides]
    )
    simulation = ClosedLoopSimulation(scenario)
    simulation.run(seed=1, realtime_rate=0.0)  # warm up with the same length: peak RSS settles
    before = rss_mb()
    start = time.perf_counter()
    result = simulation.run(seed=0)
    wall = time.perf_counter() - start
    after = rss_mb()
    log = result.log
    log_mb = sum(v.nbytes for v in log.values()) / 1e6

    finite = all(np.all(np.isfinite(v)) for k, v in log.items() if k not in ("nis",))
    e = errors(log, scenario)
    position = np.linalg.norm(e["position"], axis=1)
    tracking = np.linalg.norm(e["tracking"], axis=1)
    R = log["R_WB"]
    orthonormality = np.max(np.abs(np.einsum("kji,kjl->kil", R, R) - np.eye(3)))

    print(f"{args.steps} steps ({' '.join(args.overrides) or 'paper scenario'}), seed 0")
    print(f"  wall time            : {wall:.1f} s ({wall / args.steps * 1e6:.0f} us/step)")
    print(f"  all logged values finite: {finite}")
    print(f"  max |R^T R - I|      : {orthonormality:.2e}")
    windows = np.array_split(np.arange(scenario.steady_state_start, args.steps), 10)
    print("  position RMSE by tenth of the run [m]:")
    print("   ", " ".join(f"{np.sqrt(np.mean(position[w] ** 2)):.3f}" for w in windows))
    print("  tracking RMSE by tenth of the run [m]:")
    print("   ", " ".join(f"{np.sqrt(np.mean(tracking[w] ** 2)):.3f}" for w in windows))
    print(f"  max position error after k=200: {position[200:].max():.3f} m")
    speed = np.linalg.norm(e["relative_velocity"], axis=1)
    print(f"  |relative velocity| first/last tenth: {speed[windows[0]].mean():.1f} / "
          f"{speed[windows[-1]].mean():.1f} m/s")  # fmt: skip
    print(f"  peak RSS before/after the measured run: {before:.0f} / {after:.0f} MB "
          f"(logs of one run: {log_mb:.0f} MB)")  # fmt: skip


if __name__ == "__main__":
    main()
