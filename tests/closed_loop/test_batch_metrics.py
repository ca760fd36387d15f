"""The metrics of a batch log: run i's are the bits of run_metrics on run i's own log."""

import numpy as np
import pytest

import drake_uuv.metrics as metrics_module
from drake_uuv.diagnostics import batch_warnings, run_warnings
from drake_uuv.metrics import (
    _nees,
    batch_metrics,
    errors,
    metric_signals,
    run_log,
    run_metrics,
    smallest_eigenvalues,
)
from drake_uuv.models.measurement import DROPPED, VALID
from drake_uuv.models.so3 import exp_so3_runs
from drake_uuv.scenario import Scenario, load_scenario
from drake_uuv.simulation import ClosedLoopSimulation
from tests.closed_loop.test_metrics import _synthetic_log

STEPS, START = 50, 20


def random_log(rng: np.random.Generator, runs: int, vehicle: bool = True) -> dict:
    """B random runs of STEPS steps: every signal the metrics read, some sonar returns lost,
    some covariances not positive definite (or ill-conditioned, or NaN); run 1 all NaN from
    step 30 on (a failed run) when B > 1."""
    shape = (runs, STEPS)
    log = {"k": np.arange(STEPS), "time": 0.5 * np.arange(STEPS)}
    for name in ("p_WU", "v_WU", "p_WT", "v_WT", "u1_W", "w_WB", "w_WB_command"):
        log[name] = rng.normal(size=(*shape, 3))
    log["p_WT"] += [2.0, 2.0, 0.0]
    log["R_WB"] = exp_so3_runs(rng.normal(size=(*shape, 3)))
    log["b_W"] = log["R_WB"] @ np.array([-1.0, 1.0, 0.0])
    log["x_TU_hat"] = np.concatenate(
        [log["p_WU"] - log["p_WT"], log["v_WU"] - log["v_WT"]], axis=-1
    ) + 0.1 * rng.normal(size=(*shape, 6))
    G = rng.normal(size=(*shape, 6, 6))
    log["P_TU"] = 0.01 * G @ np.swapaxes(G, -1, -2) + 1e-3 * np.eye(6)
    log["P_TU"][:, 3] = np.diag([1.0, 1.0, 1.0, 1.0, 1.0, -1e-3])  # indefinite
    log["P_TU"][:, 7] = np.diag([1e17, 1.0, 1.0, 1.0, 1.0, 1.0])  # beyond rounding
    log["P_TU"][:, 9] = np.diag([1e15, 1.0, 1.0, 1.0, 1.0, 1.0])  # near the limit: kept
    log["sonar_status"] = np.where(rng.random((*shape, 2)) < 0.1, DROPPED, VALID).astype(np.int8)
    if vehicle:
        log["R_WB_command"] = exp_so3_runs(0.01 * rng.normal(size=(*shape, 3))) @ log["R_WB"]
        log["saturation_ticks"] = np.cumsum(rng.integers(0, 3, size=(*shape, 4)), axis=1) * 1.0
    if runs > 1:
        for name, value in log.items():
            if name not in ("k", "time", "sonar_status"):
                value[1, 30:] = np.nan
    return log


def _scenario(*overrides: str) -> Scenario:
    return load_scenario("paper", [f"steps={STEPS}", f"steady_state_start={START}", *overrides])


def assert_each_run_alone(log: dict, scenario: Scenario) -> dict[str, np.ndarray]:
    batch = batch_metrics(log, scenario)
    runs = len(log["p_WU"])
    assert all(value.shape == (runs,) for value in batch.values())
    for i in range(runs):
        alone = run_metrics(run_log(log, i), scenario)
        assert sorted(alone) == sorted(batch)
        for name, value in alone.items():
            assert np.array_equal(batch[name][i], value, equal_nan=True), (name, i)
    return batch


