"""The results page, one page per study: ``docs/results/index.md`` and a page per section.

``scripts/make_results_page.py`` composes the results as one Markdown text, a ``## `` section
per study (each section module of ``studies/results_sections/`` returns one); this module cuts
that text at its ``## `` headings and writes each section as a page of its own, its headings
one level up and its relative links (figures, other pages) made relative to
``docs/results/``. The index keeps the title and the introduction and lists the pages.

Kept apart from the script so that the cut can be run on a page already made, without the
studies: ``python scripts/results_pages.py PAGE.md`` writes the pages of ``PAGE.md``.
"""

import argparse
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: A section's page, by the start of its heading; a section not listed gets a slug of its
#: heading.
SLUGS = {
    "The paper's figures": "paper-figures",
    "Monte Carlo: the paper scenario": "monte-carlo",
    "What reproduces and what does not": "claims",
    "Beyond the paper: how far from the best possible accuracy": "estimators",
    "Beyond the paper: tracking control a vehicle can follow": "tracking",
    "Does it survive a real vehicle?": "vehicle",
    "Estimation at the limit: noise and standoff": "regimes",
    "Attitude that seeks observability": "attitude",
    "Does it survive real navigation and sonar timing?": "navigation",
    "Does any run get lost?": "robustness",
    "Comparison tables": "comparison-tables",
}

_FENCE = re.compile(r"^(```|~~~)")
_LINK = re.compile(r"(\]\()(?!https?:|#|/|mailto:)([^)\s]+)(\))")


def slug(heading: str) -> str:
    for start, name in SLUGS.items():
        if heading.startswith(start):
            return name
    return re.sub(r"[^a-z0-9]+", "-", heading.lower()).strip("-")


def _lines_outside_code(lines: list[str]):
    """``(index, line)`` of the lines outside fenced code blocks."""
    fenced = False
    for i, line in enumerate(lines):
        if _FENCE.match(line):
            fenced = not fenced
            continue
        if not fenced:
            yield i, line


def _page(lines: list[str]) -> str:
    """A section as a page: headings one level up, relative links from one folder down."""
    lines = list(lines)
    for i, line in _lines_outside_code(lines):
        if line.startswith("##"):
            line = line[1:]
        lines[i] = _LINK.sub(lambda m: f"{m[1]}../{m[2]}{m[3]}", line)
    return "\n".join(lines).strip() + "\n"


def split_results(page: str) -> dict[str, str]:
    """``{file name: Markdown}``: ``index.md`` and one page per ``## `` section of ``page``."""
    lines = page.splitlines()
    starts = [i for i, line in _lines_outside_code(lines) if line.startswith("## ")]
    if not starts:
        raise ValueError("the results page has no '## ' section")
    intro = lines[: starts[0]]
    pages: dict[str, str] = {}
    for start, end in zip(starts, [*starts[1:], len(lines)], strict=True):
        name = f"{slug(lines[start][3:].strip())}.md"
        if name in pages:
            raise ValueError(f"two sections make the page {name}")
        pages[name] = _page(lines[start:end])
    toctree = ["```{toctree}", ":maxdepth: 1", "", *(n.removesuffix(".md") for n in pages), "```"]
    index = _page(intro).rstrip("\n")
    pages = {"index.md": "\n".join([index, "", *toctree]) + "\n", **pages}
    return pages


def write_results_pages(page: str, folder: Path) -> list[Path]:
    """Writes the pages of ``page`` into ``folder`` (``docs/results``), removing the pages of
    sections that are gone; returns the files written."""
    from drake_uuv.io import write_text_atomic

    folder.mkdir(parents=True, exist_ok=True)
    pages = split_results(page)
    for stale in folder.glob("*.md"):
        if stale.name not in pages:
            stale.unlink()
    written = []
    for name, text in pages.items():
        write_text_atomic(folder / name, text)
        written.append(folder / name)
    return written


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("page", type=Path, help="the results as one Markdown file")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "results")
    args = parser.parse_args()
    for path in write_results_pages(args.page.read_text(), args.out):
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
