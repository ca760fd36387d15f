"""Acceptance of the estimators on the Drake diagram: seeded Monte Carlo against the PCRLB.

Every run is the whole closed loop (:class:`~drake_uuv.simulation.ClosedLoopSimulation`); the
bounds are those the studies report (:mod:`drake_uuv.studies`). Ratios carry a standard
error from the run-to-run spread, and every tolerance is a multiple of it.
"""

import math

import pytest

from drake_uuv.scenario import load_scenario
from drake_uuv.studies import Study, run_study

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def ekf_study(tmp_path_factory):
    """30 seeded EKF runs through the Drake diagram, 300 steps, steady state k ≥ 100 (the
    hand-over is at k ≈ 30 and the EKF settles within a few tens of steps)."""
    scenario = load_scenario(
        "paper", ["estimator=!Ekf", "steps=300", "steady_state_start=100"], seed=1000
    )
    folder = tmp_path_factory.mktemp("ekf_study")
    return run_study(Study("ekf", scenario, 30, folder), workers=1, progress=False, figures=False)


def _ratio_and_error(result, part: str, bound: float) -> tuple[float, float]:
    """RMSE / bound and its standard error from the run-to-run spread (delta method)."""
    mse = result.column(f"{part}_rmse") ** 2
    se_mse = mse.std(ddof=1) / math.sqrt(mse.size)
    return math.sqrt(mse.mean()) / bound, se_mse / (2 * math.sqrt(mse.mean())) / bound


def test_ekf_through_the_diagram_is_within_1_1_of_the_pcrlb(ekf_study) -> None:
    """The EKF's steady-state RMSE within 1.1× the PCRLB over 30 runs.

    Against the mean of the per-run bounds (what an estimator efficient on every trajectory
    attains) outright; against the proven Monte Carlo bound, which sits ~8 % lower in this
    loop (models/pcrlb.py), not significantly above 1.1 (Z = 3 standard errors of the
    run-to-run spread). Never significantly below 1: the bound holds.
    """
    s = ekf_study.summary
    z = 3.0
    for part in ("position", "velocity"):
        per_run, se_run = _ratio_and_error(ekf_study, part, s[f"pcrlb_per_run_{part}_rmse"])
        proven, se = _ratio_and_error(ekf_study, part, s[f"pcrlb_{part}_rmse"])
        assert z * se < 0.1, "30 runs must resolve the 10 % margin"
        assert per_run <= 1.1, f"{part}: {per_run:.3f}× the per-run bound"
        assert proven - z * se <= 1.1, f"{part}: {proven:.3f} ± {se:.3f}× the PCRLB"
        assert proven >= 1.0 - z * se and per_run >= 1.0 - z * se_run
        assert s[f"{part}_rmse_over_pcrlb"] == pytest.approx(proven, rel=1e-12)
        assert s[f"pcrlb_{part}_rmse"] <= s[f"pcrlb_per_run_{part}_rmse"]  # Jensen


def test_ekf_is_consistent_and_the_papers_kf_is_not_efficient(ekf_study, tmp_path) -> None:
    s = ekf_study.summary
    # Mean of 30 runs' time-averaged NEES: the χ²(6·30)/30 band at 99 % is about [4.7, 7.5].
    assert 4.7 < s["nees_mean"] < 7.5
    # The paper's KF on the same seeds: far above the bound, near its own Riccati covariance.
    scenario = load_scenario(
        "paper", ["estimator=!PaperKf", "steps=300", "steady_state_start=100"], seed=1000
    )
    kf = run_study(Study("kf", scenario, 10, tmp_path), workers=1, progress=False, figures=False)
    k = kf.summary
    assert k["position_rmse_over_pcrlb"] > 2.0
    assert k["position_rmse"] == pytest.approx(k["kf_riccati_position_rmse"], rel=0.25)
    assert s["kf_riccati_position_rmse"] > 2 * s["pcrlb_per_run_position_rmse"]