@pytest.mark.parametrize("frame", ["body", "heading"])
def test_random_batches_are_each_run_alone(monkeypatch, frame: str) -> None:
    """Five random runs, by chunks of two (the chunks must not matter), and their order
    reversed: each run's metrics are its own bits."""
    monkeypatch.setattr(metrics_module, "METRICS_CHUNK", 2)
    scenario = _scenario(f"tracking.reference_frame={frame}")
    log = random_log(np.random.default_rng(1), 5)
    batch = assert_each_run_alone(log, scenario)
    assert np.all(np.isnan(batch["position_rmse"][1])) and np.all(
        np.isfinite(batch["pcrlb_position_rmse"][[0, 2, 3, 4]])
    )
    reversed_log = {k: v if k in ("k", "time") else v[::-1] for k, v in log.items()}
    again = batch_metrics(reversed_log, scenario)
    for name, value in batch.items():
        assert np.array_equal(again[name][::-1], value, equal_nan=True), name
    assert "thrust_saturated_fraction" in batch
    no_vehicle = random_log(np.random.default_rng(2), 3, vehicle=False)
    assert "attitude_error_mean" not in assert_each_run_alone(no_vehicle, scenario)


def test_the_extended_bound_of_a_batch_is_each_run_alone() -> None:
    scenario = _scenario("navigation=!InertialNavigation")
    log = random_log(np.random.default_rng(3), 3)
    batch = assert_each_run_alone(log, scenario)
    assert "pcrlb_floor_position_rmse" in batch


@pytest.mark.parametrize(
    ("name", "overrides", "steps"),
    [
        ("paper", ["estimator=!Ekf"], 80),
        ("hovering_auv", [], 40),
        ("realistic", ["plant=!KinematicUuv"], 40),
    ],
)
def test_real_runs_as_a_batch_are_each_run_alone(name: str, overrides: list, steps: int) -> None:
    """Three seeds of a scenario simulated one by one, their logs stacked: the batch's
    metrics are each run's, bit for bit (and the signals read are the metric signals)."""
    scenario = load_scenario(
        name, [*overrides, f"steps={steps}", f"steady_state_start={steps // 2}"]
    )
    simulation = ClosedLoopSimulation(scenario, log="metrics")
    logs = [simulation.run(seed).log for seed in (1, 2, 3)]
    log = {
        key: logs[0][key] if key in ("k", "time") else np.stack([run[key] for run in logs])
        for key in logs[0]
    }
    assert set(log) - {"k", "time"} <= metric_signals(scenario)
    batch = assert_each_run_alone(log, scenario)
    for i, run in enumerate(logs):
        alone = run_metrics(run, scenario)
        assert all(np.array_equal(batch[k][i], v, equal_nan=True) for k, v in alone.items())


def test_the_nees_fast_path_keeps_the_rule() -> None:
    """Positive definite well inside the limit: |L⁻¹ e|², the LU solve's value to rounding;
    at the limit (λ_min/λ_max around 6 ε) the eigenvalues decide, as the rule states."""
    rng = np.random.default_rng(4)
    G = rng.normal(size=(200, 6, 6))
    P = G @ np.swapaxes(G, -1, -2) + 1e-6 * np.eye(6)
    e = rng.normal(size=(200, 6))
    eps = np.finfo(float).eps
    for i, ratio in enumerate([3 * eps, 5 * eps, 7 * eps, 12 * eps, 100 * eps, 0.0, -eps]):
        P[i] = np.diag([1.0, 1.0, 1.0, 1.0, 1.0, ratio])
    nees = _nees(e, P)
    values = np.linalg.eigvalsh(P)
    ok = values[:, 0] > 6 * eps * values[:, -1]
    assert np.array_equal(np.isinf(nees), ~ok)
    expected = np.einsum("ki,ki->k", e[ok], np.linalg.solve(P[ok], e[ok, :, None])[:, :, 0])
    np.testing.assert_allclose(nees[ok], expected, rtol=1e-8)
    # The same steps as a batch of runs: the same bits.
    batch = _nees(e.reshape(4, 50, 6), P.reshape(4, 50, 6, 6))
    assert np.array_equal(batch.ravel(), nees)


def test_the_smallest_eigenvalues_are_lapacks() -> None:
    rng = np.random.default_rng(5)
    G = rng.normal(size=(500, 3, 3))
    S = G @ np.swapaxes(G, -1, -2)
    S[0] = np.diag([2.0, 1.0, 3.0])
    S[1] = np.zeros((3, 3))
    S[2] = np.outer([1.0, 2.0, 3.0], [1.0, 2.0, 3.0])  # rank one
    got = smallest_eigenvalues(S)
    expected = np.linalg.eigvalsh(S)[:, 0]
    scale = np.linalg.norm(S, axis=(1, 2))
    assert np.all(np.abs(got - expected) <= 1e-14 * np.maximum(scale, 1e-300))
    assert got[0] == 1.0 and got[1] == 0.0


