"""Small statistics helpers: bootstrap and binomial intervals, and the χ² functions.

The χ² functions (``regularized_gamma_p``, ``chi2_cdf``, ``chi2_ppf``, ``nees_band``) live in
:mod:`drake_uuv.models.statistics`, where the estimators' NIS gate can use them without
importing the analysis layer; they are re-exported here. The intervals stay here: only the
analysis of finished runs (Monte Carlo summaries, the claim tests) uses them.
"""

import math
from collections.abc import Callable

import numpy as np

from drake_uuv.models.statistics import chi2_cdf, chi2_ppf, nees_band, regularized_gamma_p

__all__ = [
    "Z_95",
    "bootstrap_interval",
    "chi2_cdf",
    "chi2_ppf",
    "nees_band",
    "regularized_gamma_p",
    "wilson_interval",
]

# The standard normal quantile at 0.975: a 95 % two-sided interval.
Z_95 = 1.959963984540054


def bootstrap_interval(
    values: np.ndarray,
    statistic: Callable[[np.ndarray], np.ndarray],
    resamples: int = 2000,
    level: float = 0.95,
    seed: int = 0,
) -> tuple[float, float]:
    """Percentile bootstrap interval of ``statistic`` over the rows of ``values``.

    ``statistic`` maps an array whose last axis holds one resample to one value per resample
    (e.g. ``lambda x: np.sqrt(x.mean(axis=-1))``). The generator is seeded, so the interval
    depends only on ``values`` (in order), never on how they were computed.
    """
    values = np.asarray(values, dtype=float)
    if values.size == 0:
        return math.nan, math.nan
    rng = np.random.default_rng(seed)
    indices = rng.integers(0, len(values), size=(resamples, len(values)))
    with np.errstate(over="ignore", invalid="ignore"):
        estimates = statistic(values[indices])
    tail = 50.0 * (1.0 - level)
    low, high = np.percentile(estimates, [tail, 100.0 - tail])
    return float(low), float(high)


def wilson_interval(successes: int, trials: int, z: float = Z_95) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion (sensible at 0 and 1, unlike Wald)."""
    if trials == 0:
        return math.nan, math.nan
    p = successes / trials
    denominator = 1.0 + z * z / trials
    centre = (p + z * z / (2.0 * trials)) / denominator
    half = z * math.sqrt(p * (1.0 - p) / trials + z * z / (4.0 * trials * trials)) / denominator
    low = 0.0 if successes == 0 else max(0.0, centre - half)
    high = 1.0 if successes == trials else min(1.0, centre + half)
    return low, high
