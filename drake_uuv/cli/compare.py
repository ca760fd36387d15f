"""``drake-uuv compare``: Monte Carlo tables of scenario variants (``compare.md``, ``.csv``).

The comparison itself is :func:`drake_uuv.studies.compare`; this module parses options,
turns :class:`~drake_uuv.studies.MonteCarloError` (a bad ``--group``, ``--runs``, …) into a
usage error (status 2), and prints the Markdown tables.
"""

import argparse
from pathlib import Path

from drake_uuv.cli.options import (
    EXIT_INTERRUPTED,
    UsageError,
    add_execution_options,
    add_scenario_options,
    execution_options,
)
from drake_uuv.studies import VARIANT_GROUPS, MonteCarloError, compare, selected_variants


def _compare(args: argparse.Namespace) -> int:
    out = Path(args.out)
    try:
        variants = selected_variants(args.groups)
        compare(
            variants,
            out,
            args.runs,
            scenario=args.scenario,
            base_overrides=args.overrides,
            seed=args.seed,
            **execution_options(args),
        )
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
    parser = subparsers.add_parser(
        "compare",
        help="Monte Carlo tables: attitude × noise model, an α sweep, estimator × attitude "
        "mode against the PCRLB",
    )
    add_scenario_options(parser)
    add_execution_options(parser)
    parser.add_argument(
        "--group",
        dest="groups",
        action="append",
        default=None,
        help=f"variant group to run (repeatable; default all: {', '.join(VARIANT_GROUPS)})",
    )
    parser.add_argument("--out", default="out/compare", help="output folder (default: out/compare)")
    parser.set_defaults(handler=_compare)