def test_a_log_without_a_run_axis_is_named() -> None:
    log = random_log(np.random.default_rng(6), 1)
    with pytest.raises(ValueError, match=r"^log: p_WU must have shape \(B ≥ 1, N, 3\)"):
        batch_metrics(run_log(log, 0), _scenario())


def test_errors_of_a_batch_are_each_runs() -> None:
    scenario = _scenario("tracking.reference_frame=heading")
    log = random_log(np.random.default_rng(7), 3)
    batch = errors(log, scenario)
    for i in range(3):
        for name, value in errors(run_log(log, i), scenario).items():
            assert np.array_equal(batch[name][i], value, equal_nan=True), name


def test_the_warnings_of_a_batch_are_each_runs() -> None:
    """Runs that keep their assumptions, lose the target, have an overconfident filter or a
    NaN log: each run's warnings are those of the run alone."""
    scenario = _scenario("estimator=!Ekf")
    log = random_log(np.random.default_rng(8), 4)
    log["estimator_phase"] = np.zeros((4, STEPS, 2))
    log["estimator_phase"][2] = 1.0
    log["x_TU_hat"][3] += 30.0  # far off: tracking is fine, the NEES is not
    metrics = batch_metrics(log, scenario)
    metrics["tracking_rmse"][0] = 25.0
    warned = batch_warnings(log, metrics, scenario)
    assert len(warned) == 4
    for i in range(4):
        alone = run_warnings(
            run_log(log, i), {k: float(v[i]) for k, v in metrics.items()}, scenario
        )
        assert warned[i] == alone
    assert "tracking" in [w.code for w in warned[0]]
    assert "nees" in [w.code for w in warned[3]]


def test_a_run_of_infs_and_nans_warns_of_nothing_and_leaves_the_others() -> None:
    """A run whose log overflowed (inf, −inf, NaN mixed) gives non-finite metrics without a
    floating-point warning, and the other runs' metrics are unchanged."""
    scenario = _scenario("navigation=!InertialNavigation")
    log = random_log(np.random.default_rng(9), 3)
    clean = batch_metrics(log, scenario)
    for name, value in log.items():
        if name not in ("k", "time", "sonar_status"):
            value[2, 10:] = np.where(
                np.arange(value[2, 10:].size).reshape(value[2, 10:].shape) % 2, np.inf, -np.inf
            )
    with np.errstate(all="raise"):
        broken = batch_metrics(log, scenario)
    for name, value in clean.items():
        assert np.array_equal(broken[name][:2], value[:2], equal_nan=True), name
    assert not np.isfinite(broken["position_rmse"][2])


def test_a_failed_run_whose_pings_cannot_be_read_leaves_the_others() -> None:
    """With sonar timing the bound reads each run's pings; a failed run's NaN ping times and
    state give it NaN bounds while the others keep their own (the same as alone); a sound run
    whose pings are wrong still raises."""
    scenario = _scenario("sonar.ping_offsets=[0.1, 0.3]", "sonar.latency=0.6")
    runs = [_synthetic_log(scenario, seed) for seed in (1, 2)]
    rng = np.random.default_rng(10)
    for run in runs:
        run["x_TU_hat"] = np.concatenate(
            [run["p_WU"] - run["p_WT"], run["v_WU"] - run["v_WT"]], axis=1
        ) + 0.1 * rng.normal(size=(STEPS, 6))
        run["P_TU"] = np.tile(0.01 * np.eye(6), (STEPS, 1, 1))
    log = {name: np.stack([run[name] for run in runs]) for name in runs[0]}
    log["k"], log["time"] = np.arange(STEPS), 0.5 * np.arange(STEPS)
    log["ping_time"][1, 30:] = np.nan
    log["p_WU"][1, 30:] = np.nan
    batch = batch_metrics(log, scenario)
    alone = run_metrics(run_log(log, 0), scenario)
    assert all(np.array_equal(batch[k][0], v) for k, v in alone.items())
    assert np.isnan(batch["pcrlb_position_rmse"][1])
    with pytest.raises(ValueError, match="ping_time"):
        wrong = run_log(log, 0)
        wrong["ping_time"] = wrong["ping_time"] + 5.0
        batch_metrics({k: v if k in ("k", "time") else v[None] for k, v in wrong.items()}, scenario)
