"""Regenerates diagrams/: the Graphviz exports the docs embed (``DOCUMENTED_DIAGRAMS``).

    python scripts/export_diagrams.py

tests/visualization/test_diagram_graph.py fails when a committed export is stale. Every
variant's diagram is exported by ``drake-uuv diagram --all-variants --out DIR`` instead.
"""

import argparse
import shutil
from pathlib import Path

from drake_uuv.visualization.diagram_graph import DOCUMENTED_DIAGRAMS, export_all_variants

DIAGRAMS = Path(__file__).resolve().parents[1] / "diagrams"


def main() -> None:
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args()
    if shutil.which("dot") is None:
        raise SystemExit("Graphviz's dot is needed to render diagrams/ (apt-get install graphviz)")
    for old in DIAGRAMS.glob("*.*"):
        old.unlink()  # an export the docs no longer embed must not linger
    for path in export_all_variants(DIAGRAMS, exports=DOCUMENTED_DIAGRAMS):
        print(path.relative_to(DIAGRAMS.parent))


if __name__ == "__main__":
    main()
