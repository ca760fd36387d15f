"""Replaying recordings: a dive written by another program equals an independent KF, every
bag format reads the same, bad recordings exit 2 with their line, a run's recording replays
to the run's estimates."""

import json

import numpy as np
import pytest

from drake_uuv.cli import main
from drake_uuv.recordings import read_recording, record_run, replay, write_recording
from drake_uuv.scenario import load_scenario
from drake_uuv.simulation import ClosedLoopSimulation
from tests.recordings.dive import BASELINE, EPOCH_NS, MIDPOINT, Dive, paper_kf, write_dive

# The paper scenario on a dive of 80 steps.
PAPER = ["steps=80", "steady_state_start=0"]


@pytest.fixture(scope="module")
def dive() -> Dive:
    return Dive()


@pytest.fixture(scope="module")
def dive_bag(tmp_path_factory, dive):
    return write_dive(tmp_path_factory.mktemp("dive") / "dive", dive)


def test_a_dive_of_another_program_replays_as_an_independent_kf(dive, dive_bag) -> None:
    scenario = load_scenario("paper", PAPER)
    result = replay(dive_bag, scenario)
    W = np.asarray(scenario.target.acceleration_covariance)
    expected = paper_kf(dive, W, np.asarray(scenario.estimator.initial_covariance))
    assert result.log["x_TU_hat"].shape == (80, 6)
    np.testing.assert_allclose(result.log["x_TU_hat"], expected, rtol=0, atol=1e-7)
    # The gap is a dropout (status DROPPED, only a prediction); the mounting gives b.
    assert result.log["sonar_status"][37].tolist() == [0, 1]
    assert result.log["measurement_status"][37] == 1
    np.testing.assert_array_equal(result.scenario.sonar.baseline, BASELINE)
    assert result.metrics["updates"] == 79 and not result.warnings


def test_a_recording_source_replays_one_run(dive_bag) -> None:
    from drake_uuv.recordings import RecordingSource

    with pytest.raises(ValueError, match="^batch_size: a recording replays as one run, got 3$"):
        RecordingSource(read_recording(dive_bag, time_step=0.5), batch_size=3)


def test_the_clock_starts_at_the_first_stamp_and_u_is_the_sonars_midpoint(dive, dive_bag) -> None:
    recording = read_recording(dive_bag, time_step=0.5)
    assert recording.start_ns == EPOCH_NS and recording.steps == 80
    np.testing.assert_allclose(recording.p_WU_nav, dive.p_WU, atol=1e-12)
    np.testing.assert_allclose(recording.v_WU_nav, dive.v_WU, atol=1e-12)
    np.testing.assert_allclose(recording.R_WB_nav.reshape(-1, 3, 3), dive.R, atol=1e-12)
    assert recording.ping_offsets == (0.0, 0.0) and recording.latency == 0.0
    assert np.all(recording.ping_time[:, 0] == 0.5 * np.arange(80))
    assert np.any(MIDPOINT != 0)  # base_link is not U: the reader moved it


@pytest.mark.parametrize("storage", ["sqlite3", "ros1"])
def test_every_bag_format_reads_the_same(tmp_path, dive, dive_bag, storage) -> None:
    path = tmp_path / ("dive.bag" if storage == "ros1" else "dive")
    write_dive(path, dive, storage=storage)
    scenario = load_scenario("paper", PAPER)
    expected = replay(dive_bag, scenario).log["x_TU_hat"]
    np.testing.assert_array_equal(replay(path, scenario).log["x_TU_hat"], expected)


def test_stamps_out_of_order_are_sorted_with_a_warning(tmp_path, dive, dive_bag, capsys) -> None:
    path = write_dive(tmp_path / "swapped", dive, swap_stamps=(10, 30))
    status = main(["replay", str(path), "--out", str(tmp_path / "out"), *_sets(PAPER)])
    assert status == 0
    err = capsys.readouterr().err
    assert err.startswith("drake-uuv: WARNING: /navigation/odometry: 2 header stamps out of order")
    metrics = json.loads((tmp_path / "out" / "metrics.json").read_text())
    assert metrics["steps"] == 80 and "position_rmse" not in metrics  # no truth recorded
    assert not (tmp_path / "out" / "error_summary.png").exists()
    sorted_log = np.load(tmp_path / "out" / "log.npz")
    expected = replay(dive_bag, load_scenario("paper", PAPER)).log["x_TU_hat"]
    np.testing.assert_array_equal(sorted_log["x_TU_hat"], expected)


def _sets(overrides: list[str]) -> list[str]:
    return [arg for o in overrides for arg in ("--set", o)]


TOPICS = "/control/acceleration, /navigation/odometry, /sonar_1/range, /sonar_2/range, /tf_static"


