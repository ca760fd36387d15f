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
from drake_uuv.monitor import SimulationFailure
from drake_uuv.scenario import Scenario, ScenarioError, load_scenario

EXIT_RUN_FAILED = 1
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
        help="override a scenario field, e.g. --set tracking.alpha=1.0, or switch a slot's "
        "variant, e.g. --set attitude=!FixedAttitude (repeatable)",
    )


def scenario_from_args(args: argparse.Namespace) -> Scenario:
    """The validated scenario named by the shared options."""
    return load_scenario(args.scenario, args.overrides, seed=args.seed)


def _run(args: argparse.Namespace) -> int:
    from drake_uuv.analysis.figures import write_run_figures
    from drake_uuv.analysis.plots import plot_errors
    from drake_uuv.simulation import ClosedLoopSimulation

    scenario = scenario_from_args(args)
    if args.realtime_rate < 0:
        raise UsageError(f"--realtime-rate: must be ≥ 0, got {args.realtime_rate}")
    out = Path(args.out)
    meshcat = None
    if args.meshcat:
        from pydrake.geometry import StartMeshcat

        meshcat = StartMeshcat()
        print(f"Meshcat is serving the live scene at {meshcat.web_url()}")
    result = ClosedLoopSimulation(scenario, meshcat=meshcat).run(realtime_rate=args.realtime_rate)
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
    if meshcat is not None and sys.stdin.isatty():
        input("The scene stays up until you press Enter. ")
    return 0


def _add_run(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "run", help="simulate one scenario and write its log, metrics, figures"
    )
    add_scenario_options(parser)
    parser.add_argument("--out", default="out/paper", help="output folder (default: out/paper)")
    parser.add_argument(
        "--meshcat", action="store_true", help="draw the scene live in Meshcat (localhost)"
    )
    parser.add_argument(
        "--realtime-rate",
        type=float,
        default=0.0,
        help="pace the simulation at this multiple of real time (0: as fast as possible; "
        "with --meshcat, try 10)",
    )
    parser.set_defaults(handler=_run)


def _animate(args: argparse.Namespace) -> int:
    import numpy as np

    from drake_uuv.simulation import simulate
    from drake_uuv.visualization import record_animation

    if args.playback_speed <= 0:
        raise UsageError(f"--playback-speed: must be > 0, got {args.playback_speed}")
    if args.trail_length < 0:
        raise UsageError(f"--trail-length: must be ≥ 0, got {args.trail_length}")
    scenario = scenario_from_args(args)
    result = simulate(scenario)
    path = record_animation(
        result.log,
        np.asarray(scenario.sonar.baseline),
        scenario.time_step,
        Path(args.out) / "animation.html",
        playback_speed=args.playback_speed,
        trail_length=args.trail_length,
        follow_target=not args.fixed_camera,
    )
    size = path.stat().st_size / 1e6
    print(f"wrote {path} ({size:.1f} MB, self-contained: open it in any browser, offline)")
    return 0


def _add_animate(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "animate", help="simulate and write a self-contained 3-D animation (HTML)"
    )
    add_scenario_options(parser)
    parser.add_argument("--out", default="out/paper", help="output folder (default: out/paper)")
    parser.add_argument(
        "--playback-speed", type=float, default=4.0, help="simulated seconds per second (4)"
    )
    parser.add_argument(
        "--trail-length", type=int, default=50, help="steps of trajectory trail (0: none)"
    )
    parser.add_argument(
        "--fixed-camera",
        action="store_true",
        help="world-fixed view instead of following the target",
    )
    parser.set_defaults(handler=_animate)


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


def _add_diagram(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("diagram", help="export the closed-loop diagram as Graphviz")
    add_scenario_options(parser)
    parser.add_argument("--max-depth", type=int, default=1, help="subsystem depth to expand")
    parser.add_argument("--name", default="paper", help="file name stem (default: paper)")
    parser.add_argument("--out", default="diagrams", help="output folder (default: diagrams)")
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


# Each entry adds one subcommand (parser and handler) to the command line.
SUBCOMMANDS: list[Callable[[argparse._SubParsersAction], None]] = [
    _add_run,
    _add_diagram,
    _add_animate,
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
    except SimulationFailure as e:
        print(f"drake-uuv: {e}", file=sys.stderr)
        return EXIT_RUN_FAILED


if __name__ == "__main__":
    sys.exit(main())
