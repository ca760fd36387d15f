"""Helpers of the study tests (``from tests.studies.study_helpers import ...``)."""

from pathlib import Path

import numpy as np

# 80 steps, steady state from k = 40: long enough for every metric, ≈ 0.1 s a run.
SHORT = ("steps=80", "steady_state_start=40")


def outputs(folder: Path) -> tuple[str, str]:
    """``summary.json`` and ``runs.csv`` of a study folder, as text."""
    return (folder / "summary.json").read_text(), (folder / "runs.csv").read_text()


def synthetic_chunk(seeds, names=("position_rmse", "failed"), steps=4, information=True):
    """A chunk as :func:`drake_uuv.studies.runner.run_seeds` returns it, with values that
    encode the seed (metric j of seed s is s + j/10, norms s, information s) so that tests
    can tell runs apart without simulating."""
    seeds = np.asarray(seeds, dtype=np.int64)
    metrics = np.array([[s + j / 10 for j in range(len(names))] for s in seeds], dtype=float)
    norms = np.broadcast_to(seeds[:, None, None], (len(seeds), 4, steps)).astype(np.float32)
    total = np.full((steps, 3, 3), int(seeds.sum()), dtype=np.int64) if information else None
    return {
        "seeds": seeds,
        "metric_names": list(names),
        "metrics": metrics,
        "norms": norms,
        "information_sum": total,
    }
