"""Every figure the package writes, drawn from short runs and a small study: each has its own
file name, and no text (titles, labels, tick labels, legends) falls outside the figure.

The figures come from the registry (:mod:`drake_uuv.analysis.registry`), and each run figure
from a run of its own ``example`` scenario, so a figure added there is checked here with no
edit to this file; a function of ``drake_uuv.analysis`` or ``drake_uuv.studies`` returning a
figure that no registry entry draws fails :func:`test_every_figure_function_is_registered`.
"""

import importlib
import inspect
import pkgutil
import typing
from collections.abc import Iterator
from contextlib import contextmanager

import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.figure import Figure
from matplotlib.legend import Legend
from matplotlib.text import Text

import drake_uuv.analysis
import drake_uuv.studies
from drake_uuv.analysis.figures import fit_lines
from drake_uuv.analysis.registry import (
    RUN_FIGURES,
    STUDY_FIGURES,
    write_run_figures,
    write_study_figures,
)
from drake_uuv.scenario import load_scenario
from drake_uuv.simulation import simulate
from drake_uuv.studies import NORMS, Study, run_study

DPI = 120  # save_figure's
# Long enough for the paper's k = 200..250 insets; the short run has none and a window of 1.
LENGTHS = {
    "long": ["steps=260", "steady_state_start=100"],
    "short": ["steps=12", "steady_state_start=11"],
}
EXAMPLE_LENGTH = ["steps=30", "steady_state_start=10"]  # runs of a figure's `example`
EXAMPLES = sorted({entry.example for entry in RUN_FIGURES if entry.example})


@pytest.fixture(scope="module")
def logs() -> dict[tuple[str, ...], dict]:
    """A log of every run the figures are drawn from: the paper scenario at both lengths,
    and each distinct ``example`` of the registry, keyed by their overrides."""
    runs = {(name,): load_scenario("paper", overrides) for name, overrides in LENGTHS.items()}
    runs.update({e: load_scenario("paper", [*e, *EXAMPLE_LENGTH]) for e in EXAMPLES})
    return {key: simulate(scenario) for key, scenario in runs.items()}


@pytest.fixture(scope="module")
def study(tmp_path_factory) -> tuple:
    """A small study's norms, scenario and Monte Carlo bound curves (no figure written)."""
    from drake_uuv.analysis.figures import bound_curves
    from drake_uuv.studies import monte_carlo_bound

    scenario = load_scenario("paper", ["steps=40", "steady_state_start=10"])
    folder = tmp_path_factory.mktemp("study")
    result = run_study(Study("small", scenario, 4, folder), workers=1, progress=False)
    norms = dict(zip(NORMS, np.moveaxis(result.norms, 1, 0), strict=True))
    information = drake_uuv.studies.load_information(result.study)
    bounds = bound_curves(monte_carlo_bound(information, 4, scenario))
    return norms, scenario, bounds


@contextmanager
def _recording_drawn_text() -> Iterator[list]:
    """Records every text and legend Matplotlib actually draws (a hidden axis draws none),
    with its box measured as it is drawn (a 3-D text is projected only while drawn)."""
    drawn: list = []
    originals = {cls: cls.draw for cls in (Text, Legend)}

    def recorder(cls):
        def draw(self, renderer, *args, **kwargs):
            result = originals[cls](self, renderer, *args, **kwargs)
            if self.get_visible() and (not isinstance(self, Text) or self.get_text().strip()):
                label = self.get_text() if isinstance(self, Text) else "a legend"
                drawn.append((label, self.get_window_extent(renderer)))
            return result

        return draw

    try:
        for cls in originals:
            cls.draw = recorder(cls)
        yield drawn
    finally:
        for cls, draw in originals.items():
            cls.draw = draw


def _text_outside(figure: Figure) -> list[str]:
    """The drawn texts and legends whose box leaves the figure, by their text, at its dpi."""
    figure.set_dpi(DPI)
    with _recording_drawn_text() as drawn:
        figure.canvas.draw()
    assert drawn, "nothing drawn"
    box = figure.bbox
    return [
        f"{label!r} at {np.round(extent.extents)} (figure {box.extents})"
        for label, extent in drawn
        if extent.x0 < box.x0 - 0.5
        or extent.y0 < box.y0 - 0.5
        or extent.x1 > box.x1 + 0.5
        or extent.y1 > box.y1 + 0.5
    ]


