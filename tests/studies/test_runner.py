"""Running seeds in one process: metrics agree with the norms, exact information sums."""

import math
import threading
import warnings

import numpy as np
import pytest

from drake_uuv.metrics import run_information
from drake_uuv.scenario import load_scenario
from drake_uuv.simulation import ClosedLoopSimulation
from drake_uuv.studies.runner import (
    NORMS,
    cached_simulation,
    canonical_metric_names,
    information_exponent,
    run_seeds,
    run_task,
)


def test_information_exponent_leaves_room_for_a_million_runs(paper):
    # Largest entry of M(k): f (1/η1 + 1/η2) = 1 · (100 + 100) for the paper's sonars.
    largest = 200.0
    e = information_exponent(paper)
    assert largest * 2.0**e * 2**20 <= 2.0**62  # 2^20 runs of the largest entry fit in int64
    assert largest * 2.0 ** (e + 1) * 2**20 > 2.0**62  # and no finer unit would
    finer = load_scenario("paper", ["sonar.samples_per_step=4"])
    assert information_exponent(finer) == e - 2  # four times the information: two bits fewer


@pytest.mark.slow
def test_metrics_are_the_steady_state_statistics_of_the_returned_norms(short):
    chunk = run_seeds(short, [3, 4])
    assert chunk["seeds"].tolist() == [3, 4]
    assert chunk["norms"].shape == (2, len(NORMS), short.steps)
    assert chunk["norms"].dtype == np.float32
    names = chunk["metric_names"]
    assert names[: names.index("failed") + 1][-3:] == [
        "max_tracking_error",
        "final_tracking_error",
        "failed",
    ]
    assert not {"seed", "steps", "wall_time_s"} & set(names)  # not functions of the seed
    start = short.steady_state_start
    for row, norms in zip(chunk["metrics"], chunk["norms"].astype(float), strict=True):
        metric = dict(zip(names, row, strict=True))
        position, velocity, tracking, nees = norms
        # float32 norms: relative agreement to ~1e-7.
        assert metric["position_rmse"] == pytest.approx(
            math.sqrt(np.mean(position[start:] ** 2)), rel=1e-6
        )
        assert metric["velocity_rmse"] == pytest.approx(
            math.sqrt(np.mean(velocity[start:] ** 2)), rel=1e-6
        )
        assert metric["nees_mean"] == pytest.approx(np.mean(nees[start:]), rel=1e-6)
        assert metric["max_tracking_error"] == pytest.approx(np.max(tracking[start:]), rel=1e-6)
        assert metric["final_tracking_error"] == pytest.approx(tracking[-1], rel=1e-6)
        assert metric["final_position_error"] == pytest.approx(position[-1], rel=1e-6)
        assert metric["failed"] == 0.0


@pytest.mark.slow
def test_information_sums_are_exact_integers_whatever_the_chunking(short):
    whole = run_seeds(short, [0, 1, 2])["information_sum"]
    parts = run_seeds(short, [0])["information_sum"] + run_seeds(short, [1, 2])["information_sum"]
    assert whole.dtype == np.int64 and whole.shape == (short.steps, 3, 3)
    np.testing.assert_array_equal(whole, parts)
    # Against the information of each run computed directly: each run rounds to ½ unit.
    simulation = ClosedLoopSimulation(short)
    direct = sum(run_information(simulation.run(s).log, short)[:, :3, :3] for s in range(3))
    unit = 2.0 ** -information_exponent(short)
    np.testing.assert_allclose(whole * unit, direct, rtol=0, atol=1.5 * unit)
    assert np.max(np.abs(direct)) > 1e6 * unit  # the tolerance is far below the values


