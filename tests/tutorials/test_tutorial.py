"""The tutorial notebook runs from top to bottom in a fresh kernel of this environment's
Python, and is stored without outputs."""

import json
import shutil
import sys
from pathlib import Path

import pytest

nbformat = pytest.importorskip("nbformat", reason="the test extra: pip install -e '.[test]'")

REPO = Path(__file__).resolve().parents[2]
NOTEBOOK = REPO / "tutorials" / "drake_uuv_tutorial.ipynb"
KERNEL = "drake-uuv-tests"


def test_the_notebook_is_stored_without_outputs() -> None:
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    nbformat.validate(notebook)
    code = [cell for cell in notebook.cells if cell.cell_type == "code"]
    assert code and all(not cell.outputs and cell.execution_count is None for cell in code)


@pytest.mark.slow
def test_the_tutorial_runs_in_a_fresh_kernel_of_this_python(tmp_path, monkeypatch) -> None:
    """Every cell runs without error (nbclient raises on the first that fails) in a new
    kernel started from ``sys.executable`` through a kernel spec of its own, so that neither
    a kernel installed elsewhere nor another checkout of the package is picked up."""
    # Imported here: the kernel client costs every quick run a sixth of a second to import.
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
    probe = "import sys, drake_uuv; print(sys.executable); print(drake_uuv.__file__)"
    notebook.cells.append(nbformat.v4.new_code_cell(probe))
    client = nbclient.NotebookClient(
        notebook,
        kernel_name=KERNEL,
        timeout=600,
        resources={"metadata": {"path": str(NOTEBOOK.parent)}},
    )
    client.execute()
    executable, package = notebook.cells[-1].outputs[0]["text"].split()
    assert Path(executable) == Path(sys.executable)
    assert Path(package) == REPO / "drake_uuv" / "__init__.py"
    # The figures came out as pictures (a figure's output has its text and its picture).
    outputs = [o for c in notebook.cells if c.cell_type == "code" for o in c.outputs]
    figures = [o["data"] for o in outputs if "image/png" in o.get("data", {})]
    assert len(figures) >= 3
    diagrams = [o["data"] for o in outputs if "image/svg+xml" in o.get("data", {})]
    assert len(diagrams) == (1 if shutil.which("dot") else 0)
    as_text = [o for o in outputs if o.get("data", {}).get("text/plain", "").startswith("<Figure")]
    assert all("image/png" in o["data"] for o in as_text)
