"""The results page's "Does any run get lost?" section (``studies/results_sections/robustness.py``)
on made-up study results: which runs it calls lost, which rows consistent, and the sentences it
computes from them (the shipped scenarios out of band, where the second-order EKF fails)."""

import math
from pathlib import Path

import numpy as np
import pytest

from drake_uuv.models.statistics import nees_band
from drake_uuv.studies.study import StudyResult
from tests.conftest import study_module

section_module = study_module("results_sections.robustness")
robustness = study_module("robustness")
METRICS = ["failed", "final_position_error"]


def result(
    final: list[float], nees: float, failed: tuple[int, ...] = (), ratio: float = 1.02
) -> StudyResult:
    """A study of ``len(final)`` runs (seeds 0, 1, ...) with these final errors and mean NEES."""
    runs = len(final)
    metrics = np.zeros((runs, len(METRICS)))
    metrics[list(failed), 0] = 1.0
    metrics[:, 1] = final
    summary = {
        "nees_mean": nees,
        "nees_mean_ci95": (nees - 0.1, nees + 0.1),
        "position_rmse_over_per_run_pcrlb": ratio,
    }
    return StudyResult(None, np.arange(runs), METRICS, metrics, np.zeros((runs, 0, 0)), summary, 0)


def test_a_run_is_lost_when_stopped_or_ending_beyond_ten_metres():
    r = result([0.5, 10.5, 3.0, math.nan, 9.9], 6.0, failed=(2,))
    # Seed 1 ends 10.5 m off, seed 2 was stopped, seed 3's final error is not a number.
    assert section_module.lost_seeds(r) == [1, 2, 3]


def test_a_row_is_consistent_when_its_mean_nees_lies_in_the_band_of_its_kept_runs():
    low, high = nees_band(6, 1000)
    _, kept, consistent = section_module.row("r", "note", result([1.0] * 1000, 0.5 * (low + high)))
    assert kept and consistent
    line, kept, consistent = section_module.row("r", "note", result([1.0] * 1000, high + 0.01))
    assert kept and not consistent and "**no**" in line
    # Two of 1000 lost: the band is that of the 998 others, and the seeds are listed.
    final = [1.0] * 1000
    final[7] = final[400] = 50.0
    line, kept, _ = section_module.row("r", "note", result(final, 6.0))
    assert not kept and "| 2 (7, 400) |" in line
    assert f"[{nees_band(6, 998)[0]:.2f}, {nees_band(6, 998)[1]:.2f}]" in line


def test_the_section_names_the_shipped_scenarios_out_of_band_and_where_the_terms_fail(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    variants = robustness.robustness_variants()
    high = nees_band(6, 1000)[1]
    out = {"robust-far_standoff", "robust-realistic-auv-ekf2", "robust-lqr-ekf", "robust-far-ukf2"}
    low = nees_band(6, 1000)[0]
    nees = {name: high + 1.0 for name in out} | {"robust-lqr-ukf2": low - 0.5}
    nees |= {"robust-noisy-pf": 6.4, "robust-noisy-pf2": 6.1}
    compared = [(v, result([1.0] * 1000, nees.get(v.name, 6.0))) for v in variants]
    monkeypatch.setattr(section_module, "compare_groups", lambda *args, **kwargs: compared)
    text = " ".join(section_module.section(tmp_path, tmp_path, 1000, {}).split())
    shipped = len(robustness.SHIPPED)
    assert f"{len(variants)} of {len(variants)} rows lose no run" in text
    assert f"{len(variants) - 6} of {len(variants)} have their mean NEES" in text
    assert f"{shipped} shipped scenarios, as they ship, {shipped - 1} are" in text
    assert "(out of band: `robust-far_standoff`)" in text
    assert f"lqr {high + 1.0:.3g} → 6;" in text
    assert "with them it stays out of band in `realistic-auv` (above)." in text
    assert "so counted it stays out of band in `lqr` (below) and `far` (above)." in text
    # The particle filter's kernel in the three regimes that run it, in band in each.
    assert "ships it): paper 6 → 6; lqr 6 → 6; noisy 6.4 → 6.1; realistic-auv 6 → 6;" in text
    # Every second-order row in band: the sentence says so.
    compared = [(v, result([1.0] * 1000, 6.0)) for v in variants]
    text = " ".join(section_module.section(tmp_path, tmp_path, 1000, {}).split())
    assert "with them it is in band in every regime." in text
    assert "so counted it is in band in every regime." in text
    assert f"{shipped} shipped scenarios, as they ship, {shipped} are consistent." in text
