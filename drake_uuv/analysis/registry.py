"""Every figure the package writes, by file name: the registry of figure writers.

:data:`RUN_FIGURES` lists the figures of one run (``drake-uuv run``), each drawn from the run's
log and scenario; :data:`STUDY_FIGURES` those of a Monte Carlo study (``drake-uuv
montecarlo``), drawn from its error norms over runs. Each entry names its file (unique across
both lists), says in one line what it shows, and, for a figure that needs signals only some
runs log, which they are and a scenario that logs them.

To add a figure: a function ``name_figure(log, scenario) -> Figure`` in
``drake_uuv/analysis/`` and one line here. ``tests/analysis/test_figure_registry.py`` then
draws it from a short run of its ``example`` scenario and checks that no text falls outside
the figure; it also fails on a function of ``drake_uuv.analysis`` or ``drake_uuv.studies``
returning a figure that no entry draws.
"""

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from drake_uuv.analysis.figures import (
    FORMATS,
    band_figure,
    error_figure,
    error_summary_figure,
    excitation_figure,
    nees_figure,
    save_figure,
    trajectory_figure,
)
from drake_uuv.analysis.navigation_figures import navigation_figure
from drake_uuv.analysis.vehicle_figures import attitude_tracking_figure, thrust_figure
from drake_uuv.scenario import PerfectNavigation, Scenario

Log = Mapping[str, np.ndarray]

__all__ = [
    "RUN_FIGURES",
    "STUDY_FIGURES",
    "RunFigure",
    "StudyFigure",
    "write_run_figures",
    "write_study_figures",
]


@dataclass(frozen=True)
class RunFigure:
    """A figure of one run, written as ``<out>/<folder>/<name>.<format>`` for each format.

    ``draw(log, scenario)`` makes it; a run whose log lacks any of ``needs``, or whose
    scenario ``when`` refuses, does not get it. ``example`` is a list of ``--set`` overrides of
    the paper scenario whose runs get it: the tests draw the figure from such a run.
    """

    name: str
    draw: Callable[[Log, Scenario], Figure]
    description: str
    needs: tuple[str, ...] = ()
    example: tuple[str, ...] = ()
    folder: str = "figures"
    formats: tuple[str, ...] = FORMATS
    when: Callable[[Scenario], bool] | None = None

    def applies(self, log: Log, scenario: Scenario | None = None) -> bool:
        """Whether ``log`` has every signal this figure needs (and ``scenario`` wants it)."""
        if self.when is not None and scenario is not None and not self.when(scenario):
            return False
        return all(key in log for key in self.needs)


@dataclass(frozen=True)
class StudyFigure:
    """A figure of a Monte Carlo study, written as ``<out>/<folder>/<name>.<format>``.

    ``draw(norms, scenario, bounds=...)`` makes it from the per-step error norms over runs
    (``position``, ``velocity``, ``tracking``, ``nees``: runs × steps each) and, when the
    study has them, the Monte Carlo bound's ``position`` and ``velocity`` curves.
    """

    name: str
    draw: Callable[..., Figure]
    description: str
    folder: str = "figures"
    formats: tuple[str, ...] = FORMATS


_HOVERING = ("plant=!HoveringAuv",)

#: The figures of one run, in the order they are written.
RUN_FIGURES: tuple[RunFigure, ...] = (
    RunFigure(
        "error_summary",
        error_summary_figure,
        "estimation and tracking errors (log scale), the RMSEs of metrics.json",
        folder="",
        formats=("png",),
    ),
    RunFigure(
        "errors_vs_pcrlb",
        error_figure,
        "the paper's error figure: errors, insets on k = 200..250, this run's PCRLB",
    ),
    RunFigure("trajectory_3d", trajectory_figure, "the paper's trajectory figure, attitude inset"),
    RunFigure("excitation_eigenvalues", excitation_figure, "persistent excitation of the baseline"),
    RunFigure("nees_per_step", nees_figure, "NEES against k, its χ²(6) band"),
    RunFigure(
        "vehicle_attitude",
        attitude_tracking_figure,
        "commanded against achieved attitude and rate",
        needs=("R_WB_command", "w_WB", "w_WB_command"),
        example=_HOVERING,
    ),
    RunFigure(
        "navigation_errors",
        navigation_figure,
        "what the vehicle believes of its attitude, velocity and position, less the truth",
        needs=("p_WU_nav", "v_WU_nav", "R_WB_nav"),
        example=("navigation=InertialNavigation", "tracking=LqrTracking"),
        when=lambda scenario: not isinstance(scenario.navigation, PerfectNavigation),
    ),
    RunFigure(
        "vehicle_thrusts",
        thrust_figure,
        "thrusts against their limits",
        needs=("thrust",),
        example=_HOVERING,
    ),
)

#: The figures of a Monte Carlo study.
STUDY_FIGURES: tuple[StudyFigure, ...] = (
    StudyFigure(
        "error_bands",
        band_figure,
        "median and 5–95 % of the errors over runs, RMS against the PCRLB, mean NEES",
    ),
)


def write_run_figures(
    log: Log, scenario: Scenario, out: Path, formats: Iterable[str] | None = None
) -> list[Path]:
    """Writes the figures of one run under ``out`` (the run's folder); returns the paths.

    ``formats`` replaces each entry's formats (e.g. ``("png",)``, quicker).
    """
    paths: list[Path] = []
    for entry in RUN_FIGURES:
        if entry.applies(log, scenario):
            stem = Path(out) / entry.folder / entry.name
            paths += save_figure(entry.draw(log, scenario), stem, formats or entry.formats)
    return paths


def write_study_figures(
    norms: Mapping[str, np.ndarray],
    scenario: Scenario,
    out: Path,
    bounds: Mapping[str, np.ndarray] | None = None,
) -> list[Path]:
    """Writes the figures of a study under ``out`` (the study's folder); returns the paths."""
    paths: list[Path] = []
    for entry in STUDY_FIGURES:
        figure = entry.draw(dict(norms), scenario, bounds=bounds)
        paths += save_figure(figure, Path(out) / entry.folder / entry.name, entry.formats)
    return paths
