"""``drake-uuv animate``: simulate and write a self-contained 3-D animation (HTML)."""

import argparse
from pathlib import Path

from drake_uuv.cli.options import UsageError, add_command, scenario_from_args


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


def add_subcommand(subparsers: argparse._SubParsersAction) -> None:
    """Registers ``drake-uuv animate``."""
    parser = add_command(
        subparsers, "animate", _animate, ("out/paper", "output folder of animation.html"),
        help="simulate and write a self-contained 3-D animation (HTML)",
    )  # fmt: skip
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
