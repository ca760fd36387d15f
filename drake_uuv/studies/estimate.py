"""How long a batch of studies will take, from the measured cost of one run.

A run's cost is set by its configuration (:func:`configuration`): the plant, estimator and
attitude variants, the particle count, the number of steps and whether the estimator takes
late ranges (a particle filter or the hovering UUV costs ten to a hundred times the paper's
kinematic loop with its KF, and late ranges, which step each particle through the window of
ranges still in flight, several times a particle filter without them: 0.3-1.0 s a run against
0.2-0.3 s in the navigation study, ``benchmarks/PROFILE.md``; the rest of a variant's settings
costs little). :func:`estimate_wall_time` times two short batches of each
distinct configuration among the runs still to compute, as a study runs them
(:func:`~drake_uuv.studies.runner.run_seeds`, its diagram built; :func:`time_one_run`), and
scales:
the wall time is Σ over configurations of (one run's seconds × its runs), divided by the
workers (at most one per run). It ignores what parallel workers lose to each other (about 13 %
on two cores, ``benchmarks/bench_montecarlo.py``) and the spread of run times across seeds.
"""

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from time import perf_counter

from drake_uuv.estimators.factory import estimator_setting
from drake_uuv.scenario import Scenario, scenario_as_dict
from drake_uuv.studies.runner import max_batch_size, run_seeds
from drake_uuv.studies.storage import missing_seeds
from drake_uuv.studies.study import Study

# plant, estimator, particle count ("" without particles), attitude, steps, late ranges.
Configuration = tuple[str, str, str, str, int, bool]


def configuration(scenario: Scenario) -> Configuration:
    """What sets the cost of a run of ``scenario`` (see the module). Late ranges: the sonars'
    ranges arrive after their tick (``sonar.ping_offsets``, ``sonar.latency``) and the
    estimator models that (``error_model: modelled``)."""
    settings = scenario_as_dict(scenario)
    estimator = settings["estimator"]
    particles = estimator.get("particle_count")
    schedule = estimator_setting(scenario).ping_schedule
    late = not schedule.immediate and estimator.get("error_model") == "modelled"
    return (
        settings["plant"]["variant"],
        estimator["variant"],
        "" if particles is None else str(particles),
        settings["attitude"]["variant"],
        scenario.steps,
        late,
    )


#: Runs and steps of the timed sample: a study's runs go in batches, whose cost per run falls
#: with the batch, so one run alone would overestimate a study tens of times over.
SAMPLE_RUNS, SAMPLE_STEPS = 32, 40


def time_one_run(scenario: Scenario) -> float:
    """Wall seconds a run of ``scenario`` takes in a study, from two batches of the same (up
    to :data:`SAMPLE_RUNS`) runs timed as a study runs them (diagram built, seeds from the
    first), :data:`SAMPLE_STEPS` and twice as many steps.

    Their difference is the cost of the later steps alone: after the linear start's hand-over,
    where a filter carries its particles (the first steps cost a particle filter a tenth of
    the rest) and without the batch's fixed cost (its diagram, metrics, first kernel calls),
    which a study pays once per batch of :func:`~drake_uuv.studies.runner.max_batch_size`
    runs (a 40-step sample alone put the paper's KF at 110 ms a run, 50 times its cost in a
    study, and the realistic 20 000-particle filter at a seventh of its)."""
    short, long = min(scenario.steps, SAMPLE_STEPS), min(scenario.steps, 2 * SAMPLE_STEPS)
    runs = max(1, min(SAMPLE_RUNS, max_batch_size(scenario)))
    seeds = list(range(scenario.random_seed, scenario.random_seed + runs))

    def timed(steps: int) -> float:
        sample = dataclasses.replace(
            scenario, steps=steps, steady_state_start=min(scenario.steady_state_start, steps - 1)
        )
        start = perf_counter()
        run_seeds(sample, seeds)
        return perf_counter() - start

    first = timed(short)
    if long == short:  # too short a scenario to sample twice: the whole of it
        return first / runs
    per_step = max(timed(long) - first, 0.0) / (long - short) / runs
    fixed = max(first - per_step * short * runs, 0.0)  # per batch
    return per_step * scenario.steps + fixed / max_batch_size(scenario)


