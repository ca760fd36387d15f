"""The study summary on synthetic metrics: mean-square combination, failures, bounds."""

import math

import numpy as np
import pytest

from drake_uuv.models.motion import process_noise_covariance
from drake_uuv.scenario import load_scenario
from drake_uuv.studies.statistics import (
    BOUND_METHOD,
    DIVERGENCE_THRESHOLD,
    EXTENDED_BOUND_METHOD,
    NEEDED_METRICS,
    bound_summary,
    monte_carlo_bound,
    summarize,
)

NAMES = [*NEEDED_METRICS, "final_tracking_error", "failed"]


def _metrics(runs: int, **columns: list[float]) -> np.ndarray:
    """``runs`` rows of ones, with the named columns set."""
    metrics = np.ones((runs, len(NAMES)))
    metrics[:, NAMES.index("failed")] = 0.0
    for name, values in columns.items():
        metrics[:, NAMES.index(name)] = values
    return metrics


def test_rmse_combines_the_runs_mean_square_errors_not_their_rmses(paper):
    metrics = _metrics(2, position_rmse=[1.0, 3.0], nees_mean=[4.0, 8.0])
    summary = summarize(NAMES, metrics, paper, np.array([0, 1]))
    assert summary["position_rmse"] == pytest.approx(math.sqrt(5.0))  # not 2
    assert summary["nees_mean"] == 6.0
    assert summary["runs"] == 2 and summary["first_seed"] == 0
    assert summary["steps"] == paper.steps
    assert summary["steady_state_start"] == paper.steady_state_start
    for key in ("position_rmse", "velocity_rmse", "tracking_rmse", "nees_mean"):
        low, high = summary[f"{key}_ci95"]
        assert low <= summary[key] <= high


def test_divergence_and_bounded_tracking_count_against_their_thresholds(paper):
    final = [0.5, DIVERGENCE_THRESHOLD, DIVERGENCE_THRESHOLD + 1e-9, math.nan]
    peak = [2.0, 9.99, 10.0, 20.0]
    summary = summarize(
        NAMES,
        _metrics(4, final_position_error=final, max_tracking_error=peak),
        paper,
        np.arange(4),
    )
    assert summary["diverged_fraction"] == 0.5  # above the threshold, or not finite
    assert summary["tracking_bounded_fraction"] == 0.5  # strictly below it
    low, high = summary["diverged_fraction_ci95"]
    assert 0.0 < low < 0.5 < high < 1.0


def test_failed_runs_count_as_diverged_and_are_left_out_of_the_errors(paper):
    metrics = _metrics(3, position_rmse=[1.0, math.nan, 2.0], failed=[0.0, 1.0, 0.0])
    metrics[1, :-1] = math.nan  # what the runner returns for a failed run
    summary = summarize(NAMES, metrics, paper, np.array([5, 6, 7]))
    assert summary["completed_runs"] == 2
    assert summary["failed_fraction"] == pytest.approx(1 / 3)
    assert summary["diverged_fraction"] == pytest.approx(1 / 3)
    assert summary["position_rmse"] == pytest.approx(math.sqrt(2.5))
    assert summary["first_seed"] == 5


def test_a_study_whose_runs_all_failed_summarises_to_nulls(paper):
    summary = summarize(["failed"], np.ones((2, 1)), paper, np.array([0, 1]))
    assert summary["completed_runs"] == 0 and summary["diverged_fraction"] == 1.0
    for key in ("position_rmse", "nees_mean", "relative_speed_mean", "relative_speed_peak"):
        assert summary[key] is None
    assert summary["position_rmse_ci95"] == [None, None]
    assert summary["tracking_bounded_fraction"] == 0.0
    assert "bound_method" not in summary


