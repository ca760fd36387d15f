"""The Meshcat scene, its recording and the live visualizer, without a browser."""

from __future__ import annotations

import base64
import re
from pathlib import Path

import numpy as np
import pytest
from pydrake.geometry import Meshcat
from pydrake.systems.analysis import Simulator

from drake_uuv.diagram import make_uuv_diagram
from drake_uuv.scenario import load_scenario
from drake_uuv.visualization import LiveMeshcatVisualizer, MeshcatScene, record_animation
from drake_uuv.visualization.scene import (
    SCENE_ROOT,
    SceneFrame,
    SceneStyle,
    ThrusterLayout,
    _covariance_axes,
    world_particles,
)
from tests.visualization.synthetic_log import BASELINE_B, TIME_STEP, synthetic_log


@pytest.fixture(scope="module")
def meshcat() -> Meshcat:
    return Meshcat()


def _commands(html: str) -> list[bytes]:
    """The msgpack commands StaticHtml embeds as base64 data URLs."""
    return [
        base64.b64decode(b64)
        for b64 in re.findall(r'fetch\("data:application/octet-binary;base64,([^"]*)"\)', html)
    ]


def test_record_writes_self_contained_page(tmp_path: Path, short_log, meshcat) -> None:
    out = tmp_path / "sub" / "animation.html"
    assert record_animation(short_log, BASELINE_B, TIME_STEP, out, meshcat=meshcat) == out
    html = out.read_text(encoding="utf-8")
    assert html.startswith("<!DOCTYPE html>")
    # Nothing is fetched from a server: every script is inline, every command a data URL.
    assert not re.search(r"<script[^>]*\bsrc\s*=", html, re.IGNORECASE)
    assert not re.search(r"<link[^>]*\bhref\s*=\s*[\"']?https?:", html, re.IGNORECASE)
    assert not re.search(r"fetch\(\s*[\"']https?:", html)
    assert "CONNECTION BLOCK" not in html  # the websocket connection code was replaced
    assert [p.name for p in out.parent.iterdir()] == ["animation.html"]  # no temp file left

    commands = _commands(html)
    animations = [c for c in commands if b"set_animation" in c]
    assert len(animations) == 1
    animation = animations[0]
    for path in MeshcatScene.animated_paths():
        assert path.encode() in animation, path
    for prop in (b".position", b".quaternion", b".scale", b".visible"):
        assert prop in animation
    # One segment per step after the first, for each trajectory; each is animated.
    steps = len(short_log["p_WU"])
    for trail in ("uuv", "target"):
        for k in (0, steps - 2):
            segment = f"{SCENE_ROOT}/trails/{trail}/{k:06d}"
            assert meshcat.HasPath(segment)
            assert segment.encode() in animation
        assert not meshcat.HasPath(f"{SCENE_ROOT}/trails/{trail}/{steps - 1:06d}")
    for path in ("uuv/body", "uuv/s1", "uuv/s2", "uuv/baseline", "target", "estimate/point"):
        assert meshcat.HasPath(f"{SCENE_ROOT}/{path}")


def test_trail_length_controls_visible_segments(tmp_path: Path, short_log, meshcat) -> None:
    record_animation(
        short_log, BASELINE_B, TIME_STEP, tmp_path / "a.html", trail_length=10, meshcat=meshcat
    )
    steps = len(short_log["p_WU"])

    def visible(k: int) -> bool:
        packed = meshcat._GetPackedProperty(f"{SCENE_ROOT}/trails/uuv/{k:06d}", "visible")
        assert packed, k
        return b"\xc3" in packed  # msgpack true (false is \xc2)

    # After the last frame, exactly the newest 10 segments remain visible.
    assert [visible(k) for k in range(steps - 12, steps - 1)] == [False] + [True] * 10

    record_animation(
        short_log, BASELINE_B, TIME_STEP, tmp_path / "b.html", trail_length=0, meshcat=meshcat
    )
    assert not meshcat.HasPath(f"{SCENE_ROOT}/trails/uuv/000000")


@pytest.mark.slow
def test_paper_length_run_is_under_20_MB(tmp_path: Path, meshcat) -> None:
    out = record_animation(
        synthetic_log(500, seed=1), BASELINE_B, TIME_STEP, tmp_path / "a.html", meshcat=meshcat
    )
    assert out.stat().st_size < 20e6


def test_playback_speed_sets_frame_rate(tmp_path: Path, short_log, meshcat) -> None:
    record_animation(
        short_log, BASELINE_B, TIME_STEP, tmp_path / "a.html", playback_speed=4.0, meshcat=meshcat
    )
    # One frame per step, played at speed / time_step frames per second.
    assert meshcat.get_mutable_recording().frames_per_second() == pytest.approx(8.0)


