"""`drake-uuv animate` and `run --meshcat` use the diagram that runs the simulation."""

import numpy as np
from pydrake.geometry import StartMeshcat

from drake_uuv import ClosedLoopSimulation, load_scenario
from drake_uuv.cli import main

SHORT = ["--set", "steps=60", "--set", "steady_state_start=0"]


def test_animate_writes_a_self_contained_page(tmp_path, capfd) -> None:
    status = main(["animate", "--out", str(tmp_path), "--playback-speed", "8",
                   "--trail-length", "10", *SHORT])  # fmt: skip
    assert status == 0
    page = (tmp_path / "animation.html").read_text()
    assert "<script" in page and 'src="http' not in page
    assert (tmp_path / "animation.html").stat().st_size < 20e6
    assert 'id="drake-uuv-legend"' in page and "UUV trail, last 10 steps" in page
    # It says where the page is, and nothing of the Meshcat server that recorded it (its
    # "listening at localhost" line, logged by Drake to the terminal, read as the place).
    out, err = capfd.readouterr()
    assert out.startswith(f"wrote {tmp_path / 'animation.html'} (") and "self-contained" in out
    assert "localhost" not in out + err and "Meshcat" not in out + err


def test_animate_rejects_bad_options(capsys) -> None:
    assert main(["animate", "--playback-speed", "0"]) == 2
    assert "--playback-speed: must be > 0, got 0.0" in capsys.readouterr().err
    assert main(["animate", "--trail-length", "-1"]) == 2
    assert "--trail-length: must be ≥ 0, got -1" in capsys.readouterr().err


def test_live_meshcat_leaves_the_log_unchanged() -> None:
    scenario = load_scenario("paper", ["steps=60", "steady_state_start=0"])
    plain = ClosedLoopSimulation(scenario).run()
    live = ClosedLoopSimulation(scenario, meshcat=StartMeshcat()).run()
    for key in plain.log:
        np.testing.assert_array_equal(plain.log[key], live.log[key])
