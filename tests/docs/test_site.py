"""The documentation site builds with warnings as errors, and the built HTML holds what the
reference promises: every public system with its ports drawn, every public dataclass with its
fields, every slot's variants, the tutorial's outputs, and no broken internal link.

The site is built once per run of this module, as the README's docs command builds it (into
a temporary folder; the notebook cache, ``docs/_build/.jupyter_cache``, is shared and kept
only while the code is unchanged)."""

import dataclasses
import html
import importlib
import inspect
import pkgutil
import re
import subprocess
import sys
import time
from dataclasses import dataclass
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

import pytest

import drake_uuv

pytest.importorskip("sphinx", reason="the test extra: pip install -e '.[test]'")
pytest.importorskip("myst_nb", reason="the test extra: pip install -e '.[test]'")
pytest.importorskip("furo", reason="the test extra: pip install -e '.[test]'")

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
sys.path.insert(0, str(DOCS / "_ext"))
import uuv_sphinx  # noqa: E402 (docs/_ext, put on the path above)

pytestmark = pytest.mark.slow
#: The build's budget on 2 cores (the issue's: 3 minutes), with room for a loaded machine.
BUDGET_S = 600


@dataclass(frozen=True)
class Site:
    html: Path
    seconds: float
    output: str


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Site:
    out = tmp_path_factory.mktemp("site")
    command = [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-b", "html",
               "-d", str(out / "doctrees"), str(DOCS), str(out / "html")]  # fmt: skip
    start = time.perf_counter()
    result = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=1200)
    seconds = time.perf_counter() - start
    output = result.stdout + result.stderr
    assert result.returncode == 0, output[-6000:]
    return Site(out / "html", seconds, output)


def _page(site: Site, name: str) -> str:
    return (site.html / name).read_text()


def test_the_site_builds_with_warnings_as_errors_in_its_budget(site: Site) -> None:
    assert (site.html / "index.html").exists()
    # Sphinx's own (a kernel's "[IPKernelApp] WARNING | ..." is not one).
    assert not re.search(r"\b(WARNING|ERROR|CRITICAL):", site.output), site.output[-4000:]
    print(f"docs build: {site.seconds:.0f} s")
    assert site.seconds < BUDGET_S


def _public_classes() -> list[type]:
    classes = []
    for info in pkgutil.walk_packages(drake_uuv.__path__, "drake_uuv."):
        if info.name.endswith("__main__"):
            continue
        module = importlib.import_module(info.name)
        for name, obj in vars(module).items():
            if inspect.isclass(obj) and obj.__module__ == info.name and not name.startswith("_"):
                classes.append(obj)
    return classes


def _systems() -> list[type]:
    from pydrake.systems.framework import Diagram, LeafSystem

    return [c for c in _public_classes() if issubclass(c, LeafSystem | Diagram)]


def _dataclasses() -> list[type]:
    return [c for c in _public_classes() if dataclasses.is_dataclass(c)]


def _reference(site: Site) -> dict[str, str]:
    """``{object id: the HTML of its entry}`` over the API pages: from its ``id`` to the next
    module-level class's or function's (its methods and attributes included)."""
    entries = {}
    for page in sorted((site.html / "reference" / "api").glob("*.html")):
        text = page.read_text()
        starts: list[tuple[int, str]] = [(m.start(), m.group(1)) for m in re.finditer(
        r'<dl class="py (?:class|function|exception|data)">\s*'
        r'<dt class="sig sig-object py" id="([\w.]+)"', text)]  # fmt: skip
        if not starts:
            continue
        ends = [start for start, _ in starts[1:]] + [len(text)]
        for (start, name), end in zip(starts, ends, strict=True):
            entries[name] = entries.get(name, "") + text[start:end]
    return entries


def _id(cls: type) -> str:
    return f"{cls.__module__}.{cls.__qualname__}"


def _drawn(fragment: str) -> list[str]:
    """The system names of the port blocks drawn in an HTML fragment."""
    return re.findall(r'<span class="uuv-system-name">([^<]+)</span>', fragment)


def _ports(fragment: str) -> set[str]:
    """The port names drawn in an HTML fragment (a port's condition left out)."""
    names = re.findall(
        r'<span class="uuv-port-name">(.*?)</span>(?=<span class="uuv-port-arrow|\s*</div>)',
        fragment, re.DOTALL,
    )  # fmt: skip
    names = [re.sub(r'<span class="uuv-port-condition">.*', "", name) for name in names]
    return {html.unescape(re.sub(r"<[^>]+>", "", name)).strip() for name in names}


def _literals(fragment: str) -> set[str]:
    return {html.unescape(m) for m in re.findall(r'<span class="pre">([^<]+)</span>', fragment)}


def test_every_public_system_is_in_the_reference_with_its_ports(site: Site) -> None:
    entries = _reference(site)
    systems = _systems()
    assert len(systems) >= 20
    for system in systems:
        entry = entries.get(_id(system))
        assert entry is not None, f"{_id(system)} is not in the reference"
        blocks = uuv_sphinx.system_blocks(system.__doc__ or "")
        # A class entry runs to the next documented object, its methods included: its own
        # docstring comes first, so its blocks are the first drawn.
        drawn = _drawn(entry)
        assert drawn[: len(blocks)] == [b["name"] for b in blocks], _id(system)
        for block in blocks:
            names = {name for name, _ in block["input_ports"] + block["output_ports"]}
            assert names <= _ports(entry), f"{_id(system)}: ports not drawn"


