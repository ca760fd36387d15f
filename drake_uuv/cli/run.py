"""``drake-uuv run``: simulate one scenario; write its log, metrics and figures."""

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from drake_uuv.cli.options import UsageError, add_command, scenario_from_args

if TYPE_CHECKING:
    from drake_uuv.scenario import Scenario
    from drake_uuv.simulation import SimulationResult


def _run(args: argparse.Namespace) -> int:
    from drake_uuv.analysis.registry import write_run_figures
    from drake_uuv.simulation import ClosedLoopSimulation

    scenario = scenario_from_args(args)
    if args.realtime_rate < 0:
        raise UsageError(f"--realtime-rate: must be ≥ 0, got {args.realtime_rate}")
    out = Path(args.out)
    if args.lcm is not None and args.meshcat:
        raise UsageError("--lcm: draws no live scene, drop --meshcat")
    if args.record is not None and Path(args.record).exists():
        raise UsageError(f"--record: {args.record!r} exists (a recording is a new folder)")
    meshcat = None
    if args.meshcat:
        from pydrake.geometry import StartMeshcat

        meshcat = StartMeshcat()
        print(f"Meshcat is serving the live scene at {meshcat.web_url()}")
    if args.lcm is not None:
        result = _run_over_lcm(scenario, args)
    else:
        simulation = ClosedLoopSimulation(scenario, meshcat=meshcat)
        result = simulation.run(realtime_rate=args.realtime_rate)
    result.save(out)
    write_run_figures(result.log, scenario, out)
    if args.record is not None:
        from drake_uuv.recordings import record_run

        record_run(args.record, result.log, scenario, storage=args.record_storage)
    m = result.metrics
    print(
        f"{scenario.steps} steps in {m['wall_time_s']:.2f} s: position RMSE "
        f"{m['position_rmse']:.4f} m, velocity RMSE {m['velocity_rmse']:.4f} m/s, tracking RMSE "
        f"{m['tracking_rmse']:.4f} m, mean NEES {m['nees_mean']:.2f} (k ≥ "
        f"{scenario.steady_state_start}) -> {out}/"
    )
    for warning in result.warnings:
        print(warning)
    if meshcat is not None and sys.stdin.isatty():
        input("The scene stays up until you press Enter. ")
    return 0


def _run_over_lcm(scenario: "Scenario", args: argparse.Namespace) -> "SimulationResult":
    """The run as its two halves over LCM in this process (drake_uuv/hardware/)."""
    from drake_uuv.hardware import SplitError, run_lcm

    try:
        return run_lcm(scenario, args.lcm)
    except SplitError as e:
        raise UsageError(f"--lcm: {e}") from e


def add_subcommand(subparsers: argparse._SubParsersAction) -> None:
    """Registers ``drake-uuv run``."""
    parser = add_command(
        subparsers, "run", _run, ("out/paper", "output folder: log, metrics, figures"),
        help="simulate one scenario and write its log, metrics, figures",
    )  # fmt: skip
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
    parser.add_argument(
        "--record",
        default=None,
        metavar="PATH",
        help="also write the run as a ROS 2 bag (MCAP) in the new folder PATH, for drake-uuv "
        "replay and ROS tools (drake_uuv/recordings/layout.py)",
    )
    parser.add_argument(
        "--record-storage",
        choices=("mcap", "sqlite3"),
        default="mcap",
        help="the bag's storage for --record (default: mcap)",
    )
    parser.add_argument(
        "--lcm",
        default=None,
        metavar="URL",
        help="run the loop as its onboard and vehicle halves over LCM in this process, in "
        "lockstep (e.g. memq://): the same run (drake_uuv/hardware/)",
    )
