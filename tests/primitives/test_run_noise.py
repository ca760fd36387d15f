"""Per-run noise: each run's draws are a function of its seed, source and step; their
statistics per run and their independence across runs and sources, with tolerances from the
sample size."""

import numpy as np
import pytest
from pydrake.common import RandomDistribution

from drake_uuv.primitives.run_noise import RunNoise, philox4x32, run_draws, source_id

STEPS = 4000
GAUSSIAN, UNIFORM, EXPONENTIAL = (
    RandomDistribution.kGaussian,
    RandomDistribution.kUniform,
    RandomDistribution.kExponential,
)


def stream(seed: int, name: str, size: int, distribution=GAUSSIAN, steps: int = STEPS):
    """Run ``seed``'s draws of ``steps`` steps: (steps, size)."""
    return np.array([run_draws([seed], name, k, size, distribution)[0] for k in range(steps)])


@pytest.mark.parametrize(
    ("distribution", "mean", "variance"),
    [(GAUSSIAN, 0.0, 1.0), (UNIFORM, 0.5, 1 / 12), (EXPONENTIAL, 1.0, 1.0)],
)
def test_each_runs_draws_have_their_distributions_moments(distribution, mean, variance):
    """Mean and variance of 12 000 draws per run, for three runs, within 5 standard errors."""
    for seed in (0, 1, 123456789):
        x = stream(seed, "range_noise", 3, distribution).ravel()
        n = len(x)
        assert abs(x.mean() - mean) < 5 * np.sqrt(variance / n)
        # The sample variance's standard error: sqrt((μ4 − σ⁴)/n) with μ4 = 3σ⁴, 9/5 σ⁴
        # (uniform: 1/80) and 9σ⁴ (exponential: μ4 = 9).
        mu4 = {GAUSSIAN: 3.0, UNIFORM: 1 / 80, EXPONENTIAL: 9.0}[distribution]
        assert abs(x.var() - variance) < 5 * np.sqrt((mu4 - variance**2) / n)


def test_gaussian_tails_are_those_of_a_normal():
    """The fraction beyond 2σ (4.55 %) within 5 binomial standard errors."""
    x = np.concatenate([stream(seed, "acceleration_noise", 3).ravel() for seed in range(3)])
    p = 0.0455003
    assert abs(np.mean(np.abs(x) > 2.0) - p) < 5 * np.sqrt(p * (1 - p) / len(x))


def test_runs_sources_and_components_are_uncorrelated():
    """Correlations over 4000 steps are within 5/√n of zero: across runs, across sources of
    one run, across a port's components and between consecutive steps."""
    bound = 5 / np.sqrt(STEPS)
    a = stream(0, "range_noise", 2)
    b = stream(1, "range_noise", 2)
    c = stream(0, "acceleration_noise", 2)
    pairs = [
        (a[:, 0], b[:, 0]), (a[:, 0], c[:, 0]), (a[:, 0], a[:, 1]), (a[1:, 0], a[:-1, 0]),
        (b[:, 1], c[:, 1]),
    ]  # fmt: skip
    for x, y in pairs:
        assert abs(np.corrcoef(x, y)[0, 1]) < bound


def test_a_runs_draws_do_not_depend_on_its_batch():
    seeds = [7, 3, 2**40, 0, 99]
    batch = run_draws(seeds, "navigation_noise", 17, 6)
    for i, seed in enumerate(seeds):
        np.testing.assert_array_equal(batch[i], run_draws([seed], "navigation_noise", 17, 6)[0])
    np.testing.assert_array_equal(run_draws(seeds[::-1], "navigation_noise", 17, 6), batch[::-1])


def test_the_system_outputs_each_runs_draw_of_the_step_and_holds_it_between_ticks():
    source = RunNoise("range_noise", GAUSSIAN, 2, batch_size=3, time_step=0.5)
    context = source.CreateDefaultContext()
    np.testing.assert_array_equal(source.seeds(context), [0, 1, 2])  # the default seeds
    source.set_seeds(context, [11, 5, 8])
    for time, step in [(0.0, 0), (2.5, 5), (2.5 + 0.3, 5), (3.0 - 1e-12, 6)]:
        context.SetTime(time)
        expected = run_draws([11, 5, 8], "range_noise", step, 2).ravel()
        np.testing.assert_array_equal(source.get_output_port().Eval(context), expected)
    assert source.get_output_port().size() == 6


def test_sources_are_told_apart_by_name():
    assert source_id("range_noise") != source_id("range_noise_")
    assert not np.array_equal(
        run_draws([1], "range_noise", 0, 2), run_draws([1], "rotation_noise", 0, 2)
    )


@pytest.mark.parametrize(
    ("seeds", "message"),
    [
        ([1, 2], r"seeds: must be 3 integers \(one per run\), got \[1, 2\]"),
        ([1, 2.5, 3], r"seeds: must be integers in \[0, 2\^53\), got \[1.0, 2.5, 3.0\]"),
        ([1, -2, 3], r"seeds: must be integers in \[0, 2\^53\), got \[1, -2, 3\]"),
    ],
)
def test_bad_seeds_are_named(seeds, message):
    source = RunNoise("x", GAUSSIAN, 1, batch_size=3, time_step=0.5)
    with pytest.raises(ValueError, match=message):
        source.set_seeds(source.CreateDefaultContext(), seeds)


def test_a_bad_batch_size_is_named():
    with pytest.raises(ValueError, match=r"batch_size: must be an integer ≥ 1, got 0"):
        RunNoise("x", GAUSSIAN, 1, batch_size=0, time_step=0.5)


@pytest.mark.parametrize(
    ("counter", "key", "expected"),
    [
        ((0, 0, 0, 0), (0, 0), (0x6627E8D5, 0xE169C58D, 0xBC57AC4C, 0x9B00DBD8)),
        ((0xFFFFFFFF,) * 4, (0xFFFFFFFF,) * 2, (0x408F276D, 0x41C83B0E, 0xA20BC7C6, 0x6D5451FD)),
        (
            (0x243F6A88, 0x85A308D3, 0x13198A2E, 0x03707344),
            (0xA4093822, 0x299F31D0),
            (0xD16CFE09, 0x94FDCCEB, 0x5001E420, 0x24126EA1),
        ),
    ],
)
def test_the_generator_is_philox4x32_10(counter, key, expected):
    """Random123's known-answer vectors for Philox4x32-10 (its kat_vectors file)."""
    words = philox4x32(*(np.uint64(c) for c in counter), *(np.uint64(k) for k in key))
    assert tuple(int(w) for w in words) == expected
