"""What a study is: its request (:class:`Study`), its result, and its error.

The lowest module of :mod:`drake_uuv.studies`: the others import it, it imports none of them.
"""

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from drake_uuv.scenario import Scenario


class MonteCarloError(ValueError):
    """A bad study request (e.g. resuming a folder that holds another scenario's runs)."""


@dataclass(frozen=True)
class Study:
    """``runs`` seeded runs of ``scenario``, written to ``out_dir``.

    Run ``i`` uses seed ``scenario.random_seed + i``.
    """

    name: str
    scenario: Scenario
    runs: int
    out_dir: Path

    def seeds(self) -> list[int]:
        """The study's seeds, in order."""
        first = self.scenario.random_seed
        return [first + i for i in range(self.runs)]


@dataclass
class StudyResult:
    """A finished study: per-run metrics in seed order, error norms, and the summary."""

    study: Study
    seeds: np.ndarray
    metric_names: list[str]
    metrics: np.ndarray  # runs × metrics, float64
    norms: np.ndarray  # runs × len(NORMS) × steps, float32 (NORMS: drake_uuv.studies.runner)
    summary: dict[str, Any]
    computed: int  # runs computed now (the others were kept on disk)

    def column(self, name: str) -> np.ndarray:
        """One metric over all runs, in seed order."""
        return self.metrics[:, self.metric_names.index(name)]