def test_rejects_bad_input(tmp_path: Path, short_log) -> None:
    log = dict(short_log)
    del log["x_TU_hat"]
    with pytest.raises(ValueError, match=r"missing \['x_TU_hat'\]"):
        record_animation(log, BASELINE_B, TIME_STEP, tmp_path / "a.html")
    log = dict(short_log, p_WT=short_log["p_WT"][:-1])
    with pytest.raises(ValueError, match=r"log\['p_WT'\] has shape"):
        record_animation(log, BASELINE_B, TIME_STEP, tmp_path / "a.html")
    with pytest.raises(ValueError, match="time_step must be > 0"):
        record_animation(short_log, BASELINE_B, 0.0, tmp_path / "a.html")
    with pytest.raises(ValueError, match="baseline_B must have 3 entries"):
        record_animation(short_log, np.ones(2), TIME_STEP, tmp_path / "a.html")
    assert not (tmp_path / "a.html").exists()


def test_covariance_ellipsoid_matches_P() -> None:
    rng = np.random.default_rng(3)
    A = rng.standard_normal((3, 3))
    P = A @ A.T + 0.1 * np.eye(3)
    R, radii = _covariance_axes(P, sigma=3.0)
    M = R.matrix() @ np.diag(radii)  # maps the unit sphere onto the ellipsoid
    np.testing.assert_allclose(M @ M.T, 9.0 * P, rtol=1e-10, atol=1e-12)
    assert np.linalg.det(R.matrix()) == pytest.approx(1.0)
    # A singular P still gives an invertible transform.
    _, radii = _covariance_axes(np.zeros((3, 3)), sigma=3.0)
    assert min(radii) > 0


def test_particles_are_fixed_in_the_world() -> None:
    style = SceneStyle(particle_tile=10.0, particle_spacing=2.5)
    a = world_particles(np.array([-5.0, -5.0, -5.0]), np.array([15.0, 5.0, 5.0]), style)
    b = world_particles(np.array([12.0, 1.0, 1.0]), np.array([25.0, 2.0, 2.0]), style)
    assert len(a) == 3 * 2 * 2 * 64 and len(b) == 2 * 64
    # Boxes that meet the same cube show the same particles there.
    in_shared = (a[:, 0] >= 10.0) & (a[:, 1] >= 0.0) & (a[:, 2] >= 0.0)
    assert in_shared.sum() == 64
    shared_b = b[b[:, 0] < 20.0]
    np.testing.assert_array_equal(np.sort(a[in_shared], axis=0), np.sort(shared_b, axis=0))
    capped = world_particles(np.zeros(3), np.full(3, 100.0), SceneStyle(max_particles=1000))
    assert 500 <= len(capped) <= 1000


def test_camera_frames_target_and_vehicle(short_log, meshcat) -> None:
    scene = MeshcatScene(meshcat, BASELINE_B)
    scene.frame_log(short_log)
    # The view follows the target: it looks at the origin, far enough to see the
    # vehicle at load and for 90 % of the run inside Meshcat's 75° vertical field
    # of view, and no farther than needed.
    np.testing.assert_allclose(scene.camera_target, 0.0)
    distances = np.linalg.norm(short_log["p_WU"] - short_log["p_WT"], axis=1)
    half_fov = np.sin(np.deg2rad(37.5))
    assert distances[0] / scene.camera_distance() < half_fov
    assert np.mean(distances / scene.camera_distance() < half_fov) >= 0.9
    assert scene.camera_distance() < 3.0 * distances.max()


def _fix_inputs(system: LiveMeshcatVisualizer, context, frame: SceneFrame) -> None:
    P = np.eye(6)
    P[:3, :3] = frame.P_qq
    system.GetInputPort("p_WU").FixValue(context, frame.p_WU)
    system.GetInputPort("R_WB").FixValue(context, frame.R_WB.reshape(-1))
    system.GetInputPort("p_WT").FixValue(context, frame.p_WT)
    system.GetInputPort("x_TU_hat").FixValue(context, np.r_[frame.q_hat, np.zeros(3)])
    system.GetInputPort("P_TU").FixValue(context, P.reshape(-1))


