"""The paper's figures (§IV) and the consistency figures of one run or a Monte Carlo study.

Every figure of a run is built from its log (``SimulationResult.log``, the arrays of
``log.npz``) and its scenario; :mod:`drake_uuv.analysis.registry` names the files they are
written to:

* :func:`error_summary_figure`: estimation and tracking errors on a log scale, with the
  RMSEs of ``metrics.json`` over its window;
* :func:`error_figure`: estimation error (red) and tracking error (blue) against k, with
  insets zoomed on k = 200..250 (the paper's Fig. "error"), and the PCRLB along the run (black);
* :func:`trajectory_figure`: 3-D target trajectory (red line, red triangles), UUV trajectory,
  sonar s1 (blue stars) and s2 (green stars), and an inset of the UUV's attitude frames (the
  paper's Fig. "trajectory");
* :func:`excitation_figure`: λ_min and λ_max of Σ_{m=k}^{k+N−1} q_s q_sᵀ (paper eq. 10), N
  from ``analysis.pe_window``;
* :func:`nees_figure`: NEES against k with the χ²(6) 95 % band;
* :func:`~drake_uuv.analysis.navigation_figures.navigation_figure` (a navigation other than
  ``!PerfectNavigation``): the attitude, velocity and position errors of what the vehicle
  believes of itself against k;
* :func:`band_figure` (Monte Carlo): median and 5–95 % of the errors against k over runs, and
  the mean NEES over runs with its χ²(6M)/M band; with the Monte Carlo PCRLB, the RMS error over
  runs beside it.

Matplotlib runs on the Agg backend; figures are closed after saving. The 2-D figures use
Matplotlib's constrained layout, so labels and legends stay inside the figure whatever the
numbers, and titles are wrapped to the figure's width (:func:`fit_lines`).
"""

import textwrap
from collections.abc import Iterable, Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.ticker import FormatStrFormatter, LogLocator, NullFormatter  # noqa: E402

from drake_uuv.analysis.stats import nees_band  # noqa: E402
from drake_uuv.io import save_figure_atomic  # noqa: E402
from drake_uuv.metrics import bound_covariances, errors, rms_norm  # noqa: E402
from drake_uuv.models.information import excitation_eigenvalues  # noqa: E402
from drake_uuv.scenario import Scenario, describe  # noqa: E402

ESTIMATION_COLOR = "tab:red"
TRACKING_COLOR = "tab:blue"
BOUND_COLOR = "black"
TARGET_COLOR = "red"
S1_COLOR = "blue"
S2_COLOR = "green"
UUV_COLOR = "0.25"
# The paper's zoomed interval.
ZOOM = (200, 250)
FORMATS = ("png", "svg")
STATE_DIMENSION = 6
TITLE_SIZE = 9
# The mean advance of a character of DejaVu Sans, Matplotlib's default font, in ems (digits
# are 0.64 em, lower case about 0.55 em): how many characters a line of a given width holds.
CHARACTER_WIDTH_EM = 0.6


def save_figure(figure: Figure, stem: Path, formats: Iterable[str] = FORMATS) -> list[Path]:
    """Writes ``stem.png`` and ``stem.svg`` (atomically) and closes the figure."""
    stem = Path(stem)
    paths = []
    for fmt in formats:
        paths.append(save_figure_atomic(figure, stem.with_suffix(f".{fmt}"), dpi=120))
        # The layout is in figure fractions and points, the same for every format: laying
        # out once (a third of a figure's drawing time with constrained layout) suffices.
        if figure.get_layout_engine() is not None:
            figure.set_layout_engine("none")
    plt.close(figure)
    return paths


def fit_lines(lines: Sequence[str], width: float, fontsize: float = TITLE_SIZE) -> str:
    """``lines`` joined by newlines, each wrapped to ``width`` inches of text at ``fontsize``.

    A layout engine makes room for a title's height but not its width: a title wider than the
    figure is cut off at both sides, so it is wrapped here.
    """
    characters = max(20, int(width * 72.0 / (CHARACTER_WIDTH_EM * fontsize)))
    return "\n".join(textwrap.fill(line, characters) for line in lines if line)


def suptitle(figure: Figure, *lines: str) -> None:
    """The figure's title: ``lines``, each on its own line(s), fitted to the figure's width."""
    figure.suptitle(fit_lines(lines, 0.96 * figure.get_size_inches()[0]), fontsize=TITLE_SIZE)


