"""Regenerates diagrams/: the Graphviz export of every diagram variant the package builds.

    python scripts/export_diagrams.py

tests/test_diagram_export.py fails when a committed export is stale.
"""

import argparse
import shutil
from pathlib import Path

from drake_uuv.visualization.diagram_graph import export_all_variants

DIAGRAMS = Path(__file__).resolve().parents[1] / "diagrams"


def main() -> None:
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args()
    if shutil.which("dot") is None:
        raise SystemExit("Graphviz's dot is needed to render diagrams/ (apt-get install graphviz)")
    for old in DIAGRAMS.glob("*.*"):
        old.unlink()  # a variant that no longer exists must not linger
    for path in export_all_variants(DIAGRAMS):
        print(path.relative_to(DIAGRAMS.parent))


if __name__ == "__main__":
    main()
