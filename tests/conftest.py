"""Test-suite policy: long sweeps marked ``slow`` run only on request.

CI (`make test`) runs every test's short form; `make test-full` (LEGSIM_FULL=1) or selecting
them with ``-m slow`` runs the long sweeps too.
"""

import os

import pytest


def pytest_collection_modifyitems(config, items):
    if os.environ.get("LEGSIM_FULL") == "1" or "slow" in (config.getoption("-m") or ""):
        return
    skip = pytest.mark.skip(reason="long sweep: set LEGSIM_FULL=1 or select -m slow")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)
