"""χ² functions against closed forms (even dof: Poisson sum; dof 1 and 3: erf) and tables."""

import math

import pytest

from drake_uuv.models.statistics import chi2_cdf, chi2_ppf, nees_band, regularized_gamma_p


def _cdf_closed_form(x: float, dof: int) -> float:
    """P(χ²(dof) ≤ x) by the textbook closed forms (Abramowitz & Stegun 26.4.4, 26.4.21)."""
    h = 0.5 * x
    if dof % 2 == 0:  # 1 − e^{−h} Σ_{j < dof/2} h^j / j!
        return 1.0 - math.exp(-h) * sum(h**j / math.factorial(j) for j in range(dof // 2))
    if dof == 1:
        return math.erf(math.sqrt(h))
    if dof == 3:
        return math.erf(math.sqrt(h)) - math.sqrt(2.0 * x / math.pi) * math.exp(-h)
    raise ValueError(dof)


@pytest.mark.parametrize("dof", [1, 2, 3, 4, 6, 12, 40])
@pytest.mark.parametrize("x", [0.01, 0.5, 1.0, 3.0, 6.0, 14.4, 30.0, 60.0])
def test_cdf_matches_the_closed_forms_on_both_branches(x, dof):
    # x < a + 1 takes the series, x ≥ a + 1 the continued fraction (a = dof / 2).
    assert chi2_cdf(x, dof) == pytest.approx(_cdf_closed_form(x, dof), rel=1e-9, abs=1e-15)


@pytest.mark.parametrize("dof", [1, 2, 6, 100])
@pytest.mark.parametrize("probability", [0.001, 0.025, 0.5, 0.95, 0.975, 0.999])
def test_ppf_inverts_the_cdf(probability, dof):
    assert chi2_cdf(chi2_ppf(probability, dof), dof) == pytest.approx(probability, rel=1e-10)


def test_ppf_has_closed_forms_for_one_and_two_degrees_of_freedom():
    z = 1.959963984540054  # standard normal 0.975 quantile: χ²(1) 0.95 quantile is z²
    assert chi2_ppf(0.95, 1) == pytest.approx(z * z, rel=1e-10)
    for p in (0.05, 0.5, 0.99):  # χ²(2) is exponential with mean 2
        assert chi2_ppf(p, 2) == pytest.approx(-2.0 * math.log1p(-p), rel=1e-10)


@pytest.mark.parametrize(
    ("probability", "dof", "expected"),
    [
        (0.975, 6, 14.4494),
        (0.025, 6, 1.2373),
        (0.95, 1, 3.8415),
        (0.975, 100, 129.5612),
        (0.025, 100, 74.2219),
    ],
)
def test_ppf_matches_published_tables(probability, dof, expected):
    assert chi2_ppf(probability, dof) == pytest.approx(expected, abs=5e-5)


def test_nees_band_narrows_around_the_dimension_with_more_runs():
    low1, high1 = nees_band(6, 1)
    low100, high100 = nees_band(6, 100)
    assert low1 < low100 < 6 < high100 < high1
    assert (low1, high1) == (chi2_ppf(0.025, 6), chi2_ppf(0.975, 6))
    assert low100 == pytest.approx(chi2_ppf(0.025, 600) / 100, rel=1e-12)


def test_edges_and_bad_input():
    assert regularized_gamma_p(3.0, 0.0) == 0.0
    assert regularized_gamma_p(3.0, math.inf) == 1.0
    with pytest.raises(ValueError, match=r"^a: must be > 0, got 0\.0$"):
        regularized_gamma_p(0.0, 1.0)
    with pytest.raises(ValueError, match=r"^probability: must be in \(0, 1\), got 1\.0$"):
        chi2_ppf(1.0, 6)
    with pytest.raises(ValueError, match=r"^dof: must be > 0, got 0$"):
        chi2_ppf(0.5, 0)
