"""`drake-uuv scenarios`: every shipped file with the description its own comment gives."""

import re
from importlib import resources

from drake_uuv.cli import main


def test_lists_every_shipped_file_with_its_description(capsys) -> None:
    assert main(["scenarios"]) == 0
    out = capsys.readouterr().out
    folder = resources.files("drake_uuv") / "scenarios"
    files = sorted(p for p in folder.iterdir() if p.name.endswith(".yaml"))
    assert len(files) >= 4
    listed = re.findall(r"^  (\S+) +(.+)$", out, re.MULTILINE)
    expected = []
    for path in files:  # read here from the files themselves, not through the loader
        (line,) = [s for s in path.read_text().splitlines() if s.startswith("# description:")]
        expected.append(
            (path.name.removesuffix(".yaml"), line.removeprefix("# description:").strip())
        )
    assert listed == expected
    assert "--scenario NAME" in out
