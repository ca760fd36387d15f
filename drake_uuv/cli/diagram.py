"""``drake-uuv diagram``: export the closed-loop diagram as Graphviz (.dot, .svg, .png)."""

import argparse
from pathlib import Path

from drake_uuv.cli.options import (
    UsageError,
    add_out_option,
    add_scenario_options,
    scenario_from_args,
)


def _diagram(args: argparse.Namespace) -> int:
    from drake_uuv.visualization.diagram_graph import export_all_variants, export_diagram

    if args.max_depth < 1:
        raise UsageError(f"--max-depth: must be ≥ 1, got {args.max_depth}")
    if args.all_variants:
        written = export_all_variants(Path(args.out), args.max_depth, args.show_loggers)
    else:
        scenario = scenario_from_args(args)
        written = export_diagram(
            scenario, Path(args.out), args.name, args.max_depth, args.show_loggers
        )
    print("wrote " + ", ".join(str(p) for p in written))
    if not any(p.suffix == ".svg" for p in written):
        print("Graphviz's dot is not installed: wrote the .dot only (apt-get install graphviz)")
    return 0


def add_subcommand(subparsers: argparse._SubParsersAction) -> None:
    """Registers ``drake-uuv diagram``."""
    parser = subparsers.add_parser("diagram", help="export the closed-loop diagram as Graphviz")
    add_scenario_options(parser)
    parser.add_argument("--max-depth", type=int, default=1, help="subsystem depth to expand")
    parser.add_argument("--name", default="paper", help="file name stem (default: paper)")
    add_out_option(parser, "diagrams", "output folder")
    parser.add_argument(
        "--all-variants",
        action="store_true",
        help="export every variant the package builds (each slot's variants, sonar faults)",
    )
    parser.add_argument(
        "--show-loggers",
        action="store_true",
        help="draw the run's loggers too (one per logged signal; hidden by default)",
    )
    parser.set_defaults(handler=_diagram)
