"""Fixtures of the output tests: one recorded hopper run, shared by the whole session."""

import pytest

from helpers.recordings import recorded_hopper


@pytest.fixture(scope="session")
def hopper_run(tmp_path_factory):
    """(model, execution, path, read_rrd(path)) of the recorded hopper (do not modify)."""
    return recorded_hopper(tmp_path_factory.mktemp("rrd"))
