"""Figures of the thruster-driven vehicle: attitude tracking and thrusts against their limits.

Both take a log dict keyed by port names (``log["thrust"]`` N×8, ``log["R_WB"]`` N×9, …) plus
``log["time"]`` (N), one row per logged sample, as ``LogVectorOutput`` records them (the value
at a time before that time's discrete updates), and the run's scenario, like every figure of a
run (:mod:`drake_uuv.analysis.registry`). Matplotlib runs on the Agg backend.
"""

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from drake_uuv.analysis.figures import suptitle  # noqa: E402
from drake_uuv.models.so3 import log_so3  # noqa: E402
from drake_uuv.scenario import Scenario  # noqa: E402

__all__ = [
    "attitude_errors",
    "attitude_tracking_figure",
    "roll_pitch_yaw",
    "thrust_figure",
    "wrap_angles",
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


def wrap_angles(
    time: np.ndarray, commanded: np.ndarray, achieved: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(time, commanded, achieved)`` to plot: ``commanded`` wrapped to [−π, π), and each
    ``achieved`` angle within π of its commanded one, so that their gap on the plot is the
    difference of the angles, never 2π more.

    Where a commanded angle wraps, a NaN row is inserted in all three so that the plot breaks
    its lines there instead of drawing a jump across the panel.
    """
    commanded = (np.asarray(commanded, dtype=float) + np.pi) % (2.0 * np.pi) - np.pi
    gap = (np.asarray(achieved, dtype=float) - commanded + np.pi) % (2.0 * np.pi) - np.pi
    breaks = np.flatnonzero(np.abs(np.diff(commanded)) > np.pi) + 1
    return tuple(
        np.insert(np.asarray(values, dtype=float), breaks, np.nan)
        for values in (time, commanded, commanded + gap)
    )


def attitude_tracking_figure(log: dict[str, np.ndarray], scenario: Scenario) -> Figure:
    """Commanded against achieved attitude and angular rate.

    Needs ``time``, ``R_WB``, ``R_WB_command``, ``w_WB`` and ``w_WB_command``, logged at the
    outer period t: row k then holds the attitude reached at kt and the target ``R(k)`` set
    at step k − 1, and the rate ``u2`` that was in force over the step before. Top: roll,
    pitch and yaw of both, wrapped (:func:`wrap_angles`). Middle: the attitude error angle at
    each tick. Bottom: the world angular velocity, commanded (steps) and achieved. The title's
    mean and peak error are over the window of ``metrics.json``, k ≥ steady_state_start
    (right of the dashed line), as its ``attitude_error_mean`` and ``_peak`` are.
    """
    time = np.asarray(log["time"])
    achieved = roll_pitch_yaw(log["R_WB"])
    commanded = roll_pitch_yaw(log["R_WB_command"])
    error = attitude_errors(log)
    start = scenario.steady_state_start
    figure, axes = plt.subplots(3, 1, sharex=True, figsize=(9, 7.5), layout="constrained")
    colors = ("tab:red", "tab:green", "tab:blue")
    for i, (name, color) in enumerate(zip(("roll", "pitch", "yaw"), colors, strict=True)):
        shown_time, shown_command, shown = wrap_angles(time, commanded[:, i], achieved[:, i])
        axes[0].plot(
            shown_time, shown_command, color=color, lw=1.6, alpha=0.45, label=f"{name} cmd"
        )
        axes[0].plot(shown_time, shown, color=color, lw=0.8, label=name)
    axes[0].set_ylim(-1.15 * np.pi, 1.15 * np.pi)
    axes[0].set_yticks(
        np.pi * np.array([-1.0, -0.5, 0.0, 0.5, 1.0]), ["−π", "−π/2", "0", "π/2", "π"]
    )
    axes[0].set_ylabel("attitude [rad]")
    axes[0].legend(ncol=6, fontsize=7, loc="upper left")
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
    axes[2].legend(ncol=6, fontsize=7, loc="upper left")
    for axis in axes:
        axis.grid(True, which="both", alpha=0.3)
        if start < len(time):
            axis.axvline(time[start], color="0.5", lw=0.8, ls="--")
    window = error[start:]
    summary = (
        f"mean {window.mean():.3g} rad, peak {window.max():.3g} rad"
        if len(window)
        else "no tick in it"
    )
    suptitle(
        figure,
        f"attitude error over k ≥ {start}, metrics.json's window (right of the dashed "
        f"line): {summary}",
        "roll, pitch, yaw wrapped to ±π, each achieved angle within π of its command",
    )
    return figure


def thrust_figure(log: dict[str, np.ndarray], scenario: Scenario) -> Figure:
    """The thrusts (``log["thrust"]``, N×n) against ``±scenario.plant.max_thrust``, with the
    time each spends at the limit.

    With ``saturation_ticks`` in the log (the controller's counts at its own rate), the title
    also gives the fraction of the controller's ticks whose wrench saturation scaled down.
    """
    max_thrust = scenario.plant.max_thrust
    time = np.asarray(log["time"])
    thrust = np.asarray(log["thrust"])
    n = thrust.shape[1]
    at_limit = np.abs(thrust) >= max_thrust * (1.0 - 1e-9)
    figure, axes = plt.subplots(n, 1, sharex=True, figsize=(9, 1.1 * n + 1.3), layout="constrained")
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
    lines = [
        f"thrusts against ±{max_thrust:g} N (dashed): some thruster at its limit at "
        f"{100 * at_limit.any(axis=1).mean():.1f} % of the logged steps"
    ]
    if "saturation_ticks" in log:
        ticks, force, moment, _ = np.asarray(log["saturation_ticks"])[-1]
        lines.append(
            f"wrench scaled down at {100 * force / max(ticks, 1):.1f} % (force), "
            f"{100 * moment / max(ticks, 1):.1f} % (moment) of the {ticks:.0f} controller ticks "
            "of the whole run"
        )
    suptitle(figure, *lines)
    return figure
