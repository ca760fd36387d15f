"""The cost a run of a study, as one diagram stepping a batch of runs, at several batch sizes.

For each configuration and batch size B it times ``ClosedLoopSimulation(scenario,
log="metrics", batch_size=B).run_batch(seeds)`` (the diagram built beforehand, as a study's
worker keeps it) and prints the wall time per run. For paper, ekf, particle_filter and
hovering_auv it also times a plain batched loop of the same arithmetic with no Drake
(``plain_loops.py`` beside this file: all B runs stepped at once, the plant's, target's and
sonars' noise drawn from the diagram's own per-run sources), interleaved with the diagram so
that both see the same machine, and prints their ratio: what the framework and the systems'
generality cost over the bare arithmetic. The plain loops of paper, ekf and particle_filter
are numpy (the particle filter's over runs × particles: the reference for what its compiled
kernels save, so its ratio is below 1); hovering_auv's calls the vehicle's own compiled
step. realistic has no plain loop (``-``): its late ranges are stepped through each run's
window of pings at their times, on 20 000 particles, which a plain loop would have to
reimplement whole.

``--check`` times nothing: it runs the diagram and each plain loop on the same seeds (100 by
default) and prints both mean position RMSEs and their paired difference. paper, ekf and
hovering_auv agree to rounding; the particle filter's own draws differ from the diagram's,
so it agrees within sampling error.

    python benchmarks/bench_batch.py                       # every configuration, B = 1..1000
    python benchmarks/bench_batch.py --configs paper --sizes 1 100 --steps 200
    python benchmarks/bench_batch.py --check --configs paper ekf hovering_auv particle_filter
"""

import argparse
import math
import time
from collections.abc import Callable

import numpy as np
from plain_loops import PLAIN_LOOPS  # beside this file
from threadpoolctl import threadpool_limits

from drake_uuv import ClosedLoopSimulation, load_scenario
from drake_uuv.scenario import Scenario

#: A plain loop: ``(scenario, seeds) -> each run's position RMSE``.
PlainLoop = Callable[[Scenario, np.ndarray], np.ndarray]

#: Configuration name → (scenario, overrides).
CONFIGS = {
    "paper": ("paper", []),
    "ekf": ("paper", ["estimator=Ekf"]),
    "hovering_auv": ("hovering_auv", []),
    "particle_filter": ("paper", ["estimator=ParticleFilter"]),
    "realistic": ("realistic", []),
}


def time_diagram(scenario: Scenario, batch_size: int, repeats: int) -> float:
    """Best wall time of ``repeats`` batches [s per run]."""
    simulation = ClosedLoopSimulation(scenario, log="metrics", batch_size=batch_size)
    seeds = np.arange(batch_size) + scenario.random_seed
    simulation.run_batch(seeds)  # warm: compiled kernels, first-call caches
    best = math.inf
    for _ in range(repeats):
        start = time.perf_counter()
        simulation.run_batch(seeds)
        best = min(best, time.perf_counter() - start)
    return best / batch_size


def time_plain(loop: PlainLoop, scenario: Scenario, batch_size: int, repeats: int) -> float:
    """Best wall time of ``repeats`` batches of the plain loop [s per run]."""
    seeds = np.arange(batch_size) + scenario.random_seed
    loop(scenario, seeds)  # warm: the noise's and the models' compiled kernels
    best = math.inf
    for _ in range(repeats):
        start = time.perf_counter()
        loop(scenario, seeds)
        best = min(best, time.perf_counter() - start)
    return best / batch_size


def check(name: str, scenario: Scenario, runs: int) -> None:
    """Prints the mean position RMSE of the diagram and of the plain loop over the same
    ``runs`` seeds, and their paired difference with its standard error (the same seeds:
    the same target and range noise wherever the loop draws what the diagram draws)."""
    seeds = np.arange(runs) + scenario.random_seed
    start = time.perf_counter()
    diagram = ClosedLoopSimulation(scenario, log="metrics", batch_size=runs).run_batch(seeds)
    diagram_rmse = diagram.metrics["position_rmse"]
    middle = time.perf_counter()
    plain = PLAIN_LOOPS[name](scenario, seeds)
    end = time.perf_counter()
    difference = plain - diagram_rmse
    error = np.nanstd(difference, ddof=1) / math.sqrt(np.isfinite(difference).sum())
    print(
        f"{name:<16} {runs:>5} {np.nanmean(diagram_rmse):>10.4f} {np.mean(plain):>10.4f} "
        f"{np.nanmean(difference):>+11.4f} {error:>9.4f} {np.nanmax(np.abs(difference)):>11.2e} "
        f"{diagram.failed.sum():>7} {middle - start:>8.1f} {end - middle:>8.1f}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--configs", nargs="+", default=list(CONFIGS), choices=list(CONFIGS))
    parser.add_argument("--sizes", nargs="+", type=int, default=[1, 10, 100, 1000])
    parser.add_argument(
        "--steps", type=int, default=None, help="steps a run (default: the scenario's)"
    )
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument(
        "--check",
        action="store_true",
        help="instead of timing, compare the diagram's and each plain loop's mean position "
        "RMSE over the same --check-runs seeds",
    )
    parser.add_argument("--check-runs", type=int, default=100)
    args = parser.parse_args()
    scenarios = {}
    for name in args.configs:
        base, overrides = CONFIGS[name]
        if args.steps is not None:
            overrides = [
                *overrides, f"steps={args.steps}", f"steady_state_start={args.steps // 2}"
            ]  # fmt: skip
        scenarios[name] = load_scenario(base, overrides)
    with threadpool_limits(limits=1, user_api="blas"):
        if args.check:
            print(
                f"{'configuration':<16} {'runs':>5} {'diagram m':>10} {'plain m':>10} "
                f"{'plain-diag':>11} {'std err':>9} {'max |diff|':>11} {'failed':>7} "
                f"{'diag s':>8} {'plain s':>8}"
            )
            for name, scenario in scenarios.items():
                if name in PLAIN_LOOPS:
                    check(name, scenario, args.check_runs)
            return
        print(
            f"{'configuration':<16} {'B':>5} {'diagram ms/run':>15} {'plain ms/run':>13} "
            f"{'ratio':>6}"
        )
        for name, scenario in scenarios.items():
            loop = PLAIN_LOOPS.get(name)
            for B in args.sizes:
                try:
                    diagram = time_diagram(scenario, B, args.repeats)
                except Exception as e:  # a configuration whose systems cannot batch yet
                    print(f"{name:<16} {B:>5} {'-':>15}   ({type(e).__name__}: {str(e)[:80]})")
                    continue
                if loop is None:
                    print(f"{name:<16} {B:>5} {1e3 * diagram:>15.2f} {'-':>13} {'-':>6}")
                    continue
                plain = time_plain(loop, scenario, B, args.repeats)
                print(
                    f"{name:<16} {B:>5} {1e3 * diagram:>15.2f} {1e3 * plain:>13.2f} "
                    f"{diagram / plain:>6.2f}"
                )


if __name__ == "__main__":
    main()
