"""``drake-uuv vehicle --lcm URL``: the simulated vehicle half (plant, target, sonars,
navigation) for an onboard half over LCM (drake_uuv/hardware/channels.py)."""

import argparse

from drake_uuv.cli.onboard import add_lcm_option, run_half
from drake_uuv.cli.options import add_command


def add_subcommand(subparsers: argparse._SubParsersAction) -> None:
    """Registers ``drake-uuv vehicle``."""
    parser = add_command(
        subparsers, "vehicle", lambda args: run_half(args, "vehicle"),
        ("out/vehicle", "output folder: the vehicle half's log (the truth)"),
        help="run the simulated vehicle (plant, target, sonars, navigation) over LCM",
    )  # fmt: skip
    add_lcm_option(parser, None)
