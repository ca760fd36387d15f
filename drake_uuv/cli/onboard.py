"""``drake-uuv onboard --lcm URL``: the onboard half (estimator, attitude, tracking) against a
vehicle's LCM channels (drake_uuv/hardware/channels.py), one step per vehicle message."""

import argparse
from pathlib import Path

from drake_uuv.cli.options import UsageError, add_command, scenario_from_args


def add_lcm_option(parser: argparse.ArgumentParser, default: str | None) -> None:
    """``--lcm URL``: the LCM network of the two halves."""
    parser.add_argument(
        "--lcm",
        default=default,
        metavar="URL",
        help="LCM URL, e.g. udpm://239.255.76.67:7667?ttl=0 (the host only) or memq:// (one "
        f"process){'' if default is None else f' (default: {default})'}",
    )
    parser.add_argument(
        "--timeout",
        type=float,
        default=30.0,
        help="seconds to wait for the other half's messages of a step (default: 30)",
    )


def run_half(args: argparse.Namespace, side: str) -> int:
    """Runs one half (``onboard`` or ``vehicle``) and writes its ``log.npz`` to ``--out``."""
    from drake_uuv.hardware import LcmTimeout, SplitError, run_onboard, run_vehicle
    from drake_uuv.io import write_npz_atomic

    if args.lcm is None:
        raise UsageError(
            f"--lcm: the {side} half needs an LCM URL, e.g. udpm://239.255.76.67:7667?ttl=0"
        )
    scenario = scenario_from_args(args)
    if args.timeout <= 0:
        raise UsageError(f"--timeout: must be > 0, got {args.timeout}")
    run = run_onboard if side == "onboard" else run_vehicle
    try:
        log = run(scenario, args.lcm, timeout=args.timeout)
    except SplitError as e:
        raise UsageError(f"--lcm: {e}") from e
    except LcmTimeout as e:
        print(f"drake-uuv: {e}")
        return 1
    out = Path(args.out)
    write_npz_atomic(out / "log.npz", log)
    print(f"{side}: {len(log['k'])} steps over {args.lcm} -> {out}/")
    return 0


def add_subcommand(subparsers: argparse._SubParsersAction) -> None:
    """Registers ``drake-uuv onboard``."""
    parser = add_command(
        subparsers, "onboard", lambda args: run_half(args, "onboard"),
        ("out/onboard", "output folder: the onboard half's log"),
        help="run the onboard half (estimator, attitude, tracking) against a vehicle over LCM",
    )  # fmt: skip
    add_lcm_option(parser, None)