def _readable_log_ticks(axis: plt.Axes, decades: float = 3.0) -> None:
    """Log y axis without minor labels, labelled at 1, 2, 5 × 10ⁿ in plain numbers while the
    data span at most ``decades`` decades, at the powers of ten beyond (where 1, 2, 5 would
    overlap). Call it once the data are drawn."""
    low, high = axis.get_ylim()
    if np.log10(high / low) <= decades:
        axis.yaxis.set_major_locator(LogLocator(base=10.0, subs=(1.0, 2.0, 5.0)))
        axis.yaxis.set_major_formatter(FormatStrFormatter("%g"))
    axis.yaxis.set_minor_formatter(NullFormatter())


def _title(scenario: Scenario) -> str:
    return f"{describe(scenario)}, seed {scenario.random_seed}"


def error_summary_figure(log: dict[str, np.ndarray], scenario: Scenario) -> Figure:
    """Estimation error |q − q̂|, |ϑ − ϑ̂| and tracking error |q − R q*| against k (log
    scale), with the RMSEs ``metrics.json`` reports over its window k ≥ steady_state_start."""
    e = errors(log, scenario)
    k = log["k"]
    start = scenario.steady_state_start
    figure, axes = plt.subplots(2, 1, sharex=True, figsize=(8, 5.5), layout="constrained")
    axes[0].semilogy(k, np.linalg.norm(e["position"], axis=1), color=ESTIMATION_COLOR, lw=1.0)
    axes[0].semilogy(
        k, np.linalg.norm(e["velocity"], axis=1), color=ESTIMATION_COLOR, lw=0.8, ls=":"
    )
    axes[0].set_ylabel("estimation error")
    axes[0].legend(["|q − q̂| [m]", "|ϑ − ϑ̂| [m/s]"], loc="upper right", fontsize=8)
    axes[1].semilogy(k, np.linalg.norm(e["tracking"], axis=1), color=TRACKING_COLOR, lw=1.0)
    axes[1].set_ylabel("tracking error |q − R q*| [m]")
    axes[1].set_xlabel("step k (dashed: the window's start)")
    for axis in axes:
        axis.axvline(start, color="0.6", lw=0.8, ls="--")
        axis.grid(True, which="both", alpha=0.3)
    window = slice(start, None)
    suptitle(
        figure,
        _title(scenario),
        f"over k ≥ {start}, the window of metrics.json: position RMSE "
        f"{rms_norm(e['position'][window]):.3f} m, tracking RMSE "
        f"{rms_norm(e['tracking'][window]):.3f} m",
    )
    return figure


def _zoom_window(steps: int) -> tuple[int, int] | None:
    """The paper's k = 200..250, clipped to the run; None if the run is too short."""
    start, end = ZOOM[0], min(ZOOM[1], steps - 1)
    return (start, end) if end - start >= 5 else None


def _add_zoom_inset(axis: plt.Axes, k: np.ndarray, series: Sequence[tuple], window) -> None:
    """An inset of ``axis`` showing ``series`` (``(values, kwargs)``) over k in ``window``."""
    start, end = window
    inset = axis.inset_axes([0.52, 0.48, 0.45, 0.45])
    selected = slice(start, end + 1)
    top = 0.0
    for values, kwargs in series:
        inset.plot(k[selected], values[selected], **kwargs)
        top = max(top, float(np.nanmax(values[selected])))
    inset.set_xlim(start, end)
    inset.set_ylim(0.0, 1.05 * top if np.isfinite(top) and top > 0 else 1.0)
    inset.tick_params(labelsize=7)
    inset.grid(True, alpha=0.3)
    axis.indicate_inset_zoom(inset, edgecolor="0.4")


def bound_curves(covs: np.ndarray) -> dict[str, np.ndarray]:
    """``position`` and ``velocity``: √trace of the 3×3 blocks of covariances (N×6×6), the
    RMS error a bound allows at each k."""
    covs = np.asarray(covs, dtype=float)
    return {
        "position": np.sqrt(np.trace(covs[:, :3, :3], axis1=1, axis2=2)),
        "velocity": np.sqrt(np.trace(covs[:, 3:, 3:], axis1=1, axis2=2)),
    }


