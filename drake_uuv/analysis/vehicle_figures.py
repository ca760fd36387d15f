"""Figures of the thruster-driven vehicle: attitude tracking and thrusts against their limits.

Both take a log dict keyed by port names (``log["thrust"]`` N×8, ``log["R_WB"]`` N×9, …) plus
``log["time"]`` (N), one row per logged sample, as ``LogVectorOutput`` records them (the value
at a time before that time's discrete updates). Matplotlib runs on the Agg backend; figures are
written with ``save_figure_atomic`` and closed.
"""

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from drake_uuv.io import save_figure_atomic  # noqa: E402
from drake_uuv.models.so3 import log_so3  # noqa: E402

__all__ = [
    "attitude_errors",
    "attitude_tracking_figure",
    "plot_attitude_tracking",
    "plot_thrusts",
    "roll_pitch_yaw",
    "thrust_figure",
]

_AXES = ("x", "y", "z")


def roll_pitch_yaw(R_rows: np.ndarray) -> np.ndarray:
    """N×3 roll-pitch-yaw [rad] (Drake's extrinsic x-y-z) of N row-major rotation matrices."""
    R = np.asarray(R_rows, dtype=float).reshape(-1, 3, 3)
    roll = np.arctan2(R[:, 2, 1], R[:, 2, 2])
    pitch = np.arcsin(np.clip(-R[:, 2, 0], -1.0, 1.0))
    yaw = np.arctan2(R[:, 1, 0], R[:, 0, 0])
    return np.column_stack([roll, pitch, yaw])


def attitude_errors(log: dict[str, np.ndarray]) -> np.ndarray:
    """``|Log(R_WB_command R_WBᵀ)|`` per row [rad]: achieved against commanded attitude."""
    return np.array(
        [
            np.linalg.norm(log_so3(c.reshape(3, 3) @ a.reshape(3, 3).T))
            for c, a in zip(log["R_WB_command"], log["R_WB"], strict=True)
        ]
    )


def plot_attitude_tracking(log: dict[str, np.ndarray], path: Path) -> Path:
    """Writes :func:`attitude_tracking_figure` to ``path``."""
    figure = attitude_tracking_figure(log)
    save_figure_atomic(figure, path, dpi=120)
    plt.close(figure)
    return path


def attitude_tracking_figure(log: dict[str, np.ndarray]) -> Figure:
    """Commanded against achieved attitude and angular rate.

    Needs ``time``, ``R_WB``, ``R_WB_command``, ``w_WB`` and ``w_WB_command``, logged at the
    outer period t: row k then holds the attitude reached at kt and the target ``R(k)`` set
    at step k − 1, and the rate ``u2`` that was in force over the step before. Top: roll,
    pitch and yaw of both (roll and yaw unwrapped). Middle: the attitude error angle at each
    tick. Bottom: the world angular velocity, commanded (steps) and achieved.
    """
    time = np.asarray(log["time"])
    achieved = roll_pitch_yaw(log["R_WB"])
    commanded = roll_pitch_yaw(log["R_WB_command"])
    for i in (0, 2):  # roll and yaw wrap at ±π; pitch stays in [−π/2, π/2]
        achieved[:, i] = np.unwrap(achieved[:, i])
        commanded[:, i] = np.unwrap(commanded[:, i])
    error = attitude_errors(log)
    figure, axes = plt.subplots(3, 1, sharex=True, figsize=(9, 7.5), constrained_layout=True)
    colors = ("tab:red", "tab:green", "tab:blue")
    for i, (name, color) in enumerate(zip(("roll", "pitch", "yaw"), colors, strict=True)):
        axes[0].plot(time, commanded[:, i], color=color, lw=1.6, alpha=0.45, label=f"{name} cmd")
        axes[0].plot(time, achieved[:, i], color=color, lw=0.8, label=name)
    axes[0].set_ylabel("attitude [rad]")
    axes[0].legend(ncol=3, fontsize=7, loc="upper left")
    # Row 0 compares the initial attitude with itself: start at row 1.
    axes[1].semilogy(time[1:], np.maximum(error[1:], 1e-9), color="black", lw=0.8)
    axes[1].set_ylabel("|Log(R_cmd R_WBᵀ)| [rad]")
    rates = np.asarray(log["w_WB"])
    commanded_rates = np.asarray(log["w_WB_command"])
    for i, color in enumerate(colors):
        axes[2].step(
            time,
            commanded_rates[:, i],
            where="pre",
            color=color,
            lw=1.6,
            alpha=0.45,
            label=f"ω{_AXES[i]} cmd",
        )
        axes[2].plot(time, rates[:, i], color=color, lw=0.8, label=f"ω{_AXES[i]}")
    axes[2].set_ylabel("ω_WB [rad/s]")
    axes[2].set_xlabel("time [s]")
    axes[2].legend(ncol=3, fontsize=7, loc="upper left")
    for axis in axes:
        axis.grid(True, which="both", alpha=0.3)
    figure.suptitle(
        f"attitude error at the outer ticks: mean {error[1:].mean():.3g} rad, peak "
        f"{error[1:].max():.3g} rad",
        fontsize=9,
    )
    return figure


def plot_thrusts(log: dict[str, np.ndarray], max_thrust: float, path: Path) -> Path:
    """Writes :func:`thrust_figure` to ``path``."""
    figure = thrust_figure(log, max_thrust)
    save_figure_atomic(figure, path, dpi=120)
    plt.close(figure)
    return path


def thrust_figure(log: dict[str, np.ndarray], max_thrust: float) -> Figure:
    """The thrusts (``log["thrust"]``, N×n) against ``±max_thrust``, with time at the limit.

    With ``saturation_ticks`` in the log (the controller's counts at its own rate), the title
    also gives the fraction of the controller's ticks whose wrench saturation scaled down.
    """
    time = np.asarray(log["time"])
    thrust = np.asarray(log["thrust"])
    n = thrust.shape[1]
    at_limit = np.abs(thrust) >= max_thrust * (1.0 - 1e-9)
    figure, axes = plt.subplots(
        n, 1, sharex=True, figsize=(9, 1.1 * n + 1.0), constrained_layout=True
    )
    for i, axis in enumerate(np.atleast_1d(axes)):
        axis.plot(time, thrust[:, i], color="tab:blue", lw=0.7)
        for limit in (-max_thrust, max_thrust):
            axis.axhline(limit, color="tab:red", lw=0.8, ls="--")
        axis.set_ylim(-1.15 * max_thrust, 1.15 * max_thrust)
        axis.set_ylabel(f"f{i} [N]", fontsize=8)
        axis.text(
            0.995,
            0.03,
            f"{100 * at_limit[:, i].mean():.1f} % at limit",
            transform=axis.transAxes,
            ha="right",
            va="bottom",
            fontsize=7,
        )
        axis.grid(True, alpha=0.3)
    np.atleast_1d(axes)[-1].set_xlabel("time [s]")
    title = (
        f"thrusts against ±{max_thrust:g} N: some thruster at its limit at "
        f"{100 * at_limit.any(axis=1).mean():.1f} % of the logged steps"
    )
    if "saturation_ticks" in log:
        ticks, force, moment, _ = np.asarray(log["saturation_ticks"])[-1]
        title += (
            f"; wrench scaled down at {100 * force / max(ticks, 1):.1f} % (force), "
            f"{100 * moment / max(ticks, 1):.1f} % (moment) of {ticks:.0f} controller ticks"
        )
    figure.suptitle(title, fontsize=9)
    return figure