@dataclass(frozen=True)
class WallTimeEstimate:
    """The runs of a batch still to compute and the time they will take."""

    variants: int
    runs_per_variant: int
    # Runs still to compute (fewer than variants × runs_per_variant when resuming).
    runs: int
    # Seconds of one run of each configuration, and its runs still to compute.
    costs: dict[Configuration, tuple[float, int]]
    # Local worker processes; None on a Dask cluster (its size is known only once connected).
    workers: int | None
    # Runs of all the variants, computed or not (variants × runs_per_variant, unless some
    # variants run a share of the runs).
    total_runs: int | None = None

    @property
    def run_seconds(self) -> float:
        """The runs' seconds on one worker."""
        return sum(seconds * runs for seconds, runs in self.costs.values())

    @property
    def seconds(self) -> float:
        """Wall seconds on :attr:`workers` (on one worker for a cluster)."""
        return self.run_seconds / max(1, min(self.workers or 1, self.runs))


def estimate_wall_time(
    studies: Sequence[Study],
    workers: int | None,
    resume: bool = False,
    timer: Callable[[Scenario], float] | None = None,
) -> WallTimeEstimate:
    """Times one run of each configuration with runs to compute and scales it (see the module).

    ``timer(scenario)``: the seconds of one run (default :func:`time_one_run`).
    """
    timer = timer or time_one_run
    counts: dict[Configuration, int] = {}
    first: dict[Configuration, Scenario] = {}
    for study in studies:
        missing = len(missing_seeds(study, resume))
        if missing:
            key = configuration(study.scenario)
            counts[key] = counts.get(key, 0) + missing
            first.setdefault(key, study.scenario)
    costs = {key: (timer(first[key]), runs) for key, runs in counts.items()}
    return WallTimeEstimate(
        variants=len(studies),
        runs_per_variant=max((study.runs for study in studies), default=0),
        runs=sum(counts.values()),
        costs=costs,
        workers=workers,
        total_runs=sum(study.runs for study in studies),
    )


def duration(seconds: float) -> str:
    """``12 s``, ``4 min 10 s``, ``2 h 05 min``."""
    seconds = round(seconds)
    if seconds < 60:
        return f"{seconds} s"
    if seconds < 3600:
        return f"{seconds // 60} min {seconds % 60:02d} s"
    return f"{seconds // 3600} h {seconds % 3600 // 60:02d} min"


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}" + ("" if n == 1 else "s")


def format_estimate(estimate: WallTimeEstimate) -> str:
    """The lines ``drake-uuv compare`` prints before it starts."""
    total = estimate.total_runs
    if total is None:
        total = estimate.variants * estimate.runs_per_variant
    head = f"{_count(estimate.runs, 'run')} to compute ({_count(estimate.variants, 'variant')}"
    head += f" × {_count(estimate.runs_per_variant, 'run')}"
    if total != estimate.variants * estimate.runs_per_variant:
        head += f" or a share of them, {total} in all"
    head += ")" if estimate.runs == total else f", {total - estimate.runs} on disk already)"
    if not estimate.runs:
        return head
    where = (
        "on one worker (a cluster divides it by its worker threads)"
        if estimate.workers is None
        else f"on {_count(estimate.workers, 'worker')}"
    )
    lines = [
        f"{head}: about {duration(estimate.seconds)} {where},",
        "from two timed batches of each configuration "
        "(plant, estimator, particles, attitude, steps, late ranges):",
    ]
    for (plant, estimator, particles, attitude, steps, late), (seconds, runs) in sorted(
        estimate.costs.items(), key=lambda item: -item[1][0] * item[1][1]
    ):
        name = estimator + (f" {particles}" if particles else "")
        cost = f"{seconds:7.2f} s" if seconds >= 0.1 else f"{seconds * 1e3:6.2f} ms"
        timing = ", late ranges" if late else ""
        lines.append(f"  {cost} × {runs:>5}  {plant}, {name}, {attitude}, {steps} steps{timing}")
    return "\n".join(lines)
