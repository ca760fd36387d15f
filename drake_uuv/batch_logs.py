"""A run's log and a batch log of runs: the views between them.

A run's log maps each signal's name to its values at the N steps (``N×shape``), plus ``k`` and
``time`` (N). A *batch log* holds B runs: each signal ``B×N×shape`` (run i in row i), ``k`` and
``time`` still (N), shared (:data:`SHARED_KEYS`).
"""

import numpy as np

#: The keys of a log that are not a run's signal: shared by the runs of a batch log.
SHARED_KEYS = frozenset({"k", "time"})


def run_log(log: dict[str, np.ndarray], run: int) -> dict[str, np.ndarray]:
    """Run ``run``'s own log (views) from a batch log."""
    return {name: value if name in SHARED_KEYS else value[run] for name, value in log.items()}


def batch_log(log: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """A run's log as a batch log of one run (views with a leading axis of 1)."""
    return {
        name: value if name in SHARED_KEYS else np.asarray(value)[np.newaxis]
        for name, value in log.items()
    }
