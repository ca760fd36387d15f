"""Fixtures of the study tests: the short scenario and studies of it."""

from pathlib import Path

import pytest

from drake_uuv.scenario import Scenario, load_scenario
from drake_uuv.studies import Study
from tests.studies.study_helpers import SHORT


@pytest.fixture
def short() -> Scenario:
    """The paper scenario, shortened to :data:`SHORT`."""
    return load_scenario("paper", list(SHORT))


@pytest.fixture
def make_study():
    """``make_study(folder, runs, *overrides, seed=None)``: a study of the short scenario."""

    def make(folder: Path, runs: int, *overrides: str, seed: int | None = None) -> Study:
        scenario = load_scenario("paper", [*SHORT, *overrides], seed=seed)
        return Study("test", scenario, runs, Path(folder))

    return make
