"""The loop's halves over LCM: in one process the run's log and metrics bit for bit; across
two processes in a network namespace of the test's own (multicast on its loopback only)."""

import json
import os
import shutil
import subprocess
import sys
import uuid
from pathlib import Path

import numpy as np
import pytest

from drake_uuv.cli import main
from drake_uuv.diagram import make_systems
from drake_uuv.hardware import SplitError, channels, run_lcm
from drake_uuv.hardware.channels import ONBOARD, VEHICLE
from drake_uuv.scenario import load_scenario
from drake_uuv.simulation import ClosedLoopSimulation

ROOT = Path(__file__).resolve().parents[2]
SHORT = ["steps=60", "steady_state_start=0"]


def _same(ran: dict, over_lcm: dict) -> None:
    assert set(over_lcm) == set(ran)
    for name, value in ran.items():
        np.testing.assert_array_equal(over_lcm[name], value, err_msg=name)


def test_the_paper_channels_are_documented() -> None:
    systems = make_systems(load_scenario("paper"))
    onboard = {c.name: c.signals for c in channels(systems, ONBOARD)}
    vehicle = {c.name: c.signals for c in channels(systems, VEHICLE)}
    assert onboard == {
        "DRAKE_UUV_NAVIGATION": (("R_WB_nav", 9),),
        "DRAKE_UUV_SONAR": (("range_samples", 2), ("sonar_status", 2)),
    }
    late = make_systems(load_scenario("realistic", ["estimator=Ekf"]))
    assert {c.name: c.signals for c in channels(late, ONBOARD)} == {
        "DRAKE_UUV_NAVIGATION": (("p_WU_nav", 3), ("v_WU_nav", 3), ("R_WB_nav", 9)),
        "DRAKE_UUV_SONAR": (("range_samples", 2), ("sonar_status", 2), ("ping_time", 2)),
    }
    assert vehicle == {
        "DRAKE_UUV_ATTITUDE_GENERATOR": (("u2_W", 3),),
        "DRAKE_UUV_TRACKING_CONTROLLER": (("u1_B", 3),),
    }


def test_one_process_gives_the_run_bit_for_bit() -> None:
    scenario = load_scenario("paper", ["steps=200", "steady_state_start=100"])
    run = ClosedLoopSimulation(scenario).run()
    over_lcm = run_lcm(scenario, "memq://")
    _same(run.log, over_lcm.log)
    ran = {k: v for k, v in run.metrics.items() if k != "wall_time_s"}
    assert {k: v for k, v in over_lcm.metrics.items() if k != "wall_time_s"} == ran


@pytest.mark.slow
def test_late_ranges_and_navigation_errors_over_lcm_bit_for_bit() -> None:
    # realistic: a continuous plant, late ranges, navigation biases latched at initialization.
    scenario = load_scenario("realistic", ["estimator=Ekf", "steps=80", "steady_state_start=0"])
    run = ClosedLoopSimulation(scenario).run()
    _same(run.log, run_lcm(scenario, "memq://").log)


@pytest.mark.slow
def test_run_over_lcm_writes_the_same_metrics(tmp_path) -> None:
    assert main(["run", "--out", str(tmp_path / "a"), *_sets(SHORT)]) == 0
    assert main(["run", "--lcm", "memq://", "--out", str(tmp_path / "b"), *_sets(SHORT)]) == 0
    a, b = (json.loads((tmp_path / x / "metrics.json").read_text()) for x in "ab")
    a.pop("wall_time_s"), b.pop("wall_time_s")
    assert a == b


def _sets(overrides: list[str]) -> list[str]:
    return [arg for o in overrides for arg in ("--set", o)]


@pytest.mark.parametrize(
    "args, message",
    [
        (["run", "--lcm", "udp://x"], "--lcm: must be memq:// (one process) or "
         "udpm://ADDRESS:PORT?ttl=0 (this host), got 'udp://x'"),
        (["run", "--lcm", "memq://", "--set", "sonar.beam_half_angle_deg=30"],
         "--lcm: sonar: reads 'x_TU_prior' from the onboard half (estimator); over LCM the "
         "vehicle half reads only its commands, in its plant"),
        (["onboard"], "--lcm: the onboard half needs an LCM URL, e.g. "
         "udpm://239.255.76.67:7667?ttl=0"),
        (["vehicle", "--lcm", "memq://", "--timeout", "0"], "--timeout: must be > 0, got 0.0"),
    ],
)  # fmt: skip
def test_bad_lcm_options_exit_2_with_one_line(tmp_path, capsys, args, message) -> None:
    assert main([*args, "--out", str(tmp_path / "out")]) == 2
    assert capsys.readouterr().err == f"drake-uuv: error: {message}\n"


