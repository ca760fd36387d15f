"""``drake-uuv replay RECORDING``: run the scenario's estimator on a recorded dive."""

import argparse
import sys
from pathlib import Path

from drake_uuv.cli.options import UsageError, add_command, scenario_from_args


def _replay(args: argparse.Namespace) -> int:
    from drake_uuv.analysis.figures import error_summary_figure, nees_figure, save_figure
    from drake_uuv.recordings import RecordingError, load_topics, replay

    scenario = scenario_from_args(args)
    try:
        result = replay(args.recording, scenario, topics=load_topics(args.topics))
    except RecordingError as e:
        raise UsageError(str(e)) from e
    for warning in result.warnings:
        print(f"drake-uuv: {warning}", file=sys.stderr)
    out = Path(args.out)
    result.save(out)
    m = result.metrics
    summary = f"{int(m['steps'])} steps, {int(m['updates'])} updates in {m['wall_time_s']:.2f} s"
    if "position_rmse" in m:
        summary += (
            f": position RMSE {m['position_rmse']:.4f} m, velocity RMSE "
            f"{m['velocity_rmse']:.4f} m/s, mean NEES {m['nees_mean']:.2f} against the "
            "recorded truth"
        )
        log, replayed = result.log, result.scenario
        save_figure(error_summary_figure(log, replayed), out / "error_summary", ("png",))
        save_figure(nees_figure(log, replayed), out / "figures" / "nees_per_step", ("png",))
    print(f"{summary} -> {out}/")
    return 0


def add_subcommand(subparsers: argparse._SubParsersAction) -> None:
    """Registers ``drake-uuv replay``."""
    parser = add_command(
        subparsers, "replay", _replay, ("out/replay", "output folder: log, metrics, figures"),
        help="run the scenario's estimator on a recorded dive (a ROS 1 or ROS 2 bag)",
        description="Replays RECORDING (a ROS 2 bag folder, MCAP or sqlite3, or a ROS 1 .bag) "
        "through the scenario's estimator on the recording's clock at the scenario's step, "
        "each range at its own ping time; writes log.npz, metrics.json (against the recorded "
        "truth, where there is some) and the estimation figures. The layout: "
        "drake_uuv/recordings/layout.py.",
    )  # fmt: skip
    parser.add_argument("recording", help="the recording: a ROS 2 bag's folder or a ROS 1 .bag")
    parser.add_argument(
        "--topics",
        default=None,
        metavar="TOPICS.YAML",
        help="rename the layout's topics (keys: sonar_1, sonar_2, navigation, attitude "
        "(a sensor_msgs/msg/Imu), acceleration, tf_static, truth_vehicle, truth_target)",
    )
