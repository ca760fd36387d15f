"""The information-seeking planner in the closed loop (depends on the scenario wiring)."""

import numpy as np
import pytest

from drake_uuv import ClosedLoopSimulation, load_scenario
from drake_uuv.models.information import rotation_angles


@pytest.mark.parametrize(
    "overrides",
    [
        ["attitude.max_angle_per_step=0.2"],
        ["attitude.max_angle_per_step=0.2", "estimator.type=ekf", "tracking.type=lqr"],
    ],
)
def test_closed_loop_is_reproducible_and_keeps_the_budget(overrides: list[str]) -> None:
    scenario = load_scenario(
        "paper", ["attitude.mode=information", "steps=120", "steady_state_start=60", *overrides]
    )
    simulation = ClosedLoopSimulation(scenario)
    first, second = simulation.run(3), simulation.run(3)
    assert np.array_equal(first.log["R_WB"], second.log["R_WB"])
    assert np.array_equal(first.log["q_hat"], second.log["q_hat"])
    assert rotation_angles(first.log["R_WB"]).max() <= 0.2 + 1e-9
    assert first.metrics["excitation_min"] >= 1.0
    assert not np.array_equal(first.log["R_WB"], simulation.run(4).log["R_WB"])
