"""Fixtures of the stress tests."""

import pytest

from legsim import stress


@pytest.fixture
def scratch_cases():
    """Lets a test register cases of its own with ``stress.case``: the registry is restored when
    the test ends, in place, because the package and its framework module share the one list."""
    saved = list(stress.CASES)
    yield stress.CASES
    stress.CASES[:] = saved