@pytest.mark.parametrize(
    "writing, message",
    [
        (dict(skip=("/sonar_2/range",)),
         "no topic /sonar_2/range (sonar 2's ranges, sensor_msgs/msg/Range); its topics: "
         "/control/acceleration, /navigation/odometry, /sonar_1/range, /tf_static"),
        (dict(navigation_type="sensor_msgs/msg/Imu"),
         "topic /navigation/odometry is sensor_msgs/msg/Imu, expected nav_msgs/msg/Odometry "
         "(the navigated pose and twist)"),
        (dict(tf_children=("sonar_1",)),
         "no sonar mounting: /tf_static has no transform base_link → sonar_2"),
        (dict(skip=("/tf_static",)),
         "no sonar mounting: no topic /tf_static (tf2_msgs/msg/TFMessage, base_link → "
         "sonar_1, sonar_2); its topics: /control/acceleration, /navigation/odometry, "
         "/sonar_1/range, /sonar_2/range"),
        (dict(steps=1),
         "its stamps span 0 s, shorter than one step (time_step 0.5 s)"),
    ],
)  # fmt: skip
def test_a_bad_recording_exits_2_with_one_line(tmp_path, dive, capsys, writing, message) -> None:
    path = write_dive(tmp_path / "bad", dive, **writing)
    status = main(["replay", str(path), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert status == 2
    assert err == f"drake-uuv: error: recording {str(path)!r}: {message}\n"
    assert not (tmp_path / "out").exists()


def test_a_missing_recording_and_a_bad_topics_file_exit_2(tmp_path, dive_bag, capsys) -> None:
    assert main(["replay", str(tmp_path / "nothing")]) == 2
    assert capsys.readouterr().err == (
        f"drake-uuv: error: recording {str(tmp_path / 'nothing')!r}: no such file or folder\n"
    )
    topics = tmp_path / "topics.yaml"
    topics.write_text("sonar_3: /x\n")
    assert main(["replay", str(dive_bag), "--topics", str(topics)]) == 2
    assert capsys.readouterr().err.startswith(
        "drake-uuv: error: --topics: unknown role 'sonar_3' (known: sonar_1, sonar_2, "
    )


def test_topics_rename_and_an_imu_gives_the_attitude(tmp_path, dive, dive_bag) -> None:
    path = write_dive(tmp_path / "renamed", dive, rename={"/navigation/odometry": "/odom"},
                      imu="/imu/data")  # fmt: skip
    topics = tmp_path / "topics.yaml"
    topics.write_text("navigation: /odom\nattitude: /imu/data\n")
    out = tmp_path / "out"
    assert (
        main(["replay", str(path), "--topics", str(topics), "--out", str(out), *_sets(PAPER)]) == 0
    )
    expected = replay(dive_bag, load_scenario("paper", PAPER)).log["x_TU_hat"]
    np.testing.assert_array_equal(np.load(out / "log.npz")["x_TU_hat"], expected)
    topics.write_text("navigation: /odom\nattitude: /odom\n")
    assert main(["replay", str(path), "--topics", str(topics), "--out", str(out)]) == 2


@pytest.mark.slow
def test_record_then_replay_reproduces_the_paper_run(tmp_path, capsys) -> None:
    run, bag, again = tmp_path / "run", tmp_path / "bag", tmp_path / "replay"
    assert main(["run", "--out", str(run), "--record", str(bag)]) == 0
    assert main(["replay", str(bag), "--out", str(again)]) == 0
    ran, replayed = np.load(run / "log.npz"), np.load(again / "log.npz")
    for name in ("x_TU_hat", "P_TU", "nis"):
        np.testing.assert_allclose(replayed[name], ran[name], rtol=0, atol=1e-9, err_msg=name)
    np.testing.assert_array_equal(replayed["measurement_status"], ran["measurement_status"])
    metrics = json.loads((again / "metrics.json").read_text())
    assert metrics["position_rmse"] == pytest.approx(
        json.loads((run / "metrics.json").read_text())["position_rmse"], abs=1e-9
    )
    assert (again / "error_summary.png").exists()
    assert main(["run", "--out", str(run), "--record", str(bag)]) == 2
    assert capsys.readouterr().err.endswith(
        f"drake-uuv: error: --record: {str(bag)!r} exists (a recording is a new folder)\n"
    )


@pytest.mark.slow
def test_record_then_replay_reproduces_late_ranges(tmp_path) -> None:
    # realistic's ping offsets (0, 0.25 s) and latency (0.2 s) come back from the stamps, and
    # its estimator starts from the navigation at initialization (before the biases latch).
    overrides = ["estimator=Ekf", "steps=200", "steady_state_start=100"]
    scenario = load_scenario("realistic", overrides)
    run = ClosedLoopSimulation(scenario).run()
    bag = record_run(tmp_path / "bag", run.log, scenario)
    replayed = replay(bag, load_scenario("realistic", overrides + ["sonar.latency=0"]))
    assert replayed.scenario.sonar.ping_offsets == [0.0, 0.25]
    assert replayed.scenario.sonar.latency == 0.2
    for name in ("x_TU_hat", "P_TU", "nis"):
        np.testing.assert_allclose(
            replayed.log[name], run.log[name], rtol=0, atol=1e-9, err_msg=name
        )
    # Without the state at initialization the replay starts from step 0's navigation.
    plain = replay(write_recording(tmp_path / "plain", run.log, scenario), scenario)
    assert np.abs(plain.log["x_TU_hat"][0, 3:]).max() == 0.0
    assert np.abs(run.log["x_TU_hat"][0, 3:]).max() > 1e-3


@pytest.mark.slow
def test_record_in_sqlite3_and_replay_with_another_estimator(tmp_path) -> None:
    run, bag = tmp_path / "run", tmp_path / "bag"
    short = _sets(["steps=60", "steady_state_start=0"])
    assert main(["run", "--out", str(run), "--record", str(bag), "--record-storage", "sqlite3",
                 *short]) == 0  # fmt: skip
    assert sorted(p.suffix for p in bag.iterdir()) == [".db3", ".yaml"]
    assert main(["replay", str(bag), "--out", str(tmp_path / "kf"), *short]) == 0
    kf = np.load(tmp_path / "kf" / "log.npz")["x_TU_hat"]
    np.testing.assert_allclose(kf, np.load(run / "log.npz")["x_TU_hat"], rtol=0, atol=1e-9)
    ekf = ["--set", "estimator=Ekf"]
    assert main(["replay", str(bag), "--out", str(tmp_path / "ekf"), *short, *ekf]) == 0
    metrics = json.loads((tmp_path / "ekf" / "metrics.json").read_text())
    assert metrics["steps"] == 60 and metrics["position_rmse"] < 5.0
