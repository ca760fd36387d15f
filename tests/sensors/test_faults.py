"""Sensor faults: the filters keep estimating through dropouts, outliers and lost targets."""

import numpy as np
import pytest

from drake_uuv import ClosedLoopSimulation, load_scenario
from drake_uuv.metrics import errors
from drake_uuv.models.measurement import DROPPED, GATED, OUT_OF_BEAM, VALID

pytestmark = pytest.mark.slow

SEEDS = range(20)


def runs(overrides: list[str]):
    simulation = ClosedLoopSimulation(load_scenario("paper", overrides))
    return [simulation.run(seed) for seed in SEEDS]


@pytest.fixture(scope="module")
def clean():
    return runs([])


def pooled_position_rmse(results) -> float:
    return float(np.sqrt(np.mean([r.metrics["position_rmse"] ** 2 for r in results])))


def test_faults_are_off_in_the_paper_scenario(clean) -> None:
    for r in clean[:3]:
        assert np.all(r.log["measurement_status"] == VALID)
        assert np.all(r.log["multipath"] == 0)


def test_one_sonar_dropping_30_percent_keeps_the_filter_consistent() -> None:
    results = runs(["sonar.dropout_probability=[0.3, 0.0]"])
    status = np.concatenate([r.log["sonar_status"] for r in results])
    n = len(status)
    # Dropouts of sonar 1 at the set rate (binomial, 4 standard errors), none of sonar 2.
    rate = np.mean(status[:, 0] == DROPPED)
    assert abs(rate - 0.3) < 4 * np.sqrt(0.3 * 0.7 / n)
    assert not np.any(status[:, 1])
    # Steps without both returns only predict, and say so.
    measurement = np.concatenate([r.log["measurement_status"] for r in results])
    np.testing.assert_array_equal(measurement == DROPPED, status[:, 0] == DROPPED)
    # Consistency: mean NEES within 3 standard errors (over seeds) of 6.
    nees = np.array([r.metrics["nees_mean"] for r in results])
    assert abs(nees.mean() - 6.0) < 3 * nees.std(ddof=1) / np.sqrt(len(nees)), nees.mean()
    assert all(np.all(np.isfinite(r.log["x_TU_hat"])) for r in results)


def test_nis_gate_holds_the_error_under_multipath_outliers(clean) -> None:
    """5 % outliers: the median run within 1.2× the fault-free median RMSE with the gate; far
    worse without it. Over seeds 0–199 the gated median is 1.12× the fault-free one and the
    pooled RMSE 1.35× (a few runs let an outlier through and carry its error for a while: the
    worst 2.8 m), against 2.09× and 2.16× ungated."""
    gated = runs(["sonar.outlier_probability=0.05", "estimator.gate_probability=0.99"])
    ungated = runs(["sonar.outlier_probability=0.05"])
    reference = pooled_position_rmse(clean)

    def median_rmse(results) -> float:
        return float(np.median([r.metrics["position_rmse"] for r in results]))

    assert median_rmse(gated) < 1.2 * median_rmse(clean)
    assert pooled_position_rmse(ungated) > 1.5 * reference
    assert pooled_position_rmse(gated) < 0.8 * pooled_position_rmse(ungated)
    # The gate catches the large outliers: nearly every excess above 1 m is rejected (measured
    # 98.6 %; small excesses hide in the noise and pass, which costs little).
    status = np.concatenate([r.log["measurement_status"] for r in gated])
    excess = np.concatenate([r.log["multipath"] for r in gated]).max(axis=1)
    large = excess > 1.0
    assert large.sum() > 200
    assert np.mean(status[large] == GATED) > 0.95
    # …and rejects few clean ones: 1 % for Gaussian innovations at a 0.99 gate; Y's noise has
    # heavier tails (the ½(v1² − v2²) term), measured 1.9 %.
    clean_steps = excess == 0
    assert np.mean(status[clean_steps] == GATED) < 0.03


def test_a_target_that_leaves_the_beam_is_reacquired() -> None:
    """A 5° pan-tilt beam pointed at the prediction loses the target when the estimate strays.

    The scan of the prediction's 3-σ region brings it back: every outage ends, and within
    15 steps of reacquisition the position error is back under 1.5 m (2.5× the fault-free
    steady-state RMSE of about 0.6 m).
    """
    results = runs(
        [
            "sonar.beam_half_angle_deg=5",
            "estimator.initial_estimate=[-1, -2, -2, -0.02, -0.1, -0.1]",
        ]
    )
    outages = 0
    for r in results:
        lost = r.log["measurement_status"] == OUT_OF_BEAM
        e = np.linalg.norm(errors(r.log, r.scenario)["position"], axis=1)
        starts = np.flatnonzero(~lost[:-1] & lost[1:]) + 1
        ends = np.flatnonzero(lost[:-1] & ~lost[1:]) + 1
        assert not lost[-1], f"seed {r.scenario.random_seed}: still lost at the end"
        outages += len(starts)
        for k in ends:
            recovered = np.flatnonzero(e[k:] < 1.5)
            assert recovered.size and recovered[0] <= 15, (r.scenario.random_seed, k)
    assert outages >= 5  # the beam is narrow enough that the target does leave it
