"""What a study's process pool costs besides the runs: start-up and pickling, by worker count.

Three figures for each worker count (default 2 and 16; more workers than cores is what a
laptop user's ``--workers 16`` gives on a small machine, and what a 16-core machine pays):

* **start-up**: the forked pool (:func:`drake_uuv.studies.execution.execute_local`) running
  one one-step run per worker, minus the same runs in this process: forking, the worker
  initializer, each worker's first diagram build and the result's trip back;
* **pickling**: one task (index, scenario, a chunk of 25 seeds) pickled and unpickled, and
  one chunk's result (the metrics and norms of 25 runs of the paper scenario);
* each the fastest of repeated calls (the machine's noise only ever adds);
* their share of a 200-run paper study on this machine (its runs' time from one worker).

    python benchmarks/bench_pool.py                    # 2 and 16 workers
    python benchmarks/bench_pool.py --workers 2 4 8 16
"""

import argparse
import pickle
import time

from profile_loop import best_of  # this folder's loop profiler (the script's own folder)

from drake_uuv.scenario import load_scenario
from drake_uuv.studies.execution import default_workers, execute_local
from drake_uuv.studies.runner import run_task

CHUNK = 25  # seeds per task: the automatic chunk size's cap


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, nargs="+", default=[2, 16])
    args = parser.parse_args()

    paper = load_scenario("paper")
    one_step = load_scenario("paper", ["steps=1", "steady_state_start=0"])
    print(f"{default_workers()} cores available")

    task = (0, paper, list(range(CHUNK)))
    start = time.perf_counter()
    result = run_task(task)
    per_run = (time.perf_counter() - start) / CHUNK
    for name, value in (("task", task), ("result", result)):
        data = pickle.dumps(value)
        seconds = best_of(lambda v=value: pickle.loads(pickle.dumps(v)), repeats=20)
        print(f"pickling one {name} ({CHUNK} seeds): {len(data) / 1024:6.1f} KiB, "
              f"{1e3 * seconds:5.2f} ms there and back")  # fmt: skip
    study = 200 * per_run
    print(f"one paper run: {1e3 * per_run:.1f} ms; a 200-run study's runs: {study:.2f} s of CPU")

    def done(index: int, chunk: dict) -> None:
        pass

    for workers in args.workers:
        tasks = [(i, one_step, [i]) for i in range(workers)]
        serial = best_of(lambda t=tasks: execute_local(t, 1, done))
        pooled = best_of(lambda t=tasks, w=workers: execute_local(t, w, done))
        startup = pooled - serial
        share = startup / (study / min(workers, default_workers()) + startup)
        print(f"workers {workers:2d}: pool start-up {1e3 * startup:6.1f} ms "
              f"({1e3 * startup / workers:5.1f} ms a worker), "
              f"{share:.1%} of a 200-run study's wall time on this machine")  # fmt: skip


if __name__ == "__main__":
    main()
