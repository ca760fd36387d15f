"""The navigation's errors against the truth over a run: the figure ``navigation``.

Built from a run's log, which holds the navigation's outputs (``p_WU_nav``, ``v_WU_nav``,
``R_WB_nav``) beside the truth (``p_WU``, ``v_WU``, ``R_WB``). Matplotlib runs on the Agg
backend.
"""

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from drake_uuv.analysis.vehicle_figures import roll_pitch_yaw  # noqa: E402
from drake_uuv.scenario import Scenario, describe  # noqa: E402

__all__ = ["navigation_errors", "navigation_figure"]

_COLORS = ("tab:red", "tab:green", "tab:blue")


def navigation_errors(log: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The navigation's errors per step (N×3 each): ``attitude``, roll-pitch-yaw of
    ``R_WB_nav`` less that of ``R_WB``, wrapped to [−π, π) [rad] (the AHRS's noise plus the
    heading bias on yaw, as the model adds them); ``velocity``, ``v_WU_nav − v_WU`` [m/s];
    ``position``, ``p_WU_nav − p_WU`` [m] (world frame)."""
    attitude = roll_pitch_yaw(log["R_WB_nav"]) - roll_pitch_yaw(log["R_WB"])
    return {
        "attitude": (attitude + np.pi) % (2.0 * np.pi) - np.pi,
        "velocity": np.asarray(log["v_WU_nav"]) - np.asarray(log["v_WU"]),
        "position": np.asarray(log["p_WU_nav"]) - np.asarray(log["p_WU"]),
    }


def navigation_figure(log: dict[str, np.ndarray], scenario: Scenario) -> Figure:
    """Attitude error (roll, pitch, yaw [deg]), velocity error and position error (x, y, z
    and the norm, world frame) against k: what the vehicle believes of itself, less the
    truth. The title gives the navigation's error figures (σ of each)."""
    errors = navigation_errors(log)
    k = np.asarray(log["k"])
    figure, axes = plt.subplots(3, 1, sharex=True, figsize=(8, 7.5), constrained_layout=True)
    for i, (name, color) in enumerate(zip(("roll", "pitch", "yaw"), _COLORS, strict=True)):
        axes[0].plot(k, np.degrees(errors["attitude"][:, i]), color=color, lw=0.7, label=name)
    axes[0].set_ylabel("attitude error [deg]")
    panels = (("velocity", "velocity error [m/s]"), ("position", "position error [m]"))
    for axis, (key, label) in zip(axes[1:], panels, strict=True):
        for i, (name, color) in enumerate(zip("xyz", _COLORS, strict=True)):
            axis.plot(k, errors[key][:, i], color=color, lw=0.7, label=name)
        axis.plot(k, np.linalg.norm(errors[key], axis=1), color="black", lw=1.0, label="norm")
        axis.set_ylabel(label)
    for axis in axes:
        axis.grid(True, alpha=0.3)
        axis.legend(ncol=4, fontsize=7, loc="upper left")
    axes[2].set_xlabel("step k")
    figures = scenario.navigation.error_figures()
    sigma = ", ".join(f"{np.degrees(s):g}" for s in figures.attitude_noise)
    figure.suptitle(
        f"{describe(scenario)}, seed {scenario.random_seed}\n{type(scenario.navigation).__name__}"
        f": σ attitude [{sigma}]°, heading bias {np.degrees(figures.heading_bias):g}°, DVL "
        f"{figures.velocity_noise:g} m/s, bias {figures.velocity_bias:g} m/s (σ)",
        fontsize=9,
    )
    return figure
