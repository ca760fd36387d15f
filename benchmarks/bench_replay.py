"""What a replay costs against the run that made its recording.

Runs a scenario, records it (``drake_uuv.recordings.record_run``: a ROS 2 MCAP bag) and
replays the bag through the same scenario's estimator (``drake_uuv.recordings.replay``:
reading the bag, the replay diagram, its metrics), each timed as the best of ``--runs`` in one
warm process (the first of each, which compiles and caches, untimed). Target: a replay of a
500-step recording within 1.5× of the run; it also prints how far the replay's filtered
estimates are from the run's.

    python benchmarks/bench_replay.py [--runs 3] [--scenario paper] [--set estimator=Ekf]
"""

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from drake_uuv.recordings import record_run, replay
from drake_uuv.scenario import load_scenario
from drake_uuv.simulation import ClosedLoopSimulation

TARGET_RATIO = 1.5


def measure(scenario_name: str, overrides: list[str], runs: int) -> dict[str, float]:
    """The best run and replay times [s], their ratio and the largest estimate difference."""
    scenario = load_scenario(scenario_name, overrides)
    simulation = ClosedLoopSimulation(scenario)
    result = simulation.run()
    run_times, replay_times = [], []
    with tempfile.TemporaryDirectory() as folder:
        bag = record_run(Path(folder) / "bag", result.log, scenario)
        replayed = replay(bag, scenario)
        for _ in range(runs):
            start = time.perf_counter()
            result = simulation.run()
            run_times.append(time.perf_counter() - start)
            start = time.perf_counter()
            replayed = replay(bag, scenario)
            replay_times.append(time.perf_counter() - start)
    difference = float(np.max(np.abs(replayed.log["x_TU_hat"] - result.log["x_TU_hat"])))
    run, again = min(run_times), min(replay_times)
    return {"run_s": run, "replay_s": again, "ratio": again / run, "difference": difference}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--scenario", default="paper")
    parser.add_argument("--set", dest="overrides", action="append", default=[])
    args = parser.parse_args()
    m = measure(args.scenario, args.overrides, args.runs)
    verdict = "within" if m["ratio"] <= TARGET_RATIO else "OVER"
    print(
        f"{args.scenario} {' '.join(args.overrides)}: run {m['run_s']:.3f} s, replay "
        f"{m['replay_s']:.3f} s = {m['ratio']:.2f}x ({verdict} {TARGET_RATIO}x); filtered "
        f"estimates differ by at most {m['difference']:.1e}"
    )


if __name__ == "__main__":
    main()