@pytest.mark.slow
def test_a_run_the_monitor_stops_is_failed_with_nan_metrics_and_no_information(short, monkeypatch):
    original = ClosedLoopSimulation.run_batch

    def run_batch(self, seeds, **options):
        """The monitor's record for seed 1, whatever batch it runs in."""
        result = original(self, seeds, **options)
        for i, seed in enumerate(result.seeds):
            if seed == 1:
                result.failures[i] = "a test failure at step k=3 (t=1.5 s)"
        return result

    monkeypatch.setattr(ClosedLoopSimulation, "run_batch", run_batch)
    chunk = run_seeds(short, [0, 1])
    failed = chunk["metric_names"].index("failed")
    np.testing.assert_array_equal(chunk["metrics"][:, failed], [0.0, 1.0])
    assert np.isnan(np.delete(chunk["metrics"][1], failed)).all()
    assert np.isfinite(chunk["metrics"][0]).all()
    assert np.isnan(chunk["norms"][1]).all() and np.isfinite(chunk["norms"][0]).all()
    assert chunk["information_sum"] is None
    only_failed = run_seeds(short, [1])
    assert only_failed["metric_names"] == ["failed"]
    np.testing.assert_array_equal(only_failed["metrics"], [[1.0]])


def test_any_other_error_names_the_seed(short, monkeypatch):
    """An error inside a batch: its runs go again one by one, and the failing one is named."""

    def run_batch(self, seeds, **options):
        raise ArithmeticError("boom")

    monkeypatch.setattr(ClosedLoopSimulation, "run_batch", run_batch)
    with pytest.raises(RuntimeError, match=r"^run with seed 7 failed: boom$"):
        run_task((0, short, [7]))


def test_the_simulation_is_built_once_per_thread_and_scenario(short):
    first = cached_simulation(short)
    assert cached_simulation(load_scenario("paper", ["steps=80", "steady_state_start=40"])) is first
    assert (
        cached_simulation(load_scenario("paper", ["steps=81", "steady_state_start=40"]))
        is not first
    )
    other: list = []
    thread = threading.Thread(target=lambda: other.append(cached_simulation(short)))
    thread.start()
    thread.join()
    assert other[0] is not first  # a Simulator is not shared between threads


def test_canonical_metric_names_are_a_completed_runs_whatever_the_order():
    completed = ["position_rmse", "nees_mean", "failed"]
    assert canonical_metric_names([["failed"], completed]) == completed
    assert canonical_metric_names([completed, ["failed"]]) == completed
    assert canonical_metric_names([]) == ["failed"]
    assert canonical_metric_names([["failed"], ["failed"]]) == ["failed"]


def test_a_batch_holds_its_log_and_its_particles_within_the_budget():
    """The batch size from the memory a run needs: its metrics' log over every step, and a
    particle cloud's state where the estimator may carry one."""
    from drake_uuv.estimators.particle_cloud import bytes_per_run
    from drake_uuv.studies.runner import BATCH_LOG_BYTES, MAX_BATCH, max_batch_size

    kf = load_scenario("paper")
    pf = load_scenario("paper", ["estimator=ParticleFilter", "estimator.particle_count=20000"])
    assert max_batch_size(kf) <= MAX_BATCH
    assert max_batch_size(pf) < max_batch_size(kf)
    assert max_batch_size(pf) * bytes_per_run(20000) <= BATCH_LOG_BYTES
    assert (max_batch_size(pf) + 1) * bytes_per_run(20000) > 0.5 * BATCH_LOG_BYTES
    # With late ranges the cloud also keeps each window step's draws: the realistic filter's
    # window is 1 step (a ping 0.25 s late and 0.2 s of latency arrive by the next tick),
    # with navigation noise.
    realistic = load_scenario("realistic")
    late = bytes_per_run(20000, 1, navigation_noise=True)
    assert late > 2 * bytes_per_run(20000)
    assert max_batch_size(realistic) * late <= BATCH_LOG_BYTES
    assert (max_batch_size(realistic) + 1) * late > 0.5 * BATCH_LOG_BYTES


def test_norms_beyond_float32_become_inf_without_a_warning():
    # α = 2.2 lies outside the paper's proven interval: the loop grows without bound and its
    # tracking error passes float32's largest value before step 500.
    scenario = load_scenario("paper", ["tracking.alpha=2.2", "tracking.allow_unproven_alpha=true"])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        norms = run_seeds(scenario, [0])["norms"]
    assert norms.dtype == np.float32
    assert np.isinf(norms[0, NORMS.index("tracking")]).any()
