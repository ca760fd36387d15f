"""Bootstrap and Wilson intervals, and the χ² re-exports of drake_uuv.analysis.stats."""

import math

import numpy as np
import pytest

from drake_uuv.analysis import stats
from drake_uuv.models import statistics


def test_chi2_functions_are_re_exported_from_the_models_layer():
    for name in ("regularized_gamma_p", "chi2_cdf", "chi2_ppf", "nees_band"):
        assert getattr(stats, name) is getattr(statistics, name)


def test_bootstrap_interval_is_deterministic_and_as_wide_as_the_normal_theory_says():
    values = np.random.default_rng(1).normal(5.0, 1.0, size=200)
    first = stats.bootstrap_interval(values, lambda x: x.mean(axis=-1))
    assert first == stats.bootstrap_interval(values, lambda x: x.mean(axis=-1))
    assert first != stats.bootstrap_interval(values, lambda x: x.mean(axis=-1), seed=1)
    assert first[0] < values.mean() < first[1]
    # The 95 % interval of a mean of 200 unit-variance samples is ≈ ±1.96/√200; the bootstrap
    # width itself has a relative spread of order 1/√(2·200) ≈ 5 %, so 25 % is generous.
    assert first[1] - first[0] == pytest.approx(2 * 1.96 / math.sqrt(200), rel=0.25)


def test_bootstrap_interval_of_nothing_is_nan():
    low, high = stats.bootstrap_interval(np.empty(0), lambda x: x.mean(axis=-1))
    assert math.isnan(low) and math.isnan(high)


def test_wilson_interval_matches_its_formula_and_its_edges():
    # Wilson (1927): (p + z²/2n ± z √(p(1−p)/n + z²/4n²)) / (1 + z²/n); 3/10 at z = 1.96.
    assert stats.wilson_interval(3, 10) == pytest.approx((0.10779, 0.60322), abs=1e-5)
    assert stats.wilson_interval(0, 40) == (0.0, pytest.approx(0.0876, abs=1e-3))
    assert stats.wilson_interval(40, 40) == (pytest.approx(1 - 0.0876, abs=1e-3), 1.0)
    assert all(math.isnan(v) for v in stats.wilson_interval(0, 0))
