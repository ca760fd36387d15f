"""Sections of the results pages (docs/results/) beyond the paper's own claims, one module each.

Each module defines ``section(work, docs, runs, execution) -> str``: it runs (or, with
``execution["resume"]``, reuses) its studies under ``work``, writes its figures into
``docs/figures``, and returns its Markdown. ``scripts/make_results_page.py`` joins them in the
order of :data:`SECTIONS`.
"""

from collections.abc import Callable
from pathlib import Path
from typing import Any

Section = Callable[[Path, Path, int, dict[str, Any]], str]

from . import attitude, navigation, regimes, robustness, vehicle  # noqa: E402  (after Section, which they do not need)

SECTIONS: list[Section] = [
    vehicle.section,
    regimes.section,
    attitude.section,
    navigation.section,
    robustness.section,
]
