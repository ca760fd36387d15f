"""The closed loop as a whole: log layout, reproducibility, the filter replay, statistics."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from drake_uuv import ClosedLoopSimulation, load_scenario, make_uuv_diagram, simulate
from drake_uuv.simulation import read_log

LOG_KEYS = {
    "k": (), "time": (), "p_WU": (3,), "v_WU": (3,), "R_WB": (3, 3), "p_WU_nav": (3,),
    "v_WU_nav": (3,), "R_WB_nav": (3, 3), "p_WT": (3,),
    "v_WT": (3,), "ranges": (2,), "Y": (), "m": (), "Gamma": (), "b_W": (3,),
    "x_TU_hat": (6,), "P_TU": (6, 6), "u1_B": (3,), "u2_W": (3,), "u1_W": (3,),
    "sonar_status": (2,), "multipath": (2,), "ping_time": (2,), "p_TS_W": (6,),
    "measurement_status": (), "nis": (),
}  # fmt: skip


@pytest.fixture(scope="module")
def paper_run():
    return simulate(load_scenario("paper"))


def test_diagram_names_every_system(paper) -> None:
    diagram = make_uuv_diagram(paper).diagram
    names = {diagram.GetSubsystemByName(n).get_name() for n in ("uuv", "target", "sonar")}
    assert names == {"uuv", "target", "sonar"}
    for name in ("estimator", "attitude_generator", "tracking_controller", "range_noise"):
        assert diagram.HasSubsystemNamed(name)
    assert diagram.HasSubsystemNamed("log_x_TU_hat")


def test_log_layout(paper_run) -> None:
    log = paper_run.log
    assert set(log) == set(LOG_KEYS)
    for key, shape in LOG_KEYS.items():
        assert log[key].shape == (500, *shape), key
    assert log["sonar_status"].dtype == np.int8 and log["measurement_status"].dtype == np.int8
    assert_allclose(log["time"], 0.5 * np.arange(500))
    # Row 0 holds the initial state, before the first update.
    assert_allclose(log["p_WT"][0], [1, 2, 2])
    assert_allclose(log["v_WT"][0], [0.02, 0.1, 0.1])
    assert_allclose(log["p_WU"][0], 0)
    assert_allclose(log["R_WB"][0], np.eye(3))
    # Row k+1 follows from row k through the model: the log is one consistent trajectory.
    t = 0.5
    assert_allclose(log["v_WU"][1:], log["v_WU"][:-1] + t * log["u1_W"][:-1], atol=1e-9)
    assert_allclose(
        log["u1_W"], np.einsum("kij,kj->ki", log["R_WB"], log["u1_B"]), rtol=1e-12, atol=1e-12
    )
    assert_allclose(np.einsum("kij,j->ki", log["R_WB"], [-1, 1, 0]), log["b_W"], atol=1e-12)
    # The paper scenario has no faults: every measurement was used.
    assert not log["sonar_status"].any() and not log["measurement_status"].any()
    assert not log["multipath"].any() and np.all(np.isfinite(log["nis"]))


def test_attitude_stays_orthonormal(paper_run) -> None:
    R = paper_run.log["R_WB"]
    assert_allclose(
        np.einsum("kji,kjl->kil", R, R), np.broadcast_to(np.eye(3), R.shape), atol=1e-12
    )


def test_filter_replay_from_any_logged_step(paper_run) -> None:
    """The paper's KF equations, written out here, on the logged measurements from any logged
    estimate reproduce every later logged estimate: the log holds what the filter used."""
    log = paper_run.log
    t = 0.5
    A = np.block([[np.eye(3), t * np.eye(3)], [np.zeros((3, 3)), np.eye(3)]])
    B = np.vstack([0.5 * t * t * np.eye(3), t * np.eye(3)])
    Q = B @ np.diag([0.004, 0.001, 0.001]) @ B.T
    for start in (0, 137, 420):
        x = log["x_TU_hat"][start]
        P = log["P_TU"][start]
        for k in range(start + 1, 500):
            x = A @ x + B @ log["u1_W"][k - 1]
            P = A @ P @ A.T + Q
            C = np.concatenate([log["b_W"][k], np.zeros(3)])
            S = C @ P @ C + log["Gamma"][k]
            K = P @ C / S
            x = x + K * (log["Y"][k] - C @ x - log["m"][k])
            I_KC = np.eye(6) - np.outer(K, C)
            P = I_KC @ P @ I_KC.T + log["Gamma"][k] * np.outer(K, K)
            assert_allclose(x, log["x_TU_hat"][k], rtol=1e-9, atol=1e-9)
            assert_allclose(P, log["P_TU"][k], rtol=1e-9, atol=1e-12)


def test_measurements_in_the_log_are_the_ones_the_filter_used(paper_run) -> None:
    log = paper_run.log
    assert_allclose(log["Y"], 0.5 * (log["ranges"][:, 0] ** 2 - log["ranges"][:, 1] ** 2))


@pytest.mark.slow
def test_same_seed_same_log_and_different_seed_different_log(paper) -> None:
    simulation = ClosedLoopSimulation(paper)
    first, again, other = simulation.run(3), simulation.run(3), simulation.run(4)
    rebuilt = simulate(load_scenario("paper", seed=3))
    for key in first.log:
        np.testing.assert_array_equal(first.log[key], again.log[key])
        np.testing.assert_array_equal(first.log[key], rebuilt.log[key])
    assert not np.array_equal(first.log["ranges"], other.log["ranges"])
    assert not np.array_equal(first.log["p_WT"][1:], other.log["p_WT"][1:])


def test_random_attitude_mode_is_reproducible() -> None:
    scenario = load_scenario(
        "paper", ["attitude=!RandomAttitude", "steps=50", "steady_state_start=0"]
    )
    a, b = simulate(scenario).log, simulate(scenario).log
    np.testing.assert_array_equal(a["R_WB"], b["R_WB"])
    assert not np.allclose(a["R_WB"][1], a["R_WB"][2])


SEEDS = range(20)


@pytest.fixture(scope="module")
def derived_nees() -> np.ndarray:
    simulation = ClosedLoopSimulation(load_scenario("paper"))
    return np.array([simulation.run(seed).metrics["nees_mean"] for seed in SEEDS])


@pytest.mark.slow
def test_derived_noise_model_is_consistent(derived_nees: np.ndarray) -> None:
    """Mean NEES of a consistent 6-D filter is 6.

    The per-run means are independent across seeds; their spread gives the standard error of
    the mean over 20 runs, and we allow 3 of them (a 99.7 % band).
    """
    n = len(derived_nees)
    standard_error = derived_nees.std(ddof=1) / np.sqrt(n)
    assert abs(derived_nees.mean() - 6.0) < 3.0 * standard_error, (
        derived_nees.mean(),
        standard_error,
    )


# Fixed attitude diverging while Algorithm 2 stays bounded: tests/test_paper_claims.py.


def test_read_log_reads_a_saved_run(paper_run, tmp_path) -> None:
    paper_run.save(tmp_path)
    log = read_log(tmp_path / "log.npz")
    assert set(log) == set(LOG_KEYS)
    for key in LOG_KEYS:
        np.testing.assert_array_equal(log[key], paper_run.log[key])
        assert log[key].dtype == paper_run.log[key].dtype


@pytest.mark.parametrize(
    "overrides",
    [
        [],
        [
            "sonar.ping_offsets=[0.1, 0.3]",
            "sonar.latency=0.6",
            "estimator.vehicle_motion=navigation",
        ],
    ],
    ids=["paper", "timed-extended-bound"],
)
@pytest.mark.slow
def test_a_run_logging_only_the_metric_signals_has_the_same_metrics(overrides) -> None:
    scenario = load_scenario("paper", [*overrides, "steps=120", "steady_state_start=40"])
    full = ClosedLoopSimulation(scenario).run()
    lean = ClosedLoopSimulation(scenario, log="metrics").run()
    assert set(lean.log) < set(full.log) and "u1_B" not in lean.log
    drop = {"wall_time_s"}
    assert {k: v for k, v in lean.metrics.items() if k not in drop} == {
        k: v for k, v in full.metrics.items() if k not in drop
    }
    assert lean.warnings == full.warnings
    for key in lean.log:
        assert np.array_equal(lean.log[key], full.log[key], equal_nan=True), key


def test_a_bad_log_choice_is_named(paper) -> None:
    with pytest.raises(ValueError, match=r"^log: must be one of full, metrics, got 'some'$"):
        ClosedLoopSimulation(paper, log="some")
    with pytest.raises(ValueError, match=r"^log: must be True, False or a collection .* 'p_WU'$"):
        make_uuv_diagram(paper, log="p_WU")


def test_a_diagram_logs_the_signals_it_is_given(paper) -> None:
    built = make_uuv_diagram(paper, log=["p_WU", "x_TU_hat", "u1_B"])
    assert set(built.loggers) == {"p_WU", "x_TU_hat", "u1_B"}
