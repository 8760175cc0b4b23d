"""Fixtures shared by the metric tests."""

import pytest

from helpers.metric_systems import ball
from legsim import simulate


@pytest.fixture(scope="module")
def execution():
    """A relaxed simulation of the ball of tests/helpers/metric_systems.py over [0, 0.5] s."""
    return simulate(ball(), [1.0, 0.0], "fall", 0.5, 1e-3, 1e-3)
