"""The results pages' cost at their counts: every study they run, timed on a sample of its seeds.

``scripts/make_results_page.py --runs R`` runs the paper's Monte Carlo and every group of the
repository's ``studies/`` folder, each row its share of ``R`` runs (``studies/shares.py``).
This script times each of those studies at full length on a sample of its own first seeds,
as a study runs them (:func:`drake_uuv.studies.runner.run_seeds`, its diagram built and its
kernels loaded by a short run beforehand), and scales by the row's count. The sample:
``--sample`` runs (12); a row under 1 s a run is timed again on 40, and a row under 50 ms on
a whole chunk (up to 250 runs, the batch a study steps), since its cost a run falls with the
batch. It prints each row, then the CPU minutes by section and the wall time on ``--workers``
cores (what parallel workers lose to each other and the pages' single runs and figures are
not counted).

A row's cost depends on what its runs do, not only on its configuration (a run the paper's
law loses with late ranges keeps its particle bridge live), which is why each row is timed,
where ``drake-uuv compare`` estimates from one sample per configuration.

    python benchmarks/bench_results_pages.py                       # every row, about 25 min
    python benchmarks/bench_results_pages.py --group navigation    # one section
"""

import argparse
import dataclasses
import json
import multiprocessing
import time
from collections import defaultdict
from pathlib import Path

from drake_uuv.scenario import Scenario, load_scenario
from drake_uuv.studies import default_workers, group_variants, load_groups, variant_studies
from drake_uuv.studies.runner import cached_simulation, max_batch_size, run_seeds

STUDIES = Path(__file__).resolve().parent.parent / "studies"
MONTE_CARLO = "paper-montecarlo"
# Rows cheaper than these [s a run] are timed again on a larger sample.
CHEAP, SUB_SECOND = 0.05, 1.0
LARGER_SAMPLE, CHUNK = 40, 250
# Steps of the short run that loads a row's kernels before it is timed.
WARM_STEPS = 60
# Studies a worker process times before a fresh one takes over: pydrake never frees a
# LeafSystem written in Python, so each diagram built stays in the worker's memory.
STUDIES_PER_PROCESS = 8


def page_studies(runs: int, groups: list[str] | None) -> list[tuple[str, str, Scenario, int]]:
    """``(section, row, scenario, runs)`` of every study the pages run at ``runs``."""
    rows = []
    if not groups or MONTE_CARLO in groups:
        rows.append((MONTE_CARLO, "paper", load_scenario("paper"), runs))
    for name, group in load_groups(STUDIES).items():
        if groups and name not in groups:
            continue
        for study in variant_studies(group_variants([group]), Path("unused"), runs):
            rows.append((name, study.name, study.scenario, study.runs))
    return rows


def seconds_a_run(task: tuple[str, str, Scenario, int, int]) -> tuple[str, str, float, int, int]:
    """The row's wall seconds a run on its sample, and the sample's size."""
    section, row, scenario, runs, sample = task

    # The kernels' first call in a process loads (or, after a source changed, compiles) them:
    # a short run first, so that no row is charged for it.
    warm = dataclasses.replace(scenario, steps=WARM_STEPS, steady_state_start=WARM_STEPS - 1)
    run_seeds(warm, [warm.random_seed, warm.random_seed + 1])

    def timed(count: int) -> float:
        seeds = list(range(scenario.random_seed, scenario.random_seed + count))
        cached_simulation(scenario, min(count, max_batch_size(scenario)))  # built, not timed
        start = time.perf_counter()
        run_seeds(scenario, seeds)
        return (time.perf_counter() - start) / count

    count = min(runs, sample)
    cost = timed(count)
    if runs > count and cost < CHEAP:
        count = min(runs, CHUNK, max_batch_size(scenario))
        cost = timed(count)
    elif runs > count and cost < SUB_SECOND:
        count = min(runs, LARGER_SAMPLE)
        cost = timed(count)
    return section, row, cost, count, runs


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=1000, help="runs per kinematic row")
    parser.add_argument("--sample", type=int, default=12, help="first sample of each row")
    parser.add_argument("--workers", type=int, default=default_workers())
    parser.add_argument(
        "--group", dest="groups", action="append", help=f"a section (a group, or {MONTE_CARLO})"
    )
    parser.add_argument("--json", type=Path, help="write the rows' figures here")
    args = parser.parse_args()
    if args.runs < 1 or args.sample < 1 or args.workers < 1:
        parser.error(
            f"--runs, --sample and --workers must be ≥ 1, got {args.runs}, {args.sample}, "
            f"{args.workers}"
        )
    known = [MONTE_CARLO, *load_groups(STUDIES)]
    unknown = sorted(set(args.groups or ()) - set(known))
    if unknown:
        parser.error(f"--group: unknown {unknown} (known: {known})")

    tasks = [(*row, args.sample) for row in page_studies(args.runs, args.groups)]
    print(f"{len(tasks)} studies, {sum(t[3] for t in tasks)} runs, {args.workers} workers")
    results = []
    context = multiprocessing.get_context("spawn")  # a fresh interpreter, no inherited diagram
    with context.Pool(args.workers, maxtasksperchild=STUDIES_PER_PROCESS) as pool:
        for section, row, cost, count, runs in pool.imap_unordered(seconds_a_run, tasks):
            results.append((section, row, cost, count, runs))
            print(
                f"{section + ':' + row:60s} {cost * 1e3:9.1f} ms a run (of {count:3d}) × "
                f"{runs:5d} = {cost * runs / 60:6.1f} min",
                flush=True,
            )
    by_section: dict[str, float] = defaultdict(float)
    for section, _, cost, _, runs in results:
        by_section[section] += cost * runs / 60
    print("\nsection                 CPU min")
    for section, minutes in sorted(by_section.items(), key=lambda item: -item[1]):
        print(f"{section:22s} {minutes:8.1f}")
    total = sum(by_section.values())
    print(f"{'all':22s} {total:8.1f}: {total / args.workers:.0f} min on {args.workers} cores")
    if args.json:
        rows = {f"{s}:{r}": {"seconds_a_run": c, "sample": n, "runs": k}
                for s, r, c, n, k in results}  # fmt: skip
        args.json.write_text(json.dumps(rows, indent=1, sort_keys=True))


if __name__ == "__main__":
    main()
