"""The README is a front page, and the Markdown files a reader of the repository opens
(README.md, ARCHITECTURE.md, docs/results.md) link only to files that exist."""

import re
from pathlib import Path
from urllib.parse import unquote, urlsplit

import pytest

ROOT = Path(__file__).resolve().parents[2]
LINK = re.compile(r"\]\(([^)\s]+)\)")


def test_the_readme_is_a_front_page() -> None:
    lines = (ROOT / "README.md").read_text().splitlines()
    assert len(lines) <= 150
    text = "\n".join(lines)
    assert "sphinx-build -W" in text and "docs/_build/html" in text  # the docs command


@pytest.mark.parametrize("name", ["README.md", "ARCHITECTURE.md", "docs/results.md"])
def test_every_relative_link_resolves(name: str) -> None:
    page = ROOT / name
    links = [link for link in LINK.findall(page.read_text()) if not urlsplit(link).scheme]
    assert links
    for link in links:
        path = unquote(urlsplit(link).path)
        assert (page.parent / path).exists(), f"{name}: {link}"
