"""Test-suite policy: long sweeps marked ``slow`` run only on request.

CI (`make test`) runs every test's short form; `make test-full` (LEGSIM_FULL=1) or selecting
them with ``-m slow`` runs the long sweeps too.
"""

import os
import tempfile

# Compiled code (legsim's generated kernels, numba's caches of jitted functions) goes to a folder
# of the system's temporary directory, not to ~/.cache or the source tree: kept between test runs,
# so that a run does not compile every kernel again. Set before numba is imported.
_COMPILED = os.path.join(tempfile.gettempdir(), "legsim-test-compiled")
os.environ.setdefault("LEGSIM_CACHE_DIR", os.path.join(_COMPILED, "kernels"))
os.environ.setdefault("NUMBA_CACHE_DIR", os.path.join(_COMPILED, "numba"))

import pytest  # noqa: E402 -- after the cache folders are set
from hypothesis.configuration import set_hypothesis_home_dir  # noqa: E402

# Hypothesis keeps caches (``.hypothesis/``: constants, unicode tables, examples) in the working
# folder; tests write only in temporary folders.
set_hypothesis_home_dir(tempfile.mkdtemp(prefix="legsim-hypothesis-"))


def pytest_collection_modifyitems(config, items):
    if os.environ.get("LEGSIM_FULL") == "1" or "slow" in (config.getoption("-m") or ""):
        return
    skip = pytest.mark.skip(reason="long sweep: set LEGSIM_FULL=1 or select -m slow")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)
