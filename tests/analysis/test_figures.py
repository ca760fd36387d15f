"""The paper's figures: written as PNG and SVG, with content, from one short run (the file
names are the registry's, drake_uuv/analysis/registry.py)."""

import xml.etree.ElementTree as ElementTree
from pathlib import Path

import matplotlib.image
import matplotlib.pyplot as plt
import numpy as np
import pytest

from drake_uuv.analysis.figures import excitation_eigenvalues, sensor_positions
from drake_uuv.analysis.registry import RUN_FIGURES, write_run_figures
from drake_uuv.cli import main
from drake_uuv.scenario import load_scenario
from drake_uuv.simulation import simulate

# The figures of a run of the paper's kinematic vehicle, relative to the run's folder.
STEMS = tuple(f"{e.folder}/{e.name}".lstrip("/") for e in RUN_FIGURES if not e.needs)


@pytest.fixture(scope="module")
def run():
    """A run long enough for the paper's k = 200..250 inset."""
    return simulate(load_scenario("paper", ["steps=260", "steady_state_start=100"]))


def _pixels(path: Path) -> np.ndarray:
    image = matplotlib.image.imread(path)
    return image[..., :3]


def _ink_fraction(path: Path) -> float:
    """Fraction of pixels that are not (near) white background."""
    return float(np.mean(np.any(_pixels(path) < 0.9, axis=-1)))


def _colour_fraction(path: Path, channel: int) -> float:
    """Fraction of pixels dominated by one channel (0 red, 2 blue)."""
    rgb = _pixels(path)
    others = np.delete(rgb, channel, axis=-1)
    return float(np.mean((rgb[..., channel] > 0.5) & np.all(others < 0.6, axis=-1)))


@pytest.mark.slow
def test_run_figures_are_written_as_png_and_svg_with_content(run, tmp_path):
    paths = write_run_figures(run.log, run.scenario, tmp_path)
    assert {p.relative_to(tmp_path).with_suffix("").as_posix() for p in paths} == set(STEMS)
    for path in paths:
        if path.suffix == ".png":
            assert _ink_fraction(path) > 0.02, f"{path.name} is blank"
        else:
            svg = ElementTree.parse(path).getroot()
            drawn = [e for e in svg.iter() if e.tag.endswith(("path", "use"))]
            assert len(drawn) > 50, f"{path.name} draws almost nothing"
    for errors_png in (tmp_path / "error_summary.png", tmp_path / "figures/errors_vs_pcrlb.png"):
        assert _colour_fraction(errors_png, 0) > 1e-3, "no red estimation-error line"
        assert _colour_fraction(errors_png, 2) > 1e-3, "no blue tracking-error line"
    trajectory = tmp_path / "figures/trajectory_3d.png"
    assert _colour_fraction(trajectory, 0) > 1e-4, "no red target trajectory"


@pytest.mark.slow
def test_figures_survive_runs_shorter_than_the_zoom_and_the_window(tmp_path):
    short = simulate(load_scenario("paper", ["steps=12", "steady_state_start=2"]))
    paths = write_run_figures(short.log, short.scenario, tmp_path, formats=("png",))
    assert len(paths) == len(STEMS)
    assert all(_ink_fraction(p) > 0.01 for p in paths)


def test_excitation_eigenvalues_match_the_windowed_sum():
    rng = np.random.default_rng(3)
    q_s = rng.normal(size=(40, 3))
    window = 7
    low, high = excitation_eigenvalues(q_s, window)
    assert low.shape == high.shape == (40 - window + 1,)
    for k in (0, 11, 33):
        direct = np.linalg.eigvalsh(sum(np.outer(q, q) for q in q_s[k : k + window]))
        np.testing.assert_allclose([low[k], high[k]], direct[[0, -1]], rtol=1e-10)


def test_a_fixed_baseline_is_not_persistently_exciting():
    b = np.array([-1.0, 1.0, 0.0])
    low, high = excitation_eigenvalues(np.tile(b, (30, 1)), 24)
    np.testing.assert_allclose(low, 0.0, atol=1e-12)
    np.testing.assert_allclose(high, 24 * b @ b)


def test_sensor_positions_are_half_a_baseline_either_side(run):
    s1, s2 = sensor_positions(run.log)
    np.testing.assert_allclose(s1 - s2, run.log["b_W"], atol=1e-12)
    np.testing.assert_allclose(0.5 * (s1 + s2), run.log["p_WU"], atol=1e-12)


@pytest.mark.slow
def test_drake_uuv_run_writes_the_figures(tmp_path):
    status = main(
        ["run", "--out", str(tmp_path), "--set", "steps=30", "--set", "steady_state_start=5"]
    )
    assert status == 0
    for entry in RUN_FIGURES:
        for suffix in entry.formats:
            path = tmp_path / entry.folder / f"{entry.name}.{suffix}"
            assert path.exists() == (not entry.needs), path


def test_pe_window_is_validated():
    from drake_uuv.scenario import ScenarioError

    with pytest.raises(ScenarioError, match=r"analysis\.pe_window: must be in \[1, 1e6\], got 0"):
        load_scenario("paper", ["analysis.pe_window=0"])


def test_the_vehicle_attitude_title_reports_the_metrics_window() -> None:
    """The mean and peak attitude error in the title are metrics.json's, over k ≥
    steady_state_start (not over the whole run, whose start is far worse)."""
    from drake_uuv.analysis.vehicle_figures import attitude_errors, attitude_tracking_figure

    scenario = load_scenario("paper", ["plant=!HoveringAuv", "steps=30", "steady_state_start=15"])
    result = simulate(scenario)
    figure = attitude_tracking_figure(result.log, scenario)
    title = " ".join(figure.get_suptitle().split())  # unwrapped
    mean, peak = result.metrics["attitude_error_mean"], result.metrics["attitude_error_peak"]
    assert "over k ≥ 15, metrics.json's window" in title
    assert f"mean {mean:.3g} rad, peak {peak:.3g} rad" in title
    whole_run = attitude_errors(result.log)[1:].mean()
    assert f"{whole_run:.3g}" != f"{mean:.3g}"  # the window matters in this run
    plt.close(figure)
