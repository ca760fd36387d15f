"""The terminal summary: exact lines, null numbers as dashes, bound lines only with bounds."""

from drake_uuv.studies.report import format_summary

SUMMARY = {
    "runs": 20,
    "first_seed": 3,
    "steady_state_start": 200,
    "position_rmse": 0.61134,
    "position_rmse_ci95": [0.5852, 0.6404],
    "velocity_rmse": 0.1388,
    "velocity_rmse_ci95": [0.1338, 0.1443],
    "tracking_rmse": None,
    "tracking_rmse_ci95": [None, None],
    "nees_mean": 6.395,
    "nees_mean_ci95": [6.024, 6.745],
    "diverged_fraction": 0.05,
    "tracking_bounded_fraction": 1.0,
}


def test_without_bounds_six_lines():
    assert format_summary(SUMMARY).splitlines() == [
        "20 runs, seeds 3..22, k ≥ 200:",
        "  position RMSE 0.6113 m [0.5852, 0.6404]",
        "  velocity RMSE 0.1388 m/s [0.1338, 0.1443]",
        "  tracking RMSE — m [—, —]",
        "  mean NEES 6.395 [6.024, 6.745] (6 if consistent)",
        "  diverged 5.0%, tracking bounded 100.0%",
    ]


def test_the_warned_runs_are_counted_when_the_summary_has_them():
    line = format_summary({**SUMMARY, "warned_fraction": 0.15}).splitlines()[5]
    assert line == (
        "  diverged 5.0%, tracking bounded 100.0%, warned 15.0% (drake-uuv run --seed S says why)"
    )


def test_bound_lines_show_what_the_summary_has():
    summary = {
        **SUMMARY,
        "pcrlb_position_rmse": 0.2006,
        "position_rmse_over_pcrlb": 3.0476,
        "pcrlb_per_run_position_rmse": 0.2336,
        "position_rmse_over_per_run_pcrlb": 2.6171,
        "kf_riccati_position_rmse": 0.5953,
        "pcrlb_velocity_rmse": 0.08807,
        "velocity_rmse_over_pcrlb": None,
    }
    assert format_summary(summary).splitlines()[6:] == [
        "  position PCRLB 0.2006 m: RMSE / PCRLB 3.048, / per-run bound 0.2336 2.617; "
        "paper-KF Riccati 0.5953",
        "  velocity PCRLB 0.08807 m/s: RMSE / PCRLB —",
    ]