def error_figure(log: dict[str, np.ndarray], scenario: Scenario) -> Figure:
    """Estimation error (red) and tracking error (blue) against k, insets on k = 200..250.

    Beside the estimation error, the PCRLB along this run's true trajectory (black, √trace of
    its position and velocity blocks: the RMS error no estimator can beat on average).
    """
    e = errors(log, scenario)
    k = log["k"]
    position = np.linalg.norm(e["position"], axis=1)
    velocity = np.linalg.norm(e["velocity"], axis=1)
    tracking = np.linalg.norm(e["tracking"], axis=1)
    bound = bound_curves(bound_covariances(log, scenario)["pcrlb"])
    figure, axes = plt.subplots(2, 1, sharex=True, figsize=(8, 6), layout="constrained")
    estimation_series = [
        (position, dict(color=ESTIMATION_COLOR, lw=1.0, label="|q − q̂| [m]")),
        (velocity, dict(color=ESTIMATION_COLOR, lw=0.8, ls=":", label="|ϑ − ϑ̂| [m/s]")),
        (bound["position"], dict(color=BOUND_COLOR, lw=0.9, ls="--", label="PCRLB, position")),
        (bound["velocity"], dict(color=BOUND_COLOR, lw=0.8, ls=":", label="PCRLB, velocity")),
    ]
    tracking_series = [(tracking, dict(color=TRACKING_COLOR, lw=1.0, label="|q − R q*| [m]"))]
    window = _zoom_window(len(k))
    for axis, series, label in (
        (axes[0], estimation_series, "estimation error"),
        (axes[1], tracking_series, "tracking error"),
    ):
        for values, kwargs in series:
            axis.plot(k, values, **kwargs)
        axis.set_ylabel(label)
        axis.set_ylim(bottom=0.0)
        axis.grid(True, alpha=0.3)
        axis.legend(loc="upper left", fontsize=8)
        if window is not None:
            _add_zoom_inset(axis, k, series, window)
    axes[1].set_xlabel("step k")
    suptitle(figure, _title(scenario), "estimation error against the PCRLB of this run")
    return figure


