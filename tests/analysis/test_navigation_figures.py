"""The navigation figure: the errors it draws, and when ``drake-uuv run`` writes it."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pydrake.math import RollPitchYaw, RotationMatrix

from drake_uuv.analysis.navigation_figures import navigation_errors, navigation_figure
from drake_uuv.cli import main
from drake_uuv.scenario import load_scenario

STEPS = 40


def _log(rng: np.random.Generator) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """A log whose attitude errors are known in roll-pitch-yaw (yaw near ±π, so that the
    difference must be wrapped), and the errors."""
    rpy = np.column_stack([
        rng.uniform(-1.0, 1.0, STEPS), rng.uniform(-1.0, 1.0, STEPS), np.full(STEPS, 3.1),
    ])  # fmt: skip
    delta = rng.normal(scale=[0.01, 0.01, 0.05], size=(STEPS, 3))
    R, R_nav = ([RotationMatrix(RollPitchYaw(a)).matrix() for a in angles]
                for angles in (rpy, rpy + delta))  # fmt: skip
    p, v = rng.normal(size=(STEPS, 3)), rng.normal(size=(STEPS, 3))
    log = {
        "k": np.arange(STEPS), "R_WB": np.array(R), "R_WB_nav": np.array(R_nav),
        "p_WU": p, "p_WU_nav": p + 0.1 * np.arange(STEPS)[:, None], "v_WU": v,
        "v_WU_nav": v + 0.01,
    }  # fmt: skip
    return log, delta


def test_the_errors_are_the_navigation_less_the_truth() -> None:
    log, delta = _log(np.random.default_rng(2))
    assert np.any(delta[:, 2] > math.pi - 3.1)  # some navigated yaws cross π: wrapped
    errors = navigation_errors(log)
    assert_allclose(errors["attitude"], delta, rtol=0, atol=1e-12)
    assert_allclose(errors["velocity"], 0.01, rtol=0, atol=1e-12)
    assert_allclose(errors["position"][:, 1], 0.1 * np.arange(STEPS), atol=1e-12)


def test_the_figure_draws_each_error_and_names_the_sigmas() -> None:
    log, delta = _log(np.random.default_rng(3))
    scenario = load_scenario("paper", ["navigation=!InertialNavigation"])
    figure = navigation_figure(log, scenario)
    attitude, velocity, position = figure.axes
    for i in range(3):
        assert_allclose(attitude.lines[i].get_ydata(), np.degrees(delta[:, i]), atol=1e-9)
    assert_allclose(velocity.lines[3].get_ydata(), math.sqrt(3) * 0.01, rtol=1e-9)
    assert_allclose(position.lines[3].get_ydata(), math.sqrt(3) * 0.1 * np.arange(STEPS))
    assert "σ attitude [0.5, 0.5, 2]°, heading bias 2°" in figure.get_suptitle()


@pytest.mark.slow
@pytest.mark.parametrize("navigation, written", [("PerfectNavigation", False),
                                                 ("InertialNavigation", True)])  # fmt: skip
def test_drake_uuv_run_writes_the_figure_unless_the_navigation_is_perfect(
    tmp_path, navigation: str, written: bool
) -> None:
    args = ["run", "--out", str(tmp_path), "--set", "steps=20", "--set", "steady_state_start=5"]
    assert main([*args, "--set", f"navigation=!{navigation}"]) == 0
    for suffix in ("png", "svg"):
        assert (tmp_path / "figures" / f"navigation_errors.{suffix}").exists() == written
