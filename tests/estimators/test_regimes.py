"""The estimators at an easy and a hard regime: seeded Monte Carlo in the Drake loop.

The regimes are those of the ``regimes`` comparison group
(``REGIMES`` of ``studies/regimes.py``): the paper's (σ = 0.1 m, q* = [−2, −2, 0] in
the body frame), σ = 0.5 m at the same standoff, where the paper's KF is far from the
posterior Cramér–Rao bound and the particle filter reaches it, and σ = 1 m, where the EKF and
UKF reach it only through their particle bridge. Runs are shortened (300
steps, steady state k ≥ 150) to keep each test under about two minutes; the ratios carry a
standard error from the run-to-run spread, and each test first checks that its runs resolve
the margin it tests.
"""

import math

import numpy as np
import pytest

from drake_uuv.scenario import load_scenario
from drake_uuv.studies import Study, run_study
from tests.conftest import study_module

pytestmark = pytest.mark.slow

REGIMES = study_module("regimes").REGIMES
REGIME_ESTIMATORS = study_module("regimes").REGIME_ESTIMATORS

SHORT = ("steps=300", "steady_state_start=150")
SEED = 2000  # away from the studies' seeds 0 … 39
Z = 3.0


def _study(tmp_path_factory, regime: str, estimator: str, runs: int):
    overrides = [*REGIMES[regime][1], REGIME_ESTIMATORS[estimator], *SHORT]
    scenario = load_scenario("paper", overrides, seed=SEED)
    folder = tmp_path_factory.mktemp(f"{regime}-{estimator}")
    return run_study(
        Study(f"{regime}-{estimator}", scenario, runs, folder),
        workers=1,
        progress=False,
        figures=False,
    )


def ratio_and_error(result) -> tuple[float, float]:
    """Position RMSE over the per-run PCRLB, ``√(mean e² / mean b²)`` over the runs, and its
    standard error by the delta method on the ratio of the two means (each run's squared
    error ``e²`` and squared bound ``b²`` are a pair)."""
    a = result.column("position_rmse") ** 2
    b = result.column("pcrlb_position_rmse") ** 2
    n = a.size
    ma, mb = a.mean(), b.mean()
    cov = np.cov(a, b, ddof=1)
    relative_var = (cov[0, 0] / ma**2 + cov[1, 1] / mb**2 - 2 * cov[0, 1] / (ma * mb)) / n
    ratio = math.sqrt(ma / mb)
    return ratio, 0.5 * ratio * math.sqrt(max(relative_var, 0.0))


@pytest.fixture(scope="module")
def paper_pf(tmp_path_factory):
    # 40 runs: the ratio's standard error is about 0.023 (0.036 with 16), so 3 of them fit
    # inside the 10 % margin.
    return _study(tmp_path_factory, "paper", "pf", 40)


@pytest.fixture(scope="module")
def noisy_pf(tmp_path_factory):
    return _study(tmp_path_factory, "sigma0.5", "pf", 16)


@pytest.fixture(scope="module")
def noisy_kf(tmp_path_factory):
    return _study(tmp_path_factory, "sigma0.5", "kf", 16)


def test_ratio_and_error_is_the_delta_method_of_the_ratio_of_means() -> None:
    """Against a large sample of a known ratio: the estimate within Z standard errors, the
    standard error against the spread of many small-sample estimates."""

    class Fake:
        def __init__(self, a, b):
            self.data = {"position_rmse": np.sqrt(a), "pcrlb_position_rmse": np.sqrt(b)}

        def column(self, name):
            return self.data[name]

    rng = np.random.default_rng(0)
    estimates, errors = [], []
    for _ in range(400):
        b = rng.gamma(20.0, 0.01, size=30)  # bounds², mean 0.2
        a = b * 1.21 * rng.gamma(4.0, 0.25, size=30)  # errors², mean 1.21 b²: ratio 1.1
        ratio, se = ratio_and_error(Fake(a, b))
        estimates.append(ratio)
        errors.append(se)
    assert np.mean(estimates) == pytest.approx(1.1, abs=0.01)
    assert np.mean(errors) == pytest.approx(np.std(estimates), rel=0.15)


def test_easy_regime_the_particle_filter_is_within_1_1_of_the_per_run_bound(paper_pf) -> None:
    ratio, se = ratio_and_error(paper_pf)
    assert Z * se < 0.1, f"40 runs must resolve the 10 % margin (se {se:.3f})"
    assert ratio <= 1.1, f"{ratio:.3f} ± {se:.3f}× the per-run bound"
    assert ratio >= 1.0 - Z * se, f"{ratio:.3f} ± {se:.3f}: below the bound"
    assert paper_pf.summary["diverged_fraction"] == 0.0


def test_hard_regime_the_particle_filter_is_within_1_25_and_the_kf_far_above(
    noisy_pf, noisy_kf
) -> None:
    """σ = 0.5 m: the particle filter within 1.25× the per-run bound; the paper's KF on the
    same seeds significantly above 1.25× (it is about 2.7×), so the check can fail."""
    pf, se_pf = ratio_and_error(noisy_pf)
    kf, se_kf = ratio_and_error(noisy_kf)
    assert Z * se_pf < 0.25, f"16 runs must resolve the 25 % margin (se {se_pf:.3f})"
    assert pf <= 1.25, f"PF: {pf:.3f} ± {se_pf:.3f}× the per-run bound"
    assert pf >= 1.0 - Z * se_pf, f"PF: {pf:.3f} ± {se_pf:.3f}: below the bound"
    assert kf - Z * se_kf > 1.25, f"KF: {kf:.3f} ± {se_kf:.3f}× the per-run bound"
    assert noisy_pf.summary["diverged_fraction"] == 0.0


def _gaussian_study(tmp_path_factory, estimator: str, runs: int, *extra: str):
    overrides = [*REGIMES["sigma1"][1], REGIME_ESTIMATORS[estimator], *extra, *SHORT]
    scenario = load_scenario("paper", overrides, seed=SEED)
    name = f"sigma1-{estimator}{'-plain' if extra else ''}"
    return run_study(
        Study(name, scenario, runs, tmp_path_factory.mktemp(name)),
        workers=1,
        progress=False,
        figures=False,
    )


@pytest.mark.parametrize("estimator", ["ekf", "ukf"])
def test_hardest_regime_the_bridged_gaussian_filters_are_within_1_25(
    tmp_path_factory, estimator: str
) -> None:
    """σ = 1 m at 2.8 m, where the rule's Gaussian test never holds on the KF: with the
    particle bridge (the default) the EKF and UKF are within 1.25× the per-run bound and no
    run diverges; without it, on the same seeds, they are the paper's KF, far above."""
    bridged = _gaussian_study(tmp_path_factory, estimator, 16)
    plain = _gaussian_study(tmp_path_factory, estimator, 16, "estimator.particle_bridge=false")
    ratio, se = ratio_and_error(bridged)
    kf, se_kf = ratio_and_error(plain)
    assert Z * se < 0.25, f"16 runs must resolve the 25 % margin (se {se:.3f})"
    assert ratio <= 1.25, f"{ratio:.3f} ± {se:.3f}× the per-run bound"
    assert ratio >= 1.0 - Z * se, f"{ratio:.3f} ± {se:.3f}: below the bound"
    assert bridged.summary["diverged_fraction"] == 0.0
    assert kf - Z * se_kf > 1.25, f"without the bridge: {kf:.3f} ± {se_kf:.3f}×"