def sensor_positions(log: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """World positions of the sonars: ``s1 = p + ½ q_s``, ``s2 = p − ½ q_s`` (N×3 each)."""
    half = 0.5 * log["b_W"]
    return log["p_WU"] + half, log["p_WU"] - half


def _equal_aspect(axis, points: np.ndarray) -> None:
    low, high = np.nanmin(points, axis=0), np.nanmax(points, axis=0)
    centre, half = 0.5 * (low + high), 0.5 * max(float(np.max(high - low)), 1e-3)
    axis.set_xlim(centre[0] - half, centre[0] + half)
    axis.set_ylim(centre[1] - half, centre[1] + half)
    axis.set_zlim(centre[2] - half, centre[2] + half)
    axis.set_box_aspect((1, 1, 1))


def trajectory_figure(
    log: dict[str, np.ndarray],
    scenario: Scenario,
    window: tuple[int, int] | None = None,
    marker_every: int = 2,
    frames: int = 8,
) -> Figure:
    """The paper's trajectory figure over steps ``window`` (default k = 200..250).

    Target: red line, red triangles every ``marker_every`` steps. UUV: grey line. Sonars: s1
    blue stars, s2 green stars. The inset draws the UUV's attitude at ``frames`` consecutive
    steps from the window's start (see :func:`_attitude_inset`).
    """
    steps = len(log["k"])
    if window is None:
        window = _zoom_window(steps) or (0, steps - 1)
    start, end = max(0, window[0]), min(steps - 1, window[1])
    selected = slice(start, end + 1)
    marks = slice(start, end + 1, marker_every)
    target, uuv = log["p_WT"], log["p_WU"]
    s1, s2 = sensor_positions(log)

    figure = plt.figure(figsize=(10, 7))
    # Placed by hand: Matplotlib's layout engines do not lay out 3-D axes.
    axis = figure.add_axes([0.02, 0.02, 0.58, 0.86], projection="3d")
    axis.plot(*target[selected].T, color=TARGET_COLOR, lw=1.2, label="target")
    axis.scatter(*target[marks].T, color=TARGET_COLOR, marker="^", s=18, depthshade=False)
    axis.plot(*uuv[selected].T, color=UUV_COLOR, lw=0.8, label="UUV")
    axis.scatter(*s1[marks].T, color=S1_COLOR, marker="*", s=30, depthshade=False, label="s1")
    axis.scatter(*s2[marks].T, color=S2_COLOR, marker="*", s=30, depthshade=False, label="s2")
    _equal_aspect(axis, np.concatenate([target[selected], s1[selected], s2[selected]]))
    axis.set_xlabel("x [m]")
    axis.set_ylabel("y [m]")
    axis.set_zlabel("z [m]")
    axis.legend(loc="upper left", fontsize=8)
    suptitle(figure, _title(scenario), f"target, UUV and sonars over k = {start}..{end}")

    _attitude_inset(figure.add_axes([0.58, 0.45, 0.4, 0.42], projection="3d"), log, start, frames)
    return figure


def _attitude_inset(axis, log: dict[str, np.ndarray], start: int, frames: int) -> None:
    """Body frames R(k) (x red, y green, z blue) and the sonar baseline (s1 blue star, s2 green
    star) for ``frames`` steps from ``start``, laid out on a grid (two rows, read left to right)
    rather than at the UUV's positions, where they would overlap: the inset shows how the
    attitude changes from step to step.
    """
    R_WB, q_s = log["R_WB"], log["b_W"]
    indices = list(range(start, min(len(R_WB), start + frames)))
    columns = max(1, (len(indices) + 1) // 2)
    rows = (len(indices) + columns - 1) // columns
    length = 0.5 * float(np.max(np.linalg.norm(q_s[indices], axis=1)))
    spacing = 2.4 * length
    for slot, j in enumerate(indices):
        origin = np.array([(slot % columns) * spacing, 0.0, -(slot // columns) * spacing])
        for column, color in enumerate(("red", "green", "blue")):
            axis.plot(*np.stack([origin, origin + length * R_WB[j][:, column]]).T, color=color)
        s1, s2 = origin + 0.5 * q_s[j], origin - 0.5 * q_s[j]
        axis.plot(*np.stack([s1, s2]).T, color="0.3", lw=0.8, ls="--")
        axis.scatter(*s1, color=S1_COLOR, marker="*", s=25, depthshade=False)
        axis.scatter(*s2, color=S2_COLOR, marker="*", s=25, depthshade=False)
        axis.text(*(origin + [0.0, 0.0, 1.1 * length]), f"k={j}", fontsize=6, ha="center")
    width = (columns - 1) * spacing + 2.0 * length
    height = (rows - 1) * spacing + 2.4 * length
    axis.set_xlim(-length, width - length)
    axis.set_ylim(-length, length)
    axis.set_zlim(-(rows - 1) * spacing - length, 1.4 * length)
    axis.set_box_aspect((width, 2.0 * length, height))
    axis.set_axis_off()
    axis.view_init(elev=12, azim=-80)
    axis.set_title(
        "UUV attitude R(k): body x, y, z (red, green, blue)\nand the baseline s1–s2", fontsize=8
    )


def excitation_figure(log: dict[str, np.ndarray], scenario: Scenario) -> Figure:
    """λ_min and λ_max of the windowed Σ q_s q_sᵀ (persistent excitation, paper eq. 10)."""
    n = scenario.analysis.pe_window
    low, high = excitation_eigenvalues(log["b_W"], n)
    xi2 = float(np.dot(scenario.sonar.baseline, scenario.sonar.baseline))
    figure, axis = plt.subplots(figsize=(8, 4), layout="constrained")
    k = np.arange(len(low))
    axis.plot(k, high, color="tab:purple", lw=1.0, label="λ_max")
    axis.plot(k, low, color="tab:orange", lw=1.0, label="λ_min")
    axis.axhline(n * xi2, color="0.4", ls="--", lw=0.8, label="N|b|² (upper bound)")
    axis.axhline(n * xi2 / 3.0, color="0.4", ls=":", lw=0.8, label="N|b|²/3 (isotropic)")
    axis.set_ylim(bottom=0.0, top=1.1 * n * xi2)
    axis.set_xlabel("window start k")
    axis.set_ylabel(f"eigenvalue of Σ q_s q_sᵀ,\nN = {n} steps [m²]")
    axis.grid(True, alpha=0.3)
    axis.legend(fontsize=8, loc="center right")
    worst = float(np.min(low)) if len(low) else float("nan")
    suptitle(
        figure, _title(scenario), f"persistent excitation: min over k of λ_min = {worst:.3g} m²"
    )
    return figure


def nees_figure(log: dict[str, np.ndarray], scenario: Scenario) -> Figure:
    """NEES against k with the χ²(6) 95 % band and the steady-state mean."""
    nees = errors(log, scenario)["nees"]
    k = log["k"]
    low, high = nees_band(STATE_DIMENSION, 1)
    start = scenario.steady_state_start
    steady = nees[start:]
    inside = float(np.mean((steady >= low) & (steady <= high)))
    figure, axis = plt.subplots(figsize=(8, 4), layout="constrained")
    axis.axhspan(low, high, color="tab:green", alpha=0.15, label="χ²(6) 95 % band")
    axis.semilogy(k, np.maximum(nees, 1e-6), color="tab:blue", lw=0.6, label="NEES")
    axis.axhline(STATE_DIMENSION, color="tab:green", lw=0.8, ls="--", label="6 (consistent)")
    axis.hlines(
        float(np.mean(steady)), start, k[-1], color="black", lw=1.2, label=f"mean, k ≥ {start}"
    )
    _readable_log_ticks(axis)
    axis.axvline(start, color="0.6", lw=0.8, ls="--")
    axis.set_xlabel("step k")
    axis.set_ylabel("NEES eᵀP⁻¹e")
    axis.grid(True, which="both", alpha=0.3)
    axis.legend(fontsize=8, loc="upper right")
    suptitle(
        figure,
        _title(scenario),
        f"over k ≥ {start}, the window of metrics.json: mean NEES {np.mean(steady):.2f}, "
        f"{100 * inside:.0f} % inside [{low:.2f}, {high:.2f}]",
    )
    return figure


def band_figure(
    norms: dict[str, np.ndarray],
    scenario: Scenario,
    title: str = "",
    bounds: dict[str, np.ndarray] | None = None,
) -> Figure:
    """Monte Carlo bands: median and 5–95 % of each error norm against k, and the mean NEES.

    ``norms`` maps ``position``, ``velocity``, ``tracking`` and ``nees`` to (runs × steps)
    arrays, as collected by :mod:`drake_uuv.studies.runner`. ``bounds`` (optional) maps
    ``position`` and ``velocity`` to the per-step bound (:func:`bound_curves` of the Monte
    Carlo PCRLB), drawn in black beside the RMS error over runs (dashed), its like.
    """
    runs, steps = norms["position"].shape
    k = np.arange(steps)
    panels = [
        ("position", "|q − q̂| [m]", ESTIMATION_COLOR),
        ("velocity", "|ϑ − ϑ̂| [m/s]", ESTIMATION_COLOR),
        ("tracking", "|q − R q*| [m]", TRACKING_COLOR),
    ]
    figure, axes = plt.subplots(4, 1, sharex=True, figsize=(8, 9), layout="constrained")
    for axis, (key, label, color) in zip(axes, panels, strict=False):
        values = np.asarray(norms[key], dtype=float)
        low, median, high = np.nanpercentile(values, [5, 50, 95], axis=0)
        axis.fill_between(k, low, high, color=color, alpha=0.25, lw=0, label="5–95 %")
        axis.plot(k, median, color=color, lw=1.0, label="median")
        if bounds is not None and key in bounds:
            rms = np.sqrt(np.nanmean(values * values, axis=0))
            axis.plot(k, rms, color=color, lw=0.9, ls="--", label="RMS over runs")
            axis.plot(k, bounds[key], color=BOUND_COLOR, lw=1.0, label="PCRLB")
        axis.set_yscale("log")
        _readable_log_ticks(axis)
        axis.set_ylabel(label)
        axis.grid(True, which="both", alpha=0.3)
        axis.legend(fontsize=8, loc="upper right")
    mean_nees = np.nanmean(np.asarray(norms["nees"], dtype=float), axis=0)
    low, high = nees_band(STATE_DIMENSION, runs)
    axes[3].axhspan(low, high, color="tab:green", alpha=0.2, label=f"χ²(6·{runs})/{runs} 95 %")
    axes[3].plot(k, mean_nees, color="tab:blue", lw=0.8, label=f"mean NEES over {runs} runs")
    axes[3].axhline(STATE_DIMENSION, color="tab:green", lw=0.8, ls="--")
    axes[3].set_ylabel("NEES")
    axes[3].set_xlabel("step k")
    axes[3].grid(True, which="both", alpha=0.3)
    axes[3].legend(fontsize=8, loc="upper right")
    for axis in axes:
        axis.axvline(scenario.steady_state_start, color="0.6", lw=0.8, ls="--")
    seeds = f"seeds {scenario.random_seed}..{scenario.random_seed + runs - 1}"
    default = f"{runs} runs: {_title(scenario).rsplit(', seed', 1)[0]}, {seeds}"
    suptitle(figure, title or default)
    return figure
