"""Every ``drake-uuv`` command in README.md's code blocks can be pasted into an interactive
bash as written: no ``!`` that history expansion would take, and each parses and loads its
scenario (nothing is simulated); every error the README shows is the one the command prints."""

import re
import shlex
import shutil
from pathlib import Path

import pytest

from drake_uuv.cli import main, make_parser
from drake_uuv.cli.options import check_output_folder, scenario_from_args
from drake_uuv.scenario import resolve_scenario_path
from drake_uuv.simulation import ClosedLoopSimulation

README = Path(__file__).resolve().parents[2] / "README.md"
BLOCK = re.compile(r"^```([\w-]*)\n(.*?)^```", re.DOTALL | re.MULTILINE)
PROMPT = "$ "


def unquoted_bangs(line: str) -> list[int]:
    """Positions of the ``!`` an interactive bash would expand from its history: every one
    outside single quotes and not escaped by a backslash (double quotes and comments do not
    protect it: history expansion comes before the shell parses the line)."""
    found, quoted, escaped = [], False, False
    for i, char in enumerate(line):
        if escaped:
            escaped = False
        elif char == "'" and not escaped:
            quoted = not quoted
        elif char == "\\" and not quoted:
            escaped = True
        elif char == "!" and not quoted:
            found.append(i)
    return found


def shell_commands(line: str) -> list[list[str]]:
    """The commands of one shell line (split at ``&&``, ``;``, ``|``), comments dropped."""
    lexer = shlex.shlex(line, posix=True, punctuation_chars=True)
    lexer.whitespace_split = True
    commands: list[list[str]] = [[]]
    for token in lexer:
        if token in ("&&", ";", "|", "||"):
            commands.append([])
        else:
            commands[-1].append(token)
    return [command for command in commands if command]


def _blocks() -> list[tuple[str, str]]:
    return BLOCK.findall(README.read_text())


def readme_lines() -> list[str]:
    """Every shell line of the README that runs ``drake-uuv``: in bash blocks, and after the
    ``$`` prompt in plain blocks (the transcripts)."""
    lines = []
    for language, body in _blocks():
        for line in body.splitlines():
            if language == "" and line.startswith(PROMPT):
                lines.append(line.removeprefix(PROMPT))
            elif language == "bash" and "drake-uuv" in line:
                lines.append(line)
    return lines


def drake_uuv_commands() -> list[list[str]]:
    """The arguments (after the program) of every ``drake-uuv`` command in :func:`readme_lines`."""
    return [
        command[1:]
        for line in readme_lines()
        for command in shell_commands(line)
        if Path(command[0]).name == "drake-uuv"
    ]


def transcripts() -> list[tuple[list[str], str]]:
    """``(arguments, the error line shown after it)`` of each ``$ drake-uuv`` transcript."""
    pairs = []
    for language, body in _blocks():
        lines = body.splitlines()
        for line, shown in zip(lines, lines[1:], strict=False):
            if language == "" and line.startswith(f"{PROMPT}drake-uuv "):
                pairs.append((shlex.split(line.removeprefix(PROMPT))[1:], shown))
    return pairs


def test_the_extraction_finds_the_commands() -> None:
    commands = drake_uuv_commands()
    assert len(commands) >= 20
    assert ["run"] in commands  # the first block's `.venv/bin/drake-uuv run`
    assert ["run", "--set", "tracking=LqrTracking {max_acceleration: 7}"] in commands
    assert len(transcripts()) >= 3


@pytest.mark.parametrize(
    "line, expands",
    [
        ("drake-uuv run --set estimator=!Ekf", True),
        ("drake-uuv run --set 'estimator=!Ekf'", False),
        ('drake-uuv run --set "estimator=!Ekf"', True),
        ("drake-uuv run --set estimator=\\!Ekf", False),
        ("drake-uuv run  # no !excitation", True),
        ("drake-uuv run --set 'a=b' --set c=!D", True),
    ],
)
def test_the_history_expansion_check(line: str, expands: bool) -> None:
    assert unquoted_bangs(line) == ([line.index("!")] if expands else [])


@pytest.mark.parametrize("line", readme_lines())
def test_no_line_has_a_bang_bash_would_expand(line: str) -> None:
    assert unquoted_bangs(line) == [], f"quote the ! of: {line}"


@pytest.fixture
def users_file(tmp_path, monkeypatch) -> None:
    """A folder with the README's example file of one's own, ``my.yaml`` (the paper's)."""
    shutil.copy(resolve_scenario_path("paper"), tmp_path / "my.yaml")
    monkeypatch.chdir(tmp_path)


@pytest.fixture
def no_simulation(monkeypatch) -> None:
    def refuse(*args, **kwargs):
        raise AssertionError("simulated")

    monkeypatch.setattr(ClosedLoopSimulation, "run", refuse)


# The transcripts' commands fail on purpose: the next test checks them.
TO_RUN = [argv for argv in drake_uuv_commands() if argv not in [a for a, _ in transcripts()]]


@pytest.mark.parametrize("argv", TO_RUN, ids=" ".join)
def test_each_command_parses_and_loads_its_scenario(argv: list[str], users_file) -> None:
    args = make_parser().parse_args(argv)
    if hasattr(args, "overrides"):
        scenario_from_args(args)
    if getattr(args, "output_folder", False):
        check_output_folder(args.out)


@pytest.mark.parametrize("argv, shown", transcripts(), ids=[" ".join(a) for a, _ in transcripts()])
def test_each_error_shown_is_the_one_printed(argv, shown, capsys, users_file, no_simulation):
    assert main(argv) == 2
    assert capsys.readouterr().err == shown + "\n"
