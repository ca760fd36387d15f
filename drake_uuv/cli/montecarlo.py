"""``drake-uuv montecarlo``: many seeded runs of a scenario; ``runs.csv``, ``summary.json``, bands.

The study itself is :func:`drake_uuv.studies.run_study`; this module only parses options,
turns the study's :class:`~drake_uuv.studies.MonteCarloError` into a usage error (status 2),
and reports an interruption (status 130, the finished runs kept for ``--resume``).
"""

import argparse
from pathlib import Path

from drake_uuv.cli.options import (
    EXIT_INTERRUPTED,
    UsageError,
    add_command,
    execution_options,
    scenario_from_args,
)


def _montecarlo(args: argparse.Namespace) -> int:
    from drake_uuv.studies import (
        MonteCarloError,
        Study,
        completed_seeds,
        format_summary,
        run_study,
    )

    scenario = scenario_from_args(args)
    out = Path(args.out)
    study = Study(name=args.scenario, scenario=scenario, runs=args.runs, out_dir=out)
    try:
        result = run_study(study, **execution_options(args))
    except MonteCarloError as e:
        raise UsageError(str(e)) from e
    except KeyboardInterrupt:
        kept = len(completed_seeds(out))
        print(f"\ninterrupted: {kept} finished runs kept in {out}/runs; rerun with --resume")
        return EXIT_INTERRUPTED
    kept = study.runs - result.computed
    print(f"computed {result.computed} runs" + (f", kept {kept}" if kept else "") + f" -> {out}/")
    print(format_summary(result.summary))
    return 0


def add_subcommand(subparsers: argparse._SubParsersAction) -> None:
    """Registers ``drake-uuv montecarlo``."""
    add_command(
        subparsers, "montecarlo", _montecarlo,
        ("out/montecarlo", "output folder: runs, runs.csv, summary.json"), study=True,
        help="many seeded runs: runs.csv, summary.json, error bands",
    )  # fmt: skip