def _run_cases() -> list:
    cases = []
    for entry in RUN_FIGURES:
        keys = [entry.example] if entry.example else [(name,) for name in LENGTHS]
        cases += [pytest.param(entry, key, id=f"{entry.name}-{'-'.join(key)}") for key in keys]
    return cases


@pytest.mark.filterwarnings("error::UserWarning")  # a missing glyph, a layout that failed
@pytest.mark.parametrize(("entry", "key"), _run_cases())
@pytest.mark.slow
def test_run_figure_keeps_every_text_inside(entry, key, logs) -> None:
    result = logs[key]
    assert entry.applies(result.log), f"{entry.name}: its example logs none of {entry.needs}"
    figure = entry.draw(result.log, result.scenario)
    try:
        assert not _text_outside(figure), f"{entry.name}: text outside the figure"
    finally:
        plt.close(figure)


@pytest.mark.filterwarnings("error::UserWarning")
@pytest.mark.parametrize("entry", STUDY_FIGURES, ids=lambda entry: entry.name)
@pytest.mark.slow
def test_study_figure_keeps_every_text_inside(entry, study) -> None:
    norms, scenario, bounds = study
    figure = entry.draw(norms, scenario, bounds=bounds)
    try:
        assert not _text_outside(figure), f"{entry.name}: text outside the figure"
    finally:
        plt.close(figure)


def test_a_title_wider_than_the_figure_is_caught_and_fit_lines_wraps_it() -> None:
    """The check fails where it should (an unwrapped title of 300 characters), and the same
    title through ``fit_lines`` passes."""
    title = ", ".join(["KinematicUuv, PaperKf (derived)"] * 10)
    for text, clipped in ((title, True), (fit_lines([title], 0.96 * 6), False)):
        figure, axis = plt.subplots(figsize=(6, 3), layout="constrained")
        axis.plot([0, 1], [0, 1])
        figure.suptitle(text, fontsize=9)
        assert bool(_text_outside(figure)) is clipped
        plt.close(figure)


def test_every_file_name_is_unique() -> None:
    names = [entry.name for entry in (*RUN_FIGURES, *STUDY_FIGURES)]
    assert len(names) == len(set(names)), names
    assert not {"log", "metrics", "runs", "summary"} & set(names)


def _figure_functions() -> Iterator[tuple[str, object]]:
    """Every function of a module of ``drake_uuv.analysis`` or ``drake_uuv.studies`` whose
    return annotation is a matplotlib ``Figure``."""
    for package in (drake_uuv.analysis, drake_uuv.studies):
        for info in pkgutil.iter_modules(package.__path__, f"{package.__name__}."):
            module = importlib.import_module(info.name)
            for name, function in inspect.getmembers(module, inspect.isfunction):
                if function.__module__ != module.__name__:
                    continue
                if typing.get_type_hints(function).get("return") is Figure:
                    yield f"{module.__name__}.{name}", function


def test_every_figure_function_is_registered() -> None:
    found = dict(_figure_functions())
    # The search finds figures in both packages' modules (the study's is drawn in analysis).
    assert {"drake_uuv.analysis.figures.error_figure", "drake_uuv.analysis.figures.band_figure",
            "drake_uuv.analysis.vehicle_figures.thrust_figure"} <= set(found)  # fmt: skip
    drawn = {entry.draw for entry in (*RUN_FIGURES, *STUDY_FIGURES)}
    missing = [name for name, function in found.items() if function not in drawn]
    assert not missing, f"figures no entry of drake_uuv/analysis/registry.py draws: {missing}"


@pytest.mark.slow
def test_write_functions_write_every_registered_file(logs, study, tmp_path) -> None:
    """A run writes each figure its log has signals for, a study each study figure, every
    format, under the file names of the registry and nothing else."""
    written = set()
    for key in [("long",), *EXAMPLES]:
        result, out = logs[key], tmp_path / "-".join(key)
        paths = write_run_figures(result.log, result.scenario, out)
        written |= {p.relative_to(out).as_posix() for p in paths}
        assert all(p.stat().st_size > 5_000 for p in paths)
        assert sorted(p for p in out.rglob("*") if p.is_file()) == sorted(paths)
    expected = {
        f"{entry.folder}/{entry.name}.{fmt}".lstrip("/")
        for entry in RUN_FIGURES
        for fmt in entry.formats
    }
    assert written == expected
    norms, scenario, bounds = study
    paths = write_study_figures(norms, scenario, tmp_path / "study", bounds=bounds)
    assert sorted(p.name for p in paths) == sorted(
        f"{entry.name}.{fmt}" for entry in STUDY_FIGURES for fmt in entry.formats
    )
