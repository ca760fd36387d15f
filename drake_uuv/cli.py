"""The ``drake-uuv`` command line.

Every subcommand takes ``--scenario NAME_OR_PATH``, ``--seed S`` and repeated
``--set dotted.key=value``. Bad input (scenario file, ``--set``, options) exits with status 2
and one line naming the field and the value, without a traceback.
"""

import argparse
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

from drake_uuv import compare, montecarlo
from drake_uuv.scenario import Scenario, ScenarioError, load_scenario

EXIT_BAD_INPUT = 2


class UsageError(ValueError):
    """A bad command-line option (named in the message)."""


class _ArgumentParser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # argparse's own errors: one line, status 2.
        raise UsageError(message)


def add_scenario_options(parser: argparse.ArgumentParser) -> None:
    """``--scenario``, ``--seed`` and ``--set``, shared by every subcommand."""
    parser.add_argument(
        "--scenario", default="paper", help="shipped scenario name or YAML path (default: paper)"
    )
    parser.add_argument("--seed", type=int, default=None, help="override random_seed")
    parser.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a scenario field, e.g. --set attitude.mode=fixed (repeatable)",
    )


def scenario_from_args(args: argparse.Namespace) -> Scenario:
    """The validated scenario named by the shared options."""
    return load_scenario(args.scenario, args.overrides, seed=args.seed)


def _run(args: argparse.Namespace) -> int:
    from drake_uuv.analysis.figures import write_run_figures
    from drake_uuv.analysis.plots import plot_errors
    from drake_uuv.simulation import simulate

    scenario = scenario_from_args(args)
    out = Path(args.out)
    result = simulate(scenario)
    result.save(out)
    plot_errors(result, out / "errors.png")
    write_run_figures(result.log, scenario, out / "figures")
    m = result.metrics
    print(
        f"{scenario.steps} steps in {m['wall_time_s']:.2f} s: position RMSE "
        f"{m['position_rmse']:.4f} m, velocity RMSE {m['velocity_rmse']:.4f} m/s, tracking RMSE "
        f"{m['tracking_rmse']:.4f} m, mean NEES {m['nees_mean']:.2f} (k ≥ "
        f"{scenario.steady_state_start}) -> {out}/"
    )
    return 0


def _add_run(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "run", help="simulate one scenario and write its log, metrics, figures"
    )
    add_scenario_options(parser)
    parser.add_argument("--out", default="out/paper", help="output folder (default: out/paper)")
    parser.set_defaults(handler=_run)


def _diagram(args: argparse.Namespace) -> int:
    from drake_uuv.visualization.diagram_graph import export_all_variants, export_diagram

    if args.max_depth < 1:
        raise UsageError(f"--max-depth: must be ≥ 1, got {args.max_depth}")
    if args.all_variants:
        written = export_all_variants(Path(args.out), args.max_depth)
    else:
        scenario = scenario_from_args(args)
        written = export_diagram(scenario, Path(args.out), args.name, args.max_depth)
    print("wrote " + ", ".join(str(p) for p in written))
    if not any(p.suffix == ".svg" for p in written):
        print("Graphviz's dot is not installed: wrote the .dot only (apt-get install graphviz)")
    return 0


def _add_diagram(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("diagram", help="export the closed-loop diagram as Graphviz")
    add_scenario_options(parser)
    parser.add_argument("--max-depth", type=int, default=1, help="subsystem depth to expand")
    parser.add_argument("--name", default="paper", help="file name stem (default: paper)")
    parser.add_argument("--out", default="diagrams", help="output folder (default: diagrams)")
    parser.add_argument(
        "--all-variants",
        action="store_true",
        help="export every variant the package builds (attitude modes, estimators, laws)",
    )
    parser.set_defaults(handler=_diagram)


# Each entry adds one subcommand (parser and handler) to the command line.
SUBCOMMANDS: list[Callable[[argparse._SubParsersAction], None]] = [
    _add_run,
    _add_diagram,
    montecarlo.add_subcommand,
    compare.add_subcommand,
]


def make_parser() -> argparse.ArgumentParser:
    parser = _ArgumentParser(prog="drake-uuv", description=__doc__.splitlines()[0])
    subparsers = parser.add_subparsers(dest="command", required=True, parser_class=_ArgumentParser)
    for add in SUBCOMMANDS:
        add(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``drake-uuv``; returns the exit status."""
    try:
        args = make_parser().parse_args(argv)
        return args.handler(args)
    except (ScenarioError, UsageError) as e:
        print(f"drake-uuv: error: {e}", file=sys.stderr)
        return EXIT_BAD_INPUT


if __name__ == "__main__":
    sys.exit(main())