def test_live_visualizer_ports_and_drawing(short_log, meshcat) -> None:
    system = LiveMeshcatVisualizer(
        meshcat, baseline_B=BASELINE_B, publish_period=0.5, trail_length=3
    )
    sizes = {
        system.get_input_port(i).get_name(): system.get_input_port(i).size()
        for i in range(system.num_input_ports())
    }
    assert sizes == {"p_WU": 3, "R_WB": 9, "p_WT": 3, "x_TU_hat": 6, "P_TU": 36}
    assert system.num_output_ports() == 0

    context = system.CreateDefaultContext()
    _fix_inputs(system, context, SceneFrame.from_log(short_log, 0))
    simulator = Simulator(system, context)
    simulator.AdvanceTo(3.0)  # publishes at t = 0, 0.5, ..., 3.0: 7 points, 6 segments
    for path in MeshcatScene.animated_paths():
        assert meshcat.HasPath(path), path
    assert meshcat.HasPath(f"{SCENE_ROOT}/particles")
    # Segments older than trail_length are deleted in live mode.
    assert not meshcat.HasPath(f"{SCENE_ROOT}/trails/uuv/000002")
    assert meshcat.HasPath(f"{SCENE_ROOT}/trails/uuv/000003")
    assert meshcat.HasPath(f"{SCENE_ROOT}/trails/uuv/000005")
    assert not meshcat.HasPath(f"{SCENE_ROOT}/trails/uuv/000006")
    # The scene is drawn where the inputs say: the follow transform is −p_target.
    packed = meshcat._GetPackedTransform(SCENE_ROOT)
    p_target = short_log["p_WT"][0]
    # The message ends with the column-major 4×4 matrix as 16 msgpack float64s
    # (marker 0xcb, then 8 big-endian bytes each).
    tail = np.frombuffer(packed[-16 * 9 :], dtype=np.uint8).reshape(16, 9)
    assert np.all(tail[:, 0] == 0xCB)
    matrix = np.frombuffer(tail[:, 1:].tobytes(), dtype=">f8").reshape(4, 4).T
    np.testing.assert_allclose(matrix[:3, 3], -p_target)

    # A new simulation starts new trails.
    simulator.get_mutable_context().SetTime(0.0)
    simulator.Initialize()
    assert not meshcat.HasPath(f"{SCENE_ROOT}/trails/uuv/000005")


def test_the_builder_wires_the_live_visualizer_by_name(meshcat) -> None:
    scenario = load_scenario("paper", ["steps=6", "steady_state_start=0"])
    built = make_uuv_diagram(scenario, meshcat=meshcat)
    visualizer = built.diagram.GetSubsystemByName("meshcat_visualizer")
    assert isinstance(visualizer, LiveMeshcatVisualizer)
    simulator = Simulator(built.diagram)
    simulator.AdvanceTo(2.0)
    # The last publish drew the scene around the target where the target system says it is.
    target = built.systems["target"]
    p_WT = target.GetOutputPort("p_WT").Eval(target.GetMyContextFromRoot(simulator.get_context()))
    tail = np.frombuffer(meshcat._GetPackedTransform(SCENE_ROOT)[-16 * 9 :], dtype=np.uint8)
    matrix = np.frombuffer(tail.reshape(16, 9)[:, 1:].tobytes(), dtype=">f8").reshape(4, 4).T
    np.testing.assert_allclose(matrix[:3, 3], -p_WT)


def _legend(html: str) -> str:
    match = re.search(r'<div id="drake-uuv-legend".*?</div></div>', html, re.DOTALL)
    assert match, "no legend in the page"
    return match.group(0)


def test_the_page_has_a_key_to_every_colour_of_the_scene(tmp_path: Path, short_log) -> None:
    """The key lists the vehicle, the sonars, the target, the estimate and its ellipsoid, the
    trails and the particles, each with its colour in the scene's style."""
    style = SceneStyle()
    out = record_animation(short_log, BASELINE_B, TIME_STEP, tmp_path / "a.html", trail_length=7)
    legend = _legend(out.read_text(encoding="utf-8"))
    expected = {
        "UUV body": style.body_rgb,
        "sonar s1": style.s1_rgb,
        "sonar s2": style.s2_rgb,
        "sonar baseline": style.baseline_rgb,
        "target (true position)": style.target_rgb,
        "estimated target position": style.estimate_rgb,
        "3σ ellipsoid of the estimate": style.estimate_rgb,
        "UUV trail, last 7 steps": style.uuv_trail_rgb,
        "target trail, last 7 steps": style.target_trail_rgb,
        "world-fixed particles": style.particle_rgb,
    }
    swatches = re.findall(
        r"background:rgba\((\d+), (\d+), (\d+),([\d.]+)\)\"></span>([^<]*)<", legend
    )
    by_label = {label: tuple(int(c) for c in rgb) for *rgb, _, label in swatches}
    assert len(swatches) == len(expected)
    for start, rgb in expected.items():
        (label,) = [label for label in by_label if label.startswith(start)]
        assert by_label[label] == tuple(round(255 * c) for c in rgb), label
    assert "thruster" not in legend


def test_the_key_follows_the_options(tmp_path: Path, short_log) -> None:
    """No trails, a fixed camera: neither trails nor particles in the key; thrusters: theirs."""
    log = dict(short_log, thrust=np.zeros((len(short_log["p_WU"]), 2)))
    thrusters = ThrusterLayout(np.eye(3)[:2], np.eye(3)[:2], 10.0)
    out = record_animation(log, BASELINE_B, TIME_STEP, tmp_path / "a.html", trail_length=0,
                           follow_target=False, thrusters=thrusters)  # fmt: skip
    legend = _legend(out.read_text(encoding="utf-8"))
    assert "trail" not in legend and "particles" not in legend
    assert "thruster effort" in legend and "UUV body" in legend
