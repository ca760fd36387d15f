"""The paper's qualitative claims as seeded statistical tests.

Every variant runs the same seeds (common random numbers), 300 steps with the steady-state
window from k = 100: shorter than the paper's 500 steps, long enough for each claim. The
tolerances come from the sample: Wilson intervals for proportions, paired percentile
bootstrap intervals (fixed generator seed) for differences of means.
"""

import numpy as np
import pytest

from drake_uuv.analysis.stats import bootstrap_interval, wilson_interval
from drake_uuv.scenario import load_scenario
from drake_uuv.studies import DIVERGENCE_THRESHOLD, Study, StudyResult, run_studies

pytestmark = pytest.mark.slow

RUNS = 40
SHORT = ["steps=300", "steady_state_start=100"]
VARIANTS = {
    "fixed": ["attitude=!FixedAttitude"],
    "random": ["attitude=!RandomAttitude"],
    "trajectory": ["attitude=!TrajectoryAttitude"],
    "trajectory_paper_printed": ["estimator.noise_model=paper_printed"],
}


@pytest.fixture(scope="module")
def studies(tmp_path_factory) -> dict[str, StudyResult]:
    folder = tmp_path_factory.mktemp("claims")
    planned = [
        Study(name, load_scenario("paper", [*SHORT, *overrides]), RUNS, folder / name)
        for name, overrides in VARIANTS.items()
    ]
    results = run_studies(planned, workers=2, progress=False, figures=False)
    return {study.name: result for study, result in zip(planned, results, strict=True)}


def _paired_mean_difference_interval(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """95 % bootstrap interval of mean(a − b) over paired runs."""
    return bootstrap_interval(a - b, lambda x: np.mean(x, axis=-1))


def test_fixed_attitude_diverges_while_trajectory_stays_bounded(studies):
    fixed = studies["fixed"].column("final_position_error")
    trajectory = studies["trajectory"]
    diverged = int(np.sum(~(fixed <= DIVERGENCE_THRESHOLD)))
    low, _ = wilson_interval(diverged, RUNS)
    assert low > 0.5, f"only {diverged}/{RUNS} fixed-attitude runs diverged"
    kept = int(np.sum(trajectory.column("final_position_error") <= DIVERGENCE_THRESHOLD))
    bounded = int(np.sum(trajectory.column("max_tracking_error") < 10.0))
    assert wilson_interval(kept, RUNS)[0] > 0.9, f"{RUNS - kept} trajectory runs diverged"
    assert wilson_interval(bounded, RUNS)[0] > 0.9
    assert studies["fixed"].summary["position_rmse"] > 10 * trajectory.summary["position_rmse"]


def test_random_attitude_tracks_worse_than_the_trajectory(studies):
    random = studies["random"].column("tracking_rmse")
    trajectory = studies["trajectory"].column("tracking_rmse")
    low, _ = _paired_mean_difference_interval(random, trajectory)
    assert low > 0.0, "Algorithm 1's tracking error is not larger than Algorithm 2's"


def test_both_excited_modes_estimate_well(studies):
    for name in ("random", "trajectory"):
        summary = studies[name].summary
        assert summary["diverged_fraction"] == 0.0
        assert summary["position_rmse"] < 1.0


def test_derived_noise_model_nees_is_nearer_six_than_paper_printed(studies):
    derived = studies["trajectory"].column("nees_mean")
    printed = studies["trajectory_paper_printed"].column("nees_mean")
    gap = np.abs(printed - 6.0)
    low, _ = bootstrap_interval(
        np.stack([derived, printed], axis=-1),
        lambda x: (
            np.abs(np.mean(x[..., 1], axis=-1) - 6.0) - np.abs(np.mean(x[..., 0], axis=-1) - 6.0)
        ),
    )
    assert low > 0.0, (
        f"derived mean NEES {derived.mean():.2f}, paper_printed {printed.mean():.2f} "
        f"(mean |NEES − 6| {gap.mean():.2f})"
    )
    # And the derived model is consistent: 6 lies within its 95 % interval widened by half its
    # width (≈ 3 standard errors either side of the mean).
    d_low, d_high = bootstrap_interval(derived, lambda x: np.mean(x, axis=-1))
    half = 0.5 * (d_high - d_low)
    assert d_low - half < 6.0 < d_high + half, f"derived mean NEES {derived.mean():.2f}"
