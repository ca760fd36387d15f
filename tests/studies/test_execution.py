"""Running studies: the same numbers whatever the backend or chunking; resume; bad requests."""

import collections
import math
import os

import numpy as np
import pytest

from drake_uuv.simulation import ClosedLoopSimulation
from drake_uuv.studies import MonteCarloError, completed_seeds, execution, run_study
from drake_uuv.studies.execution import automatic_chunk_size, chunks, connect, execute_local
from tests.studies.study_helpers import outputs

RUNS = 6
QUIET = dict(progress=False, figures=False)


# ----------------------------------------------------------------------- reproducibility


@pytest.mark.slow
def test_summary_is_identical_for_one_and_two_workers_and_on_dask(tmp_path, make_study):
    distributed = pytest.importorskip("dask.distributed")
    serial = run_study(make_study(tmp_path / "serial", RUNS), workers=1, **QUIET)
    pooled = run_study(make_study(tmp_path / "pool", RUNS), workers=2, chunk_size=1, **QUIET)
    with distributed.LocalCluster(
        processes=False, n_workers=1, threads_per_worker=2, dashboard_address=None
    ) as cluster:
        on_dask = run_study(
            make_study(tmp_path / "dask", RUNS),
            scheduler=cluster.scheduler_address,
            chunk_size=2,
            **QUIET,
        )
    assert serial.computed == pooled.computed == on_dask.computed == RUNS
    reference = outputs(tmp_path / "serial")
    assert outputs(tmp_path / "pool") == reference
    assert outputs(tmp_path / "dask") == reference
    np.testing.assert_array_equal(serial.norms, pooled.norms)
    np.testing.assert_array_equal(serial.norms, on_dask.norms)
    np.testing.assert_array_equal(serial.seeds, np.arange(RUNS))
    # Chunks of 1, 2 and 6 (automatic) seeds: one part file per chunk.
    assert len(list((tmp_path / "pool" / "runs").glob("part-*.npz"))) == RUNS
    assert len(list((tmp_path / "dask" / "runs").glob("part-*.npz"))) == RUNS // 2
    assert serial.summary["pcrlb_position_rmse"] is not None  # the exact information sum


@pytest.mark.slow
def test_run_i_uses_seed_random_seed_plus_i(tmp_path, make_study):
    base = run_study(make_study(tmp_path / "a", 4), workers=1, **QUIET)
    shifted = run_study(make_study(tmp_path / "b", 2, seed=2), workers=1, **QUIET)
    np.testing.assert_array_equal(shifted.seeds, [2, 3])
    np.testing.assert_array_equal(shifted.metrics, base.metrics[2:])
    np.testing.assert_array_equal(shifted.norms, base.norms[2:])


# ---------------------------------------------------------------------------- resuming


@pytest.mark.slow
def test_resume_computes_only_the_missing_runs_and_gives_the_same_result(tmp_path, make_study):
    fresh = run_study(make_study(tmp_path / "fresh", RUNS), workers=1, **QUIET)
    folder = tmp_path / "resumed"
    first = run_study(make_study(folder, 2), workers=1, **QUIET)
    assert first.computed == 2
    resumed = run_study(make_study(folder, RUNS), workers=2, resume=True, **QUIET)
    assert resumed.computed == RUNS - 2
    assert outputs(folder) == outputs(tmp_path / "fresh")
    again = run_study(make_study(folder, RUNS), workers=1, resume=True, **QUIET)
    assert again.computed == 0
    assert again.summary == fresh.summary
    fewer = run_study(make_study(folder, 3), workers=1, resume=True, **QUIET)
    assert fewer.computed == 0 and fewer.summary["runs"] == 3
    np.testing.assert_array_equal(fewer.metrics, fresh.metrics[:3])


@pytest.mark.slow
def test_without_resume_old_runs_are_discarded(tmp_path, make_study):
    run_study(make_study(tmp_path, 4), workers=1, chunk_size=1, **QUIET)
    assert completed_seeds(tmp_path) == {0, 1, 2, 3}
    result = run_study(make_study(tmp_path, 2), workers=1, **QUIET)
    assert result.computed == 2
    assert completed_seeds(tmp_path) == {0, 1}  # the parts of seeds 2 and 3 are gone
    assert (tmp_path / "runs.csv").read_text().count("\n") == 1 + 2


@pytest.mark.slow
def test_resume_refuses_a_folder_of_another_scenario(tmp_path, make_study):
    run_study(make_study(tmp_path, 2), workers=1, **QUIET)
    other = make_study(tmp_path, 2, "attitude=!RandomAttitude")
    with pytest.raises(
        MonteCarloError,
        match=r"another scenario: attitude\.variant \('TrajectoryAttitude' on disk, "
        r"'RandomAttitude' now\)$",
    ):
        run_study(other, workers=1, resume=True, **QUIET)
    assert completed_seeds(tmp_path) == {0, 1}  # nothing was discarded


