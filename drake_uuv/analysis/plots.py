"""Figures of one run (matplotlib, Agg backend)."""

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from drake_uuv.io import save_figure_atomic  # noqa: E402
from drake_uuv.metrics import errors  # noqa: E402
from drake_uuv.scenario import describe  # noqa: E402
from drake_uuv.simulation import SimulationResult  # noqa: E402


def plot_errors(result: SimulationResult, path: Path) -> Path:
    """Estimation error |q − q̂| and tracking error |q − R q*| against k (log scale)."""
    e = errors(result.log, result.scenario)
    k = result.log["k"]
    figure, axes = plt.subplots(2, 1, sharex=True, figsize=(8, 5.5), constrained_layout=True)
    axes[0].semilogy(k, np.linalg.norm(e["position"], axis=1), color="tab:red", lw=1.0)
    axes[0].semilogy(
        k, np.linalg.norm(e["velocity"], axis=1), color="tab:red", lw=0.8, ls=":", alpha=0.8
    )
    axes[0].set_ylabel("estimation error")
    axes[0].legend(["|q − q̂| [m]", "|ϑ − ϑ̂| [m/s]"], loc="upper right")
    axes[1].semilogy(k, np.linalg.norm(e["tracking"], axis=1), color="tab:blue", lw=1.0)
    axes[1].set_ylabel("tracking error |q − R q*| [m]")
    axes[1].set_xlabel("step k")
    start = result.scenario.steady_state_start
    for axis in axes:
        axis.axvline(start, color="0.6", lw=0.8, ls="--")
        axis.grid(True, which="both", alpha=0.3)
    m = result.metrics
    figure.suptitle(
        f"{describe(result.scenario)}, seed {result.scenario.random_seed}: position RMSE "
        f"{m['position_rmse']:.3f} m, tracking RMSE {m['tracking_rmse']:.3f} m (k ≥ {start})",
        fontsize=9,
    )
    save_figure_atomic(figure, path, dpi=120)
    plt.close(figure)
    return path
