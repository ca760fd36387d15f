"""Work arrays a particle cloud's numpy steps reuse from step to step.

A step's temporaries of a 6×N cloud are 240 kB each at N = 5000: numpy allocates each afresh
and glibc maps (or trims and regrows) blocks that large on every allocation, so a step
faulted its pages in again each time (about 270 page faults a step of the paper's run, a
third of its cost). Every step takes an optional :class:`Workspace` and writes its
temporaries there; without one it allocates them, with the same arithmetic in the same
order, so both give the same bits.
"""

import numpy as np

#: The relative state ``[q, ϑ]``'s size: a particle's.
STATE_SIZE = 6


class Workspace:
    """Work arrays for the steps of a cloud of ``count`` particles, reused from step to step.

    ``arrays`` arrays of 6×``count``; a step uses the first four, a caller may keep the rest
    for its own (``workspace[i]``). It serves one call at a time: each system holds its own
    (a study builds its systems once per thread), and no step returns one of its arrays.
    """

    def __init__(self, count: int, arrays: int = 4) -> None:
        self._arrays = list(np.empty((arrays, STATE_SIZE, count)))
        # The views a step asks for, made once: each costs a microsecond, about 40 a step.
        self._rows = [[a[:rows] for rows in range(STATE_SIZE + 1)] for a in self._arrays]

    @property
    def count(self) -> int:
        return self._arrays[0].shape[1]

    def __getitem__(self, index: int) -> np.ndarray:
        return self._arrays[index]

    def rows(self, index: int, rows: int) -> np.ndarray:
        """The first ``rows`` rows of array ``index``."""
        return self._rows[index][rows]


def work_rows(work: Workspace | None, index: int, rows: int, count: int) -> np.ndarray:
    """The first ``rows`` rows of work array ``index``, or a new array without a workspace."""
    if work is None:
        return np.empty((rows, count))
    return work.rows(index, rows)
