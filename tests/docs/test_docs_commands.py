"""The site's pages keep the README's promise: every ``drake-uuv`` command in a bash block of
``docs/**/*.md`` can be pasted into an interactive bash, parses and loads its scenario, and
every error a page shows is the one the command prints (the checks of
``tests/cli/test_readme_commands.py``, on the pages the README's sections moved to)."""

import shlex
from pathlib import Path

import pytest

from drake_uuv.cli import main, make_parser
from drake_uuv.cli.options import check_output_folder, scenario_from_args
from tests.cli.test_readme_commands import (  # noqa: F401 (fixtures)
    BLOCK,
    PROMPT,
    no_simulation,
    shell_commands,
    unquoted_bangs,
    users_file,
)

DOCS = Path(__file__).resolve().parents[2] / "docs"
PAGES = sorted(p for p in DOCS.rglob("*.md") if "_build" not in p.parts)


def _blocks() -> list[tuple[str, str]]:
    return [block for page in PAGES for block in BLOCK.findall(page.read_text())]


def docs_lines() -> list[str]:
    lines = []
    for language, body in _blocks():
        for line in body.splitlines():
            if language == "" and line.startswith(PROMPT):
                lines.append(line.removeprefix(PROMPT))
            elif language == "bash" and "drake-uuv" in line:
                lines.append(line)
    return lines


def transcripts() -> list[tuple[list[str], str]]:
    pairs = []
    for language, body in _blocks():
        lines = body.splitlines()
        for line, shown in zip(lines, lines[1:], strict=False):
            if language == "" and line.startswith(f"{PROMPT}drake-uuv "):
                pairs.append((shlex.split(line.removeprefix(PROMPT))[1:], shown))
    return pairs


def commands() -> list[list[str]]:
    shown = [argv for argv, _ in transcripts()]
    found = [
        command[1:]
        for line in docs_lines()
        for command in shell_commands(line)
        if Path(command[0]).name == "drake-uuv"
    ]
    unique = []
    for argv in found:
        if argv not in unique and argv not in shown:
            unique.append(argv)
    return unique


def test_the_pages_have_commands() -> None:
    assert len(commands()) >= 20 and len(transcripts()) >= 4


@pytest.mark.parametrize("line", sorted(set(docs_lines())))
def test_no_line_has_a_bang_bash_would_expand(line: str) -> None:
    assert unquoted_bangs(line) == [], f"quote the ! of: {line}"


@pytest.mark.usefixtures("users_file")
@pytest.mark.parametrize("argv", commands(), ids=" ".join)
def test_each_command_parses_and_loads_its_scenario(argv: list[str]) -> None:
    args = make_parser().parse_args(argv)
    if hasattr(args, "overrides"):
        scenario_from_args(args)
    if getattr(args, "output_folder", False):
        check_output_folder(args.out)


@pytest.mark.usefixtures("users_file", "no_simulation")
@pytest.mark.parametrize("argv, shown", transcripts(), ids=[" ".join(a) for a, _ in transcripts()])
def test_each_error_shown_is_the_one_printed(argv, shown, capsys):
    assert main(argv) == 2
    assert capsys.readouterr().err == shown + "\n"