def test_per_run_bounds_are_root_mean_square_and_the_ratios_use_them(paper):
    column = {
        "pcrlb_position_rmse": np.array([1.0, 7.0]),  # √((1 + 49)/2) = 5
        "pcrlb_velocity_rmse": np.array([2.0, 2.0]),
        "kf_riccati_position_rmse": np.array([3.0, 4.0]),
        "kf_riccati_velocity_rmse": np.array([0.0, 0.0]),
    }
    summary = {
        "runs": 2,
        "position_rmse": 10.0,
        "position_rmse_ci95": [5.0, None],
        "velocity_rmse": None,
        "velocity_rmse_ci95": [1.0, 3.0],
    }
    out = bound_summary(summary, column, paper, None)
    assert out["pcrlb_per_run_position_rmse"] == 5.0
    assert out["kf_riccati_position_rmse"] == pytest.approx(math.sqrt(12.5))
    assert out["position_rmse_over_per_run_pcrlb"] == 2.0
    assert out["position_rmse_over_per_run_pcrlb_ci95"] == [1.0, None]
    assert out["velocity_rmse_over_per_run_pcrlb"] is None
    assert out["velocity_rmse_over_per_run_pcrlb_ci95"] == [0.5, 1.5]
    assert "position_rmse_over_pcrlb" not in out  # no information sum: no Monte Carlo bound
    assert out["bound_method"] == BOUND_METHOD
    assert bound_summary(summary, {}, paper, None) == {}


def test_monte_carlo_bound_averages_the_information_over_the_runs(paper):
    steps = 5
    zero = monte_carlo_bound(np.zeros((steps, 6, 6)), 3, paper)
    # No information: the prior propagated by the constant-velocity model, P(k+1) = A P Aᵀ + Q.
    t = paper.time_step
    A = np.block([[np.eye(3), t * np.eye(3)], [np.zeros((3, 3)), np.eye(3)]])
    Q = process_noise_covariance(np.asarray(paper.target.acceleration_covariance), t)
    P = np.asarray(paper.estimator.initial_covariance, dtype=float)
    for k in range(steps):
        np.testing.assert_allclose(zero[k], P, rtol=1e-12, atol=1e-12)
        P = A @ P @ A.T + Q
    one = np.zeros((steps, 6, 6))
    one[:, :3, :3] = np.diag([4.0, 9.0, 16.0])
    np.testing.assert_allclose(
        monte_carlo_bound(7 * one, 7, paper), monte_carlo_bound(one, 1, paper), rtol=1e-12
    )
    # At k = 0 the bound is (P0⁻¹ + M)⁻¹.
    P0 = np.asarray(paper.estimator.initial_covariance, dtype=float)
    expected = np.linalg.inv(np.linalg.inv(P0) + one[0])
    np.testing.assert_allclose(monte_carlo_bound(one, 1, paper)[0], expected, rtol=1e-12)


def test_summary_has_the_monte_carlo_bound_with_an_information_sum(paper):
    information = np.zeros((paper.steps, 6, 6))
    information[:, :3, :3] = 2 * 100.0 * np.eye(3)  # two runs of 100 m⁻² per axis
    metrics = _metrics(2, position_rmse=[0.2, 0.2])
    summary = summarize(NAMES, metrics, paper, np.array([0, 1]), information)
    assert 0.0 < summary["pcrlb_position_rmse"] < 0.2
    assert summary["position_rmse_over_pcrlb"] == pytest.approx(
        0.2 / summary["pcrlb_position_rmse"]
    )


def test_with_navigation_errors_the_per_run_bound_has_its_floor_and_says_so(paper):
    column = {
        "pcrlb_position_rmse": np.array([3.0, 5.0]),
        "pcrlb_velocity_rmse": np.array([2.0, 2.0]),
        "pcrlb_floor_position_rmse": np.array([1.0, 7.0]),  # √((1 + 49)/2) = 5
        "pcrlb_floor_velocity_rmse": np.array([0.0, 0.0]),
    }
    summary = {"runs": 2, "position_rmse": 10.0, "position_rmse_ci95": [5.0, 20.0],
               "velocity_rmse": 4.0, "velocity_rmse_ci95": [1.0, 3.0]}  # fmt: skip
    errors = load_scenario("paper", ["sonar.latency=0.5"])
    out = bound_summary(summary, column, errors, np.zeros((paper.steps, 6, 6)))
    assert out["pcrlb_per_run_floor_position_rmse"] == 5.0
    assert out["pcrlb_per_run_position_rmse"] == pytest.approx(math.sqrt(17.0))
    assert out["bound_method"] == BOUND_METHOD + EXTENDED_BOUND_METHOD
    assert "pcrlb stays the Monte Carlo bound" in out["bound_method"]
    assert bound_summary(summary, column, paper, None)["bound_method"] == BOUND_METHOD
