"""The cautious loop in closed loop: a seed the certainty-equivalent loop loses is kept.

Seed 153 of ``realistic`` on the kinematic plant (EKF, particle bridge off, so that 200 seeds
batch): the paper's certainty-equivalent law chases the linear start's estimate at up to
46 m/s and the EKF's innovations blow up. Holding station until the hand-over, within a
0.76 m/s top speed, it ends 0.12 m off (a batch search over seeds 0–199: 4 runs lost by the
certainty-equivalent loop, 1 by the cautious one, seed 62, whose filter diverges later).
"""

import numpy as np
import pytest

from drake_uuv import ClosedLoopSimulation, load_scenario
from drake_uuv.models.tracking_laws import saturate_norm
from tests.conftest import T

SEED = 153
# The filter's recovery off: the cautious loop alone keeps the seed.
LOOP = ["plant=KinematicUuv", "estimator=Ekf", "estimator.particle_bridge=false",
        "estimator.recovery_window=null"]  # fmt: skip
CERTAINTY_EQUIVALENT = ["tracking.hold_until_handover=false", "tracking.max_speed=null"]
CAUTIOUS = ["tracking.hold_until_handover=true", "tracking.max_speed=0.76"]


def run(overrides: list[str]):
    """The seed beside seed 0, which both loops keep: a batch whose every run fails stops
    before the steady state and has no metrics."""
    scenario = load_scenario("realistic", LOOP + overrides)
    return ClosedLoopSimulation(scenario, batch_size=2).run_batch([SEED, 0])


@pytest.mark.slow
def test_a_seed_lost_to_the_chase_is_kept_by_the_cautious_loop() -> None:
    lost = run(CERTAINTY_EQUIVALENT)
    assert lost.failures[0] is not None and "innovations blew up" in lost.failures[0]

    kept = run(CAUTIOUS)
    assert kept.failures == [None, None]
    assert kept.metrics["final_position_error"][0] < 2.0
    assert kept.metrics["position_rmse"][0] < 1.0
    speed = np.linalg.norm(kept.log["v_WU"][0], axis=-1)
    # The law limits the navigated velocity; the true one is off by the navigation's errors
    # (DVL noise and bias, the heading's error turning the applied acceleration).
    assert np.max(speed) <= 0.80 and np.max(np.linalg.norm(lost.log["v_WU"][0], axis=-1)) > 10
    # It held station through the linear start: the command there brings the navigated
    # velocity to rest (within the law's 0.6 m/s²), whatever the estimate says.
    linear = kept.log["estimator_phase"][0, :, 0] == 1.0
    assert linear[:20].all()
    rest = saturate_norm(-kept.log["v_WU_nav"][0][linear] / T, 0.6)
    np.testing.assert_array_equal(kept.log["u1_W"][0][linear], rest)
    assert np.abs(kept.log["u1_W"][0][linear]).max() < 0.2  # DVL noise and bias only
