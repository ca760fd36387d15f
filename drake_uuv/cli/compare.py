"""``drake-uuv compare``: Monte Carlo tables of scenario variants (``compare.md``, ``.csv``).

The groups of variants are not part of the package: they are read from a studies folder
(``--studies DIR``, by default the ``studies/`` folder of the checkout the package was
imported from; see :mod:`drake_uuv.studies.groups`). Without ``--group`` the paper's groups
run; ``--group list`` lists every group and runs nothing. Before it starts, the command prints
the number of runs and an estimate of the wall time from one timed run of each configuration
(:mod:`drake_uuv.studies.estimate`). The comparison itself is :func:`drake_uuv.studies.compare`;
:class:`~drake_uuv.studies.MonteCarloError` (a bad ``--group``, ``--studies``, ``--runs``, …)
becomes a usage error (status 2).
"""

import argparse
from pathlib import Path

from drake_uuv.cli.options import (
    EXIT_INTERRUPTED,
    UsageError,
    add_command,
    execution_options,
)


def _compare(args: argparse.Namespace) -> int:
    from drake_uuv.studies import (
        LIST,
        BaseScenario,
        MonteCarloError,
        compare_groups,
        default_studies_folder,
        default_workers,
        estimate_wall_time,
        format_estimate,
        format_group_list,
        group_variants,
        load_groups,
        select_groups,
        variant_studies,
    )

    out = Path(args.out)
    try:
        if args.runs < 1:  # before the runs are listed or timed
            raise MonteCarloError(f"--runs: must be ≥ 1, got {args.runs}")
        groups = load_groups(args.studies or default_studies_folder())
        if args.groups and LIST in args.groups:
            print(format_group_list(groups, args.runs))
            return 0
        chosen = select_groups(groups, args.groups)
        base = BaseScenario(args.scenario, tuple(args.overrides), args.seed)
        studies = variant_studies(group_variants(chosen), out, args.runs, base)
        workers = default_workers() if args.workers is None else args.workers
        workers = None if args.scheduler else workers
        print(format_estimate(estimate_wall_time(studies, workers, args.resume)), flush=True)
        compare_groups(chosen, out, args.runs, base=base, **execution_options(args))
    except MonteCarloError as e:
        raise UsageError(str(e)) from e
    except KeyboardInterrupt:
        print(f"\ninterrupted: finished runs kept in {out}/studies; rerun with --resume")
        return EXIT_INTERRUPTED
    print((out / "compare.md").read_text())
    print(f"-> {out}/compare.md, {out}/compare.csv")
    return 0


def add_subcommand(subparsers: argparse._SubParsersAction) -> None:
    """Registers ``drake-uuv compare``."""
    parser = add_command(
        subparsers,
        "compare",
        _compare,
        ("out/compare", "output folder: compare.md, compare.csv, studies"),
        study=True,
        help="Monte Carlo tables of named groups of scenario variants (default: the paper's "
        "groups; --group list shows them all)",
        description="Runs every variant of the chosen groups as Monte Carlo studies and writes "
        "OUT/compare.md and OUT/compare.csv. It first prints the runs and an estimate of the "
        "wall time, from two timed batches of each configuration (plant, estimator, "
        "particles, attitude, steps, late ranges) among the variants.",
    )
    parser.add_argument(
        "--group",
        dest="groups",
        action="append",
        default=None,
        metavar="NAME",
        help="variant group to run (repeatable); 'list' prints every group (name, variants, "
        "runs at --runs, what it measures) and runs nothing; default: the paper's groups, "
        "those that test its claims (attitude_noise, alpha, tracking in the repository's "
        "studies/)",
    )
    parser.add_argument(
        "--studies",
        type=Path,
        default=None,
        metavar="DIR",
        help="folder of the study groups, a package whose __init__.py defines GROUPS "
        "(default: the studies/ folder of the checkout drake_uuv was imported from)",
    )
