"""Shared fixtures and constants of the tests.

The constants are the paper's simulation (§IV) unless a name says otherwise; import them with
``from tests.conftest import T, W, ETA``. The repository's study groups and their constants
(the ``studies/`` folder beside the package) are reached through :func:`study_module`, which
loads them as ``drake-uuv compare`` does.
"""

from __future__ import annotations

import importlib
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING

import numpy as np
import pytest

# The package is imported where first used: pytest-xdist's controller loads this file too, and
# runs no test.
if TYPE_CHECKING:
    from drake_uuv.scenario import Scenario

#: The repository's studies folder: the groups of ``drake-uuv compare``, the results page.
STUDIES = Path(__file__).resolve().parents[1] / "studies"

#: The paper's sampling period t [s].
T = 0.5
#: The paper's target acceleration covariance W [m²/s⁴].
W = np.diag([0.004, 0.001, 0.001])
#: The paper's range noise variances η1, η2 [m²].
ETA = np.array([0.01, 0.01])
#: Unequal range noise variances, so a test catches the two sonars swapped [m²].
ETA_UNEQUAL = np.array([0.01, 0.02])
#: A relative state near the paper's q* = [−2, −2, 0]: [q, ϑ] [m, m/s].
X0 = np.array([-1.8, -2.3, 0.4, 0.05, 0.0, -0.02])


@pytest.fixture
def paper() -> Scenario:
    """The shipped paper scenario."""
    from drake_uuv.scenario import load_scenario

    return load_scenario("paper")


def study_module(name: str = "") -> ModuleType:
    """The repository's ``studies/`` package (``name`` empty) or one of its modules
    (``"vehicle"``, ``"paired"``, ...), loaded by the loader of ``drake-uuv compare``
    (:func:`drake_uuv.studies.load_studies`)."""
    from drake_uuv.studies import load_studies

    package = load_studies(STUDIES)
    return importlib.import_module(f"{package.__name__}.{name}") if name else package
