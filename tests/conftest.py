"""Test-suite policy: tests write only in temporary folders, and long sweeps marked ``slow``
run only on request.

CI (`make test`) runs every test's short form; `make test-full` (LEGSIM_FULL=1) or selecting
them with ``-m slow`` runs the long sweeps too.
"""

import atexit
import contextlib
import os
import shutil
import signal
import subprocess
import sys
import tempfile

# Libraries write settings, caches and telemetry under the home folder (Rerun's analytics
# config and queued events, matplotlib's font cache, ...). Every test process gets a home and
# XDG folders of its own in the system's temporary directory, set before any of those
# libraries is imported. pytest-xdist's workers inherit the controller's, marked by
# LEGSIM_TEST_HOME; the process that made the folder removes it at exit.
XDG_FOLDERS = {
    "XDG_CONFIG_HOME": ".config",
    "XDG_DATA_HOME": os.path.join(".local", "share"),
    "XDG_CACHE_HOME": ".cache",
    "XDG_STATE_HOME": os.path.join(".local", "state"),
}


def _rerun_analytics_off(env: dict[str, str]) -> None:
    """Rerun's documented opt-out, ``rerun analytics disable``, in the test home: a viewer or
    server a test starts (``rerun --serve-grpc``) then records no usage event. Without
    rerun-sdk's command the tests that need it skip, and nothing is done here."""
    with contextlib.suppress(OSError, subprocess.SubprocessError):
        subprocess.run(
            [sys.executable, "-m", "rerun_cli", "analytics", "disable"],
            env=env,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            timeout=60,
            check=False,
        )


def _user_pip_config() -> str | None:
    """The user's own pip configuration file (the package index a build may need), read where
    pip reads it before the home folder moves; None when there is none."""
    config = os.environ.get("XDG_CONFIG_HOME") or os.path.join(os.path.expanduser("~"), ".config")
    for path in (os.path.join(config, "pip", "pip.conf"), os.path.join(os.path.expanduser("~"), ".pip", "pip.conf")):
        if os.path.isfile(path):
            return path
    return None


def _own_home() -> None:
    home = os.environ.get("LEGSIM_TEST_HOME")
    if not home or os.environ.get("HOME") != home:
        # The packaging tests run pip; it keeps reading the user's configuration, read-only.
        pip_config = _user_pip_config()
        if pip_config is not None:
            os.environ.setdefault("PIP_CONFIG_FILE", pip_config)
        home = tempfile.mkdtemp(prefix="legsim-test-home-")
        atexit.register(shutil.rmtree, home, ignore_errors=True)
        os.environ["LEGSIM_TEST_HOME"] = os.environ["HOME"] = home
        for name, folder in XDG_FOLDERS.items():
            os.environ[name] = os.path.join(home, folder)
        _rerun_analytics_off(dict(os.environ))


_own_home()

# A shell starts a background job with SIGINT ignored, and every command a test starts would
# inherit that: the tests of Ctrl-C need the signal's default, whoever started the suite.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

# Compiled code (legsim's generated kernels, numba's caches of jitted functions) goes to a folder
# of the system's temporary directory, not to the test home or the source tree: kept between
# test runs, so that a run does not compile every kernel again. Set before numba is imported.
_COMPILED = os.path.join(tempfile.gettempdir(), "legsim-test-compiled")
os.environ.setdefault("LEGSIM_CACHE_DIR", os.path.join(_COMPILED, "kernels"))
os.environ.setdefault("NUMBA_CACHE_DIR", os.path.join(_COMPILED, "numba"))

import pytest  # noqa: E402 -- after the home and cache folders are set
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