def test_a_split_the_lockstep_cannot_answer_is_refused() -> None:
    systems = make_systems(load_scenario("paper", ["sonar.beam_half_angle_deg=30"]))
    with pytest.raises(SplitError, match="^sonar: reads 'x_TU_prior' from the onboard half"):
        channels(systems, VEHICLE)


@pytest.fixture
def namespace():
    """A network namespace of the test's own: only its loopback, up, multicast routed to it.
    Skipped where namespaces cannot be made (no privileges); deleted after."""
    if shutil.which("ip") is None:
        pytest.skip("no ip command (iproute2)")
    name = f"drake-uuv-{uuid.uuid4().hex[:8]}"
    made = subprocess.run(["ip", "netns", "add", name], capture_output=True, text=True)
    if made.returncode != 0:
        pytest.skip(f"ip netns add refused: {made.stderr.strip()}")
    try:
        for command in (
            ["ip", "link", "set", "lo", "up"],
            ["ip", "link", "set", "lo", "multicast", "on"],
            ["ip", "route", "add", "224.0.0.0/4", "dev", "lo"],
        ):
            subprocess.run(["ip", "netns", "exec", name, *command], check=True)
        links = subprocess.run(["ip", "netns", "exec", name, "ip", "-o", "link", "show"],
                               capture_output=True, text=True, check=True).stdout  # fmt: skip
        # Multicast cannot leave: the namespace has no interface but its loopback.
        assert [line.split(":")[1].strip() for line in links.splitlines()] == ["lo"]
        yield name
    finally:
        subprocess.run(["ip", "netns", "del", name], check=False)


@pytest.mark.slow
def test_two_processes_give_the_run_bit_for_bit(tmp_path, namespace) -> None:
    url = "udpm://239.255.76.67:7667?ttl=0"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}

    def half(side: str) -> subprocess.Popen:
        # Each half waits this long for the other's messages: enough to compile the kernels
        # in a cold cache on a loaded machine.
        command = [sys.executable, "-m", "drake_uuv.cli", side, "--lcm", url, "--timeout",
                   "240", "--out", str(tmp_path / side), *_sets(SHORT)]  # fmt: skip
        return subprocess.Popen(["ip", "netns", "exec", namespace, *command], env=env,
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)  # fmt: skip

    vehicle, onboard = half("vehicle"), half("onboard")
    outputs = [p.communicate(timeout=600)[0] for p in (vehicle, onboard)]
    assert [vehicle.returncode, onboard.returncode] == [0, 0], outputs
    run = ClosedLoopSimulation(load_scenario("paper", SHORT)).run()
    vehicle_log = np.load(tmp_path / "vehicle" / "log.npz")
    onboard_log = np.load(tmp_path / "onboard" / "log.npz")
    for name in ("x_TU_hat", "P_TU", "u1_B", "u2_W", "nis"):
        np.testing.assert_array_equal(onboard_log[name], run.log[name], err_msg=name)
    for name in ("p_WU", "v_WU", "R_WB", "p_WT", "ranges", "sonar_status"):
        np.testing.assert_array_equal(vehicle_log[name], run.log[name], err_msg=name)


def test_a_message_of_another_size_is_refused_naming_the_channel() -> None:
    from drake import lcmt_scope

    from drake_uuv.hardware import Channel
    from drake_uuv.hardware.channels import ScopeToVector, VectorToScope

    channel = Channel("DRAKE_UUV_SONAR", "sonar", (("range_samples", 2), ("sonar_status", 2)))
    unpack = ScopeToVector(channel)
    context = unpack.CreateDefaultContext()
    message = lcmt_scope()
    message.size, message.value = 3, [1.0, 2.0, 0.0]
    unpack.get_input_port().FixValue(context, message)
    with pytest.raises(ValueError, match=r"^DRAKE_UUV_SONAR: a message of 3 values, expected 4: "
                       r"DRAKE_UUV_SONAR \(range_samples 2, sonar_status 2\)$"):  # fmt: skip
        unpack.GetOutputPort("range_samples").Eval(context)
    message.size, message.value = 4, [1.0, 2.0, 0.0, 1.0]
    unpack.get_input_port().FixValue(context, message)
    assert unpack.GetOutputPort("sonar_status").Eval(context).tolist() == [0.0, 1.0]
    for system in (ScopeToVector, VectorToScope):
        with pytest.raises(ValueError, match="^batch_size: the loop over LCM runs one run, got 2$"):
            system(channel, batch_size=2)
