"""The recording notebook runs from top to bottom in a fresh kernel of this environment's
Python (as the main tutorial's test runs that one), and is stored without outputs."""

import json
import sys
from pathlib import Path

import pytest

nbformat = pytest.importorskip("nbformat", reason="the test extra: pip install -e '.[test]'")

REPO = Path(__file__).resolve().parents[2]
NOTEBOOK = REPO / "tutorials" / "your_own_recording.ipynb"
KERNEL = "drake-uuv-recording-tests"


def test_the_notebook_is_stored_without_outputs() -> None:
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    nbformat.validate(notebook)
    code = [cell for cell in notebook.cells if cell.cell_type == "code"]
    assert code and all(not cell.outputs and cell.execution_count is None for cell in code)


@pytest.mark.slow
def test_the_recording_notebook_runs_in_a_fresh_kernel(tmp_path, monkeypatch) -> None:
    nbclient = pytest.importorskip("nbclient", reason="the test extra: pip install -e '.[test]'")
    pytest.importorskip("ipykernel", reason="the test extra: pip install -e '.[test]'")
    spec = tmp_path / "jupyter" / "kernels" / KERNEL
    spec.mkdir(parents=True)
    argv = [sys.executable, "-m", "ipykernel_launcher", "-f", "{connection_file}"]
    (spec / "kernel.json").write_text(json.dumps({"argv": argv, "language": "python",
                                                  "display_name": KERNEL}))  # fmt: skip
    monkeypatch.setenv("JUPYTER_PATH", str(tmp_path / "jupyter"))
    monkeypatch.setenv("PYTHONPATH", str(REPO))  # this checkout's drake_uuv
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    client = nbclient.NotebookClient(
        notebook, kernel_name=KERNEL, timeout=600,
        resources={"metadata": {"path": str(NOTEBOOK.parent)}},
    )  # fmt: skip
    client.execute()
    outputs = [o for c in notebook.cells if c.cell_type == "code" for o in c.outputs]
    text = "".join(o.get("text", "") for o in outputs)
    # The bag's topics as rosbags lists them; the replayed KF is the run's.
    assert "/sonar_1/range                   sensor_msgs/msg/Range" in text
    reproduced = next(line for line in text.splitlines() if line.startswith("paper's KF repro"))
    assert float(reproduced.split(":")[1]) < 1e-9
    assert "EKF        position RMSE" in text
    assert len([o for o in outputs if "image/png" in o.get("data", {})]) == 2
