"""The thrusters' efforts in the Meshcat scene: jet geometry and the recorded animation."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from pydrake.geometry import Meshcat

from drake_uuv.scenario.plants import HoveringAuv
from drake_uuv.visualization import record_animation
from drake_uuv.visualization.scene import SCENE_ROOT, ThrusterLayout, thruster_jets
from tests.visualization.synthetic_log import BASELINE_B, TIME_STEP


@pytest.fixture(scope="module")
def layout() -> ThrusterLayout:
    return ThrusterLayout.from_config(HoveringAuv())


def test_jets_start_at_the_thrusters_and_follow_the_force(layout) -> None:
    f_max = layout.max_thrust
    thrust = np.array([f_max, -f_max, 0.5 * f_max, 0.0, 2 * f_max, -0.25 * f_max, 0.0, 0.0])
    starts, ends = thruster_jets(layout, thrust, length=0.6)
    np.testing.assert_array_equal(starts, layout.positions)
    jets = ends - starts
    # Length 0.6 m at full thrust, in proportion below it, clipped at the limit above it.
    np.testing.assert_allclose(
        np.linalg.norm(jets, axis=1), [0.6, 0.6, 0.3, 0.0, 0.6, 0.15, 0.0, 0.0], atol=1e-12
    )
    # Along the force the thruster applies: +d for positive thrust, −d for negative.
    np.testing.assert_allclose(jets[0], 0.6 * np.array([0.0, 0.0, 1.0]))
    np.testing.assert_allclose(jets[1], -0.6 * np.array([0.0, 0.0, 1.0]))
    np.testing.assert_allclose(jets[4], 0.6 * np.array([1.0, -1.0, 0.0]) / np.sqrt(2.0))


def test_layout_and_jets_reject_bad_input(layout) -> None:
    with pytest.raises(ValueError, match=r"thrust: must have 8 entries, got \(3,\)"):
        thruster_jets(layout, np.zeros(3), 0.6)
    with pytest.raises(ValueError, match=r"max_thrust: must be > 0, got 0.0"):
        ThrusterLayout(layout.positions, layout.directions, 0.0)
    with pytest.raises(ValueError, match=r"directions: must be non-zero"):
        ThrusterLayout(layout.positions, np.zeros((8, 3)), 1.0)
    with pytest.raises(ValueError, match=r"directions: must be n×3 like positions \(8, 3\)"):
        ThrusterLayout(layout.positions, np.zeros((7, 3)), 1.0)


def _vehicle_log(steps: int, layout: ThrusterLayout) -> dict[str, np.ndarray]:
    """A log with the keys a vehicle run writes (a still vehicle, thrusts ramping up)."""
    ramp = np.linspace(0.0, layout.max_thrust, steps)[:, None]
    return {
        "p_WU": np.zeros((steps, 3)),
        "R_WB": np.tile(np.eye(3), (steps, 1, 1)),
        "p_WT": np.tile([3.0, 0.0, 0.0], (steps, 1)),
        "x_TU_hat": np.tile([-3.0, 0.0, 0.0, 0.0, 0.0, 0.0], (steps, 1)),
        "P_TU": np.tile(np.eye(6), (steps, 1, 1)),
        "thrust": ramp * np.ones((1, layout.count)),
    }


def test_the_animation_draws_one_jet_per_thruster(tmp_path: Path, layout) -> None:
    meshcat = Meshcat()
    log = _vehicle_log(6, layout)
    record_animation(log, BASELINE_B, TIME_STEP, tmp_path / "a.html", meshcat=meshcat,
                     thrusters=layout)  # fmt: skip
    for i in range(layout.count):
        assert meshcat.HasPath(f"{SCENE_ROOT}/uuv/thrusters/{i}")
    assert not meshcat.HasPath(f"{SCENE_ROOT}/uuv/thrusters/{layout.count}")
    # Without a layout, none.
    record_animation(log, BASELINE_B, TIME_STEP, tmp_path / "b.html", meshcat=meshcat)
    assert not meshcat.HasPath(f"{SCENE_ROOT}/uuv/thrusters/0")
    del log["thrust"]
    with pytest.raises(ValueError, match=r"log\['thrust'\] has shape \(\), expected \(6, 8\)"):
        record_animation(log, BASELINE_B, TIME_STEP, tmp_path / "c.html", meshcat=meshcat,
                         thrusters=layout)  # fmt: skip
