"""Shared fixtures."""

import pytest

from drake_uuv.scenario import Scenario, load_scenario


@pytest.fixture
def paper() -> Scenario:
    """The shipped paper scenario."""
    return load_scenario("paper")
