"""Fixtures of the visualization tests."""

import pytest

from tests.visualization.synthetic_log import synthetic_log


@pytest.fixture(scope="session")
def short_log() -> dict:
    """A synthetic log of 100 steps, seed 0."""
    return synthetic_log(100, seed=0)
