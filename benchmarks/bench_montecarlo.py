"""Monte Carlo throughput: runs per second of the paper scenario with 1 and 2 workers.

Times :func:`drake_uuv.studies.run_study` end to end (pool start-up, one diagram build per
worker, every run, the per-chunk files on disk, runs.csv and summary.json; not the band
figure), in a temporary folder. The project's targets on a 2-core machine: 1000 runs of the
500-step paper scenario in under 60 s, and a 200-run study (``drake-uuv montecarlo --runs 200``,
its band figure included) in at most 5 s, which is 25 ms a run per core.

    python benchmarks/bench_montecarlo.py                 # 1000 runs, 1 and 2 workers
    python benchmarks/bench_montecarlo.py --runs 200 --workers 2
"""

import argparse
import json
import tempfile
import time
from pathlib import Path

from drake_uuv.scenario import load_scenario
from drake_uuv.studies import Study, default_workers, run_study

TARGET_RUNS = 1000
TARGET_SECONDS = 60.0
STUDY_RUNS, STUDY_SECONDS = 200, 5.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=TARGET_RUNS, help="runs per measurement")
    parser.add_argument(
        "--workers", type=int, nargs="+", default=[1, 2], help="worker counts to time"
    )
    parser.add_argument("--scenario", default="paper")
    parser.add_argument("--set", dest="overrides", action="append", default=[])
    args = parser.parse_args()

    scenario = load_scenario(args.scenario, args.overrides)
    print(
        f"{args.runs} runs of {scenario.steps} steps ({args.scenario}), "
        f"{default_workers()} cores available"
    )
    summaries = {}
    results = []
    for workers in args.workers:
        with tempfile.TemporaryDirectory() as folder:
            study = Study("bench", scenario, args.runs, Path(folder))
            start = time.perf_counter()
            result = run_study(study, workers=workers, progress=False, figures=False)
            seconds = time.perf_counter() - start
        rate = args.runs / seconds
        projected = TARGET_RUNS / rate
        results.append((workers, seconds, rate, projected))
        summaries[workers] = json.dumps(result.summary, sort_keys=True)
        print(
            f"workers {workers}: {seconds:6.1f} s, {rate:6.2f} runs/s, "
            f"{1000 * seconds * workers / args.runs:6.1f} ms per run per worker, "
            f"{TARGET_RUNS} runs ≈ {projected:5.1f} s "
            f"({'meets' if projected < TARGET_SECONDS else 'misses'} the {TARGET_SECONDS:.0f} s "
            "target)"
        )
    workers, seconds, rate, _ = results[-1]
    print(
        f"{STUDY_RUNS}-run study at {workers} workers ≈ {STUDY_RUNS / rate:5.1f} s "
        f"({STUDY_RUNS / rate / STUDY_SECONDS:.2f}x the {STUDY_SECONDS:.0f} s target; "
        "the figure and the process start not included)"
    )
    if len(results) > 1:
        base = results[0]
        for workers, _, rate, _ in results[1:]:
            print(f"speed-up {base[0]} → {workers} workers: {rate / base[2]:.2f}×")
        identical = len(set(summaries.values())) == 1
        print(f"summary.json identical across worker counts: {identical}")


if __name__ == "__main__":
    main()
