"""Every command that writes checks its ``--out`` folder before any work: one line naming the
path and the reason, status 2, before Drake is imported (so at once); an OS error
during the work is one line naming the path, status 1, never a traceback."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from drake_uuv.cli import main
from drake_uuv.cli import options as options_module

# Each command that writes into --out, with options that would make it do real work.
COMMANDS = {
    "run": ["run", "--set", "steps=5", "--set", "steady_state_start=0"],
    "montecarlo": ["montecarlo", "--runs", "2", "--no-progress"],
    "compare": ["compare", "--group", "alpha", "--runs", "1", "--no-progress"],
    "animate": ["animate", "--set", "steps=5", "--set", "steady_state_start=0"],
    "diagram": ["diagram"],
}
AS_ROOT = hasattr(os, "geteuid") and os.geteuid() == 0
# This checkout's package, whatever is installed (the subprocess runs in a temporary folder).
CHECKOUT = str(Path(__file__).resolve().parents[2])


def _one_error_line(capsys) -> str:
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    return err.rstrip("\n")


@pytest.mark.parametrize("command", COMMANDS)
def test_under_a_file_exits_2_naming_the_path(tmp_path, capsys, command: str) -> None:
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    out = blocker / "x" / "y"
    assert main([*COMMANDS[command], "--out", str(out)]) == 2
    assert _one_error_line(capsys) == (
        f"drake-uuv: error: --out: cannot write to {str(out)!r}: {str(blocker)!r} is not a folder"
    )


@pytest.mark.parametrize("command", COMMANDS)
def test_a_file_in_its_place_exits_2(tmp_path, capsys, command: str) -> None:
    out = tmp_path / "a_file"
    out.write_text("keep me")
    assert main([*COMMANDS[command], "--out", str(out)]) == 2
    assert _one_error_line(capsys) == (
        f"drake-uuv: error: --out: cannot write to {str(out)!r}: it is not a folder"
    )
    assert out.read_text() == "keep me"


@pytest.mark.skipif(
    AS_ROOT, reason="root writes into a folder whatever its mode: chmod denies nothing"
)
@pytest.mark.parametrize("command", COMMANDS)
def test_a_read_only_folder_exits_2(tmp_path, capsys, command: str) -> None:
    folder = tmp_path / "read_only"
    folder.mkdir()
    folder.chmod(0o555)
    try:
        assert main([*COMMANDS[command], "--out", str(folder / "x")]) == 2
        assert _one_error_line(capsys).endswith(f"{str(folder)!r} is not writable")
        assert main([*COMMANDS[command], "--out", str(folder)]) == 2
        assert _one_error_line(capsys).endswith(": it is not writable")
    finally:
        folder.chmod(0o755)


def test_a_folder_the_process_may_not_write_exits_2(tmp_path, capsys, monkeypatch) -> None:
    # What a read-only folder or file system looks like to the check, also as root.
    denied = tmp_path / "denied"
    denied.mkdir()
    allowed = os.access
    monkeypatch.setattr(
        options_module.os, "access", lambda p, mode: Path(p) != denied and allowed(p, mode)
    )
    assert main(["run", "--out", str(denied / "x")]) == 2
    assert _one_error_line(capsys) == (
        f"drake-uuv: error: --out: cannot write to {str(denied / 'x')!r}: "
        f"{str(denied)!r} is not writable"
    )
    options_module.check_output_folder(str(tmp_path / "fine" / "new"))  # creatable: no error


# As ``python -m drake_uuv.cli`` runs, then whether Drake was imported before the refusal.
PROBE = """
import runpy, sys
try:
    runpy.run_module("drake_uuv.cli", run_name="__main__", alter_sys=True)
except SystemExit as exit:
    print(exit.code, "pydrake" in sys.modules)
"""


@pytest.mark.parametrize("command", COMMANDS)
def test_an_impossible_folder_is_refused_before_drake_is_imported(tmp_path, command: str) -> None:
    # A fresh process, as from the shell (this one has imported Drake already).
    result = subprocess.run(
        [sys.executable, "-c", PROBE, *COMMANDS[command], "--out", "/dev/null/x"],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        env={**os.environ, "PYTHONPATH": CHECKOUT},
    )
    assert result.stdout == "2 False\n", result.stdout
    assert result.stderr == (
        "drake-uuv: error: --out: cannot write to '/dev/null/x': '/dev/null' is not a folder\n"
    )
    assert list(tmp_path.iterdir()) == []


def test_an_os_error_during_a_run_is_one_line_with_status_1(tmp_path, capsys) -> None:
    out = tmp_path / "out"
    (out / "log.npz").mkdir(parents=True)  # the log's place is taken by a folder
    assert main([*COMMANDS["run"], "--out", str(out)]) == 1
    line = _one_error_line(capsys)
    assert line.startswith("drake-uuv: error: ")
    assert line.endswith(f" -> {str(out / 'log.npz')!r}: Is a directory")