# ------------------------------------------------------------------------------ failures


@pytest.mark.slow
def test_runs_stopped_by_the_monitor_count_as_failed_and_diverged(
    tmp_path, make_study, monkeypatch
):
    original = ClosedLoopSimulation.run_batch

    def run_batch(self, seeds, **options):
        """The monitor's record for seeds 1 and 2, whatever batch they run in."""
        result = original(self, seeds, **options)
        for i, seed in enumerate(result.seeds):
            if seed in (1, 2):
                result.failures[i] = "a test failure at step k=3 (t=1.5 s)"
        return result

    monkeypatch.setattr(ClosedLoopSimulation, "run_batch", run_batch)
    one_per_part = run_study(make_study(tmp_path / "a", 4), workers=1, chunk_size=1, **QUIET)
    one_part = run_study(make_study(tmp_path / "b", 4), workers=1, chunk_size=4, **QUIET)
    assert outputs(tmp_path / "a") == outputs(tmp_path / "b")  # parts of failed runs only
    summary = one_per_part.summary
    assert summary["completed_runs"] == 2 and summary["failed_fraction"] == 0.5
    assert summary["diverged_fraction"] >= 0.5
    assert "pcrlb_position_rmse" not in summary  # no exact information sum with a failed run
    np.testing.assert_array_equal(one_part.column("failed"), [0, 1, 1, 0])
    assert np.isnan(one_part.column("position_rmse")[1])
    completed = one_part.column("position_rmse")[[0, 3]]
    assert summary["position_rmse"] == pytest.approx(math.sqrt(np.mean(completed**2)))


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (dict(chunk_size=0), r"^--chunk-size: must be ≥ 1, got 0$"),
        (dict(workers=0), r"^--workers: must be ≥ 1, got 0$"),
        (dict(workers=-2), r"^--workers: must be ≥ 1, got -2$"),
    ],
)
def test_bad_execution_options_are_refused_before_any_run(tmp_path, make_study, options, message):
    with pytest.raises(MonteCarloError, match=message):
        run_study(make_study(tmp_path, 2), **QUIET, **options)
    assert completed_seeds(tmp_path) == set()


def test_a_study_of_no_runs_is_refused(tmp_path, make_study):
    with pytest.raises(MonteCarloError, match=r"^--runs: must be ≥ 1, got 0$"):
        run_study(make_study(tmp_path, 0), workers=1, **QUIET)


@pytest.mark.slow
def test_an_unreachable_scheduler_is_refused_naming_it():
    dask = pytest.importorskip("dask")
    pytest.importorskip("dask.distributed")
    with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
        with pytest.raises(
            MonteCarloError, match=r"^--scheduler: cannot connect to 'tcp://127\.0\.0\.1:9'"
        ):
            connect("tcp://127.0.0.1:9")


# ------------------------------------------------------------------------------ chunking


def test_chunks_cover_the_seeds_in_order():
    assert chunks([5, 6, 7, 8, 9], 2) == [[5, 6], [7, 8], [9]]
    assert chunks([], 3) == []


@pytest.mark.parametrize(
    ("total", "slots", "size"),
    [(0, 2, 1), (1, 2, 1), (4, 2, 1), (5, 2, 2), (100, 2, 25), (1000, 2, 250), (1000, 64, 8)],
)
def test_automatic_chunks_are_about_two_per_slot_and_at_most_250(total, slots, size):
    assert automatic_chunk_size(total, slots) == size


def _worker_pid(task: int) -> tuple[int, int]:
    return task, os.getpid()


def test_a_pool_is_replaced_after_its_share_of_tasks(monkeypatch):
    # A worker's memory grows with every simulation it builds (pydrake never frees a Python
    # system), so each pool of 2 workers takes 2 * 2 tasks and a fresh pool the next.
    monkeypatch.setattr(execution, "TASKS_PER_WORKER", 2)
    monkeypatch.setattr(execution, "run_task", _worker_pid)  # inherited by the forked workers
    done: dict[int, int] = {}
    execute_local(list(range(12)), 2, done.__setitem__)
    assert sorted(done) == list(range(12))  # every task once
    # Tasks 0-3 went to the first pool, 4-7 to the second, 8-11 to the third: no worker ran
    # tasks of two pools.
    pools = [{done[t] for t in range(first, first + 4)} for first in (0, 4, 8)]
    assert not (pools[0] & pools[1] or pools[1] & pools[2] or pools[0] & pools[2])
    assert max(collections.Counter(done.values()).values()) <= 4