def test_every_public_dataclass_is_in_the_reference_with_its_fields(site: Site) -> None:
    entries = _reference(site)
    classes = _dataclasses()
    assert len(classes) >= 60
    for cls in classes:
        entry = entries.get(_id(cls))
        assert entry is not None, f"{_id(cls)} is not in the reference"
        fields = [f.name for f in dataclasses.fields(cls)]
        if fields:
            assert 'class="uuv-fields' in entry, f"{_id(cls)} has no fields table"
            table = entry[entry.index('class="uuv-fields') :]
            table = table[: table.index("</table>")]
            assert set(fields) <= _literals(table), f"{_id(cls)}: fields missing"
            assert table.count('class="uuv-field') >= len(fields)


def test_the_slots_page_shows_every_variant_with_its_ports_and_fields(site: Site) -> None:
    from drake_uuv.diagram import SLOT_REGISTRY
    from drake_uuv.plants import TargetRandomWalk
    from drake_uuv.scenario import SonarConfig, TargetConfig
    from drake_uuv.sensors import DualSonar

    page = _page(site, "reference/slots.html")
    sections = re.split(r"<section id=", page)
    pairs = [(f"!{v.__name__}", v, s) for slot in SLOT_REGISTRY for v, s in slot.table.items()]
    pairs += [("TargetConfig", TargetConfig, TargetRandomWalk),
              ("SonarConfig", SonarConfig, DualSonar)]  # fmt: skip
    for heading, config, system in pairs:
        found = [s for s in sections if re.search(rf"<h3>.*{re.escape(heading)}.*</h3>", s)]
        assert len(found) == 1, heading
        section = found[0]
        assert _drawn(section) == [system.__name__], heading
        assert {f.name for f in dataclasses.fields(config)} <= _literals(section), heading


def test_the_guide_tables_every_variant_with_its_system(site: Site) -> None:
    from drake_uuv.diagram import SLOT_REGISTRY

    page = _page(site, "guide/diagram.html")
    table = page[page.index('class="uuv-slot-table') :]
    table = table[: table.index("</table>")]
    names = _literals(table)
    for slot in SLOT_REGISTRY:
        for variant, system in slot.table.items():
            assert {f"!{variant.__name__}", system.__name__} <= names, variant.__name__


def test_the_signals_page_lists_every_signal(site: Site) -> None:
    from drake_uuv.estimators.range_filter import RangeFilter
    from drake_uuv.plants.hovering_auv import HoveringAuvPlant
    from drake_uuv.signals import SIGNALS

    page = _page(site, "reference/signals.html")
    extra = [*HoveringAuvPlant.extra_signals, *RangeFilter.extra_signals]
    for signal in [*SIGNALS, *extra]:
        assert f'id="{uuv_sphinx.signal_label(signal.name)}"' in page, signal.name


@pytest.mark.parametrize(
    "notebook", sorted(p.stem for p in (ROOT / "tutorials").glob("*.ipynb")), ids=str
)
def test_each_tutorial_ran_at_build_time(site: Site, notebook: str) -> None:
    page = _page(site, f"tutorials/{notebook}.html")
    outputs = re.findall(r'<div class="cell_output docutils container">', page)
    assert len(outputs) >= 3
    assert page.count("<img ") >= 2
    assert "Traceback" not in page
    assert f'href="{notebook}.html"' in _page(site, "tutorials/index.html")


def test_every_results_page_and_figure_is_there(site: Site) -> None:
    for page in (DOCS / "results").glob("*.md"):
        assert (site.html / "results" / f"{page.stem}.html").exists(), page.name
    text = "".join(page.read_text() for page in (DOCS / "results").glob("*.md"))
    figures = set(re.findall(r"\(\.\./figures/([\w.-]+\.png)\)", text))
    assert len(figures) >= 15
    assert figures <= {p.name for p in (site.html / "_images").iterdir()}


class _Links(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.links: list[str] = []
        self.ids: set[str] = set()

    def handle_starttag(self, tag: str, attrs: list) -> None:
        for name, value in attrs:
            if name == "id" and value:
                self.ids.add(value)
            elif name in ("href", "src") and value and tag in ("a", "img", "link", "script"):
                self.links.append(value)


def test_no_internal_link_is_broken(site: Site) -> None:
    parsed: dict[Path, _Links] = {}
    for page in site.html.rglob("*.html"):
        links = _Links()
        links.feed(page.read_text())
        parsed[page] = links
    broken = []
    for page, links in parsed.items():
        for link in links.links:
            parts = urlsplit(link)
            if parts.scheme or parts.netloc:
                continue  # an external link: not checked (the build fetches nothing)
            target = (page.parent / unquote(parts.path)).resolve() if parts.path else page
            if target.is_dir():
                target = target / "index.html"
            if not target.exists():
                broken.append(f"{page.relative_to(site.html)}: {link}")
            elif parts.fragment and target.suffix == ".html":
                ids = parsed[target].ids if target in parsed else set()
                if unquote(parts.fragment) not in ids:
                    broken.append(f"{page.relative_to(site.html)}: {link} (no such anchor)")
    assert not broken, "\n".join(broken[:40])
    assert sum(len(links.links) for links in parsed.values()) > 1000
