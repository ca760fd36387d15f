"""The ``drake-uuv`` command line.

Every subcommand takes ``--scenario NAME_OR_PATH``, ``--seed S`` and repeated
``--set dotted.key=value``. Bad input (scenario file, ``--set``, options, an output folder that
cannot be written) exits with status 2 and one line naming the field and the value, without a
traceback; the output folder is checked before anything of Drake is imported. An OS error
later (a full disk, a folder removed during a run) is one line naming the path, status 1.

One module per subcommand (:mod:`~drake_uuv.cli.run`, :mod:`~drake_uuv.cli.diagram`,
:mod:`~drake_uuv.cli.animate`, :mod:`~drake_uuv.cli.montecarlo`,
:mod:`~drake_uuv.cli.compare`, :mod:`~drake_uuv.cli.variants`,
:mod:`~drake_uuv.cli.scenarios`, :mod:`~drake_uuv.cli.replay`,
:mod:`~drake_uuv.cli.onboard`, :mod:`~drake_uuv.cli.vehicle`), each with its parser
(``add_subcommand``) and handler; the shared options and :class:`UsageError` are in
:mod:`~drake_uuv.cli.options`. The command line is the top layer: nothing else in the package
imports it.
"""

import argparse
import sys
from collections.abc import Callable, Sequence

from drake_uuv.cli import (
    animate,
    compare,
    diagram,
    montecarlo,
    onboard,
    replay,
    run,
    scenarios,
    variants,
    vehicle,
)
from drake_uuv.cli.options import (
    ArgumentParser,
    UsageError,
    add_execution_options,
    add_scenario_options,
    check_output_folder,
    execution_options,
    scenario_from_args,
)

__all__ = [
    "EXIT_BAD_INPUT",
    "EXIT_RUN_FAILED",
    "SUBCOMMANDS",
    "UsageError",
    "add_execution_options",
    "add_scenario_options",
    "execution_options",
    "main",
    "make_parser",
    "scenario_from_args",
]

EXIT_RUN_FAILED = 1
EXIT_BAD_INPUT = 2

# Each entry adds one subcommand (parser and handler) to the command line.
SUBCOMMANDS: list[Callable[[argparse._SubParsersAction], None]] = [
    run.add_subcommand,
    replay.add_subcommand,
    onboard.add_subcommand,
    vehicle.add_subcommand,
    diagram.add_subcommand,
    animate.add_subcommand,
    montecarlo.add_subcommand,
    compare.add_subcommand,
    variants.add_subcommand,
    scenarios.add_subcommand,
]


def make_parser() -> argparse.ArgumentParser:
    """The ``drake-uuv`` parser with every subcommand of :data:`SUBCOMMANDS`."""
    parser = ArgumentParser(
        prog="drake-uuv",
        description="Range-only estimation of a target by a UUV with two sonars, as a Drake "
        "diagram. To start: drake-uuv scenarios (the shipped scenarios, run with --scenario "
        "NAME), drake-uuv variants (what --set SECTION=VARIANT can switch), drake-uuv run.",
    )
    subparsers = parser.add_subparsers(dest="command", required=True, parser_class=ArgumentParser)
    for add in SUBCOMMANDS:
        add(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``drake-uuv``; returns the exit status."""
    try:
        args = make_parser().parse_args(argv)
        if getattr(args, "output_folder", False):
            check_output_folder(args.out)
    except UsageError as e:
        return _error(f"error: {e}", EXIT_BAD_INPUT)
    # Imported only now: they load Drake, which the checks above do not need.
    from drake_uuv.monitor import SimulationFailure
    from drake_uuv.scenario import ScenarioError

    try:
        return args.handler(args)
    except (ScenarioError, UsageError) as e:
        return _error(f"error: {e}", EXIT_BAD_INPUT)
    except SimulationFailure as e:
        return _error(str(e), EXIT_RUN_FAILED)
    except OSError as e:
        return _error(f"error: {_os_error(e, args)}", EXIT_RUN_FAILED)


def _error(message: str, status: int) -> int:
    print(f"drake-uuv: {message}", file=sys.stderr)
    return status


def _os_error(error: OSError, args: argparse.Namespace) -> str:
    """One line naming the path(s) and the reason: ``'out/x/log.npz': No space left on
    device``; without a path in the error, the output folder the command was writing to."""
    reason = error.strerror or " ".join(str(error).split())
    paths = [repr(str(p)) for p in (error.filename, error.filename2) if p is not None]
    if not paths and getattr(args, "output_folder", False):
        return f"{reason} (writing to {args.out!r})"
    return f"{' -> '.join(paths)}: {reason}" if paths else reason
