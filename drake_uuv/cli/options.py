"""What every subcommand shares: the usage error, the parser class, the common options, the
check of the output folder.

The lowest module of :mod:`drake_uuv.cli`; the subcommand modules import it. It imports
nothing of Drake, so that a bad option or output folder is refused before anything is loaded.
"""

import argparse
import os
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

if TYPE_CHECKING:
    from drake_uuv.scenario import Scenario

# A study stopped by Ctrl-C: 128 + SIGINT, as a shell reports it.
EXIT_INTERRUPTED = 130


class UsageError(ValueError):
    """A bad command-line option (named in the message)."""


class ArgumentParser(argparse.ArgumentParser):
    """argparse's own errors as :class:`UsageError`: one line and status 2, no usage dump."""

    def error(self, message: str) -> NoReturn:
        raise UsageError(message)


def add_listing(
    subparsers: argparse._SubParsersAction,
    name: str,
    summary: str,
    handler: Callable[[argparse.Namespace], int],
) -> None:
    """Registers ``drake-uuv NAME``, a command without options that prints a listing."""
    subparsers.add_parser(name, help=summary).set_defaults(handler=handler)


def add_scenario_options(parser: argparse.ArgumentParser) -> None:
    """``--scenario``, ``--seed`` and ``--set``, shared by every subcommand."""
    parser.add_argument(
        "--scenario",
        default="paper",
        help="shipped scenario name (drake-uuv scenarios lists them) or YAML path (default: paper)",
    )
    parser.add_argument("--seed", type=int, default=None, help="override random_seed")
    parser.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a scenario field, e.g. --set tracking.alpha=1.0, or switch a slot's "
        "variant, e.g. --set attitude=FixedAttitude (drake-uuv variants lists them; "
        "repeatable)",
    )


def scenario_from_args(args: argparse.Namespace) -> "Scenario":
    """The validated scenario named by the shared options."""
    from drake_uuv.scenario import load_scenario

    return load_scenario(args.scenario, args.overrides, seed=args.seed)


def add_out_option(parser: argparse.ArgumentParser, default: str, what: str) -> None:
    """``--out DIR``, the folder a subcommand writes ``what`` to; :func:`check_output_folder`
    checks it before the subcommand starts."""
    parser.add_argument("--out", default=default, help=f"{what} (default: {default})")
    parser.set_defaults(output_folder=True)


def add_command(
    subparsers: argparse._SubParsersAction,
    name: str,
    handler: Callable[[argparse.Namespace], int],
    out: tuple[str, str],
    *,
    study: bool = False,
    **parser_fields: str,
) -> argparse.ArgumentParser:
    """Registers ``drake-uuv NAME`` (``parser_fields``: ``help``, ``description``): the scenario
    options, with ``study`` the execution options, ``--out`` of ``out`` (default, what) and
    ``handler``. Returns the parser for the command's own options."""
    parser = subparsers.add_parser(name, **parser_fields)
    add_scenario_options(parser)
    if study:
        add_execution_options(parser)
    add_out_option(parser, *out)
    parser.set_defaults(handler=handler)
    return parser


def add_execution_options(parser: argparse.ArgumentParser) -> None:
    """The options of how a study runs: runs, workers, scheduler, resume, chunk size, progress."""
    parser.add_argument("--runs", type=int, default=100, help="runs per study (default: 100)")
    parser.add_argument(
        "--workers", type=int, default=None, help="local processes (default: every core)"
    )
    parser.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="run on a dask.distributed cluster, e.g. tcp://host:8786",
    )
    parser.add_argument(
        "--resume", action="store_true", help="keep finished runs in --out, compute the rest"
    )
    parser.add_argument(
        "--chunk-size",
        type=int,
        default=None,
        help="seeds per task (default: automatic; smaller loses less on interruption)",
    )
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")


def execution_options(args: argparse.Namespace) -> dict[str, Any]:
    """The :func:`drake_uuv.studies.run_studies` keywords from :func:`add_execution_options`."""
    return dict(
        workers=args.workers,
        scheduler=args.scheduler,
        resume=args.resume,
        chunk_size=args.chunk_size,
        progress=not args.no_progress,
    )


def check_output_folder(out: str) -> None:
    """Raises :class:`UsageError` naming ``out`` and the reason if it cannot become a folder
    this process writes into: something else than a folder in its place or in its path, or
    a folder it may not write into (permissions, a read-only file system)."""
    path = existing = Path(out)
    try:
        while not existing.exists() and not existing.is_symlink():
            existing = existing.parent
    except OSError as e:  # e.g. a folder on the way that may not be searched
        raise UsageError(f"--out: cannot write to {out!r}: {e.strerror}") from e
    it = "it" if existing == path else repr(str(existing))
    if not existing.is_dir():
        raise UsageError(f"--out: cannot write to {out!r}: {it} is not a folder")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise UsageError(f"--out: cannot write to {out!r}: {it} is not writable")
