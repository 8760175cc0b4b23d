"""Issue 16, "the test suite changes the host": no test installs or upgrades system software.
Without a browser the browser tests are skipped, saying why, and call no installer."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

TESTS = Path(__file__).resolve().parents[1]
REPO = TESTS.parent
INSTALLERS = (
    "apt-get",
    "apt",
    "aptitude",
    "dpkg",
    "dnf",
    "yum",
    "zypper",
    "pacman",
    "apk",
    "snap",
    "brew",
    "port",
    "sudo",
)


def test_no_test_calls_a_system_package_manager():
    # A command line in a test that starts with an installer: ["apt-get", ...] or "apt-get ...".
    names = "|".join(map(re.escape, INSTALLERS))
    call = re.compile(rf"""[\[(,]\s*["'](?:{names})["']|["'](?:{names})\s+(?:install|update|upgrade|-)""")
    found = {
        str(p.relative_to(REPO)): m.group()
        for p in sorted(TESTS.rglob("*.py"))
        if p != Path(__file__).resolve() and (m := call.search(p.read_text()))
    }
    assert found == {}


def test_without_a_browser_the_browser_tests_are_skipped_and_install_nothing(tmp_path):
    # A PATH holding only fake installers that note any call: the browser tests find no
    # browser, skip with the reason, and none of the installers runs.
    fake = tmp_path / "bin"
    fake.mkdir()
    calls = tmp_path / "installer-calls"
    for name in INSTALLERS:
        script = fake / name
        script.write_text(f'#!/bin/sh\necho {name} "$@" >> {calls}\nexit 1\n')
        script.chmod(0o755)
    env = {k: v for k, v in os.environ.items() if k not in ("LEGSIM_BROWSER", "PYTEST_ADDOPTS", "PYTEST_XDIST_WORKER")}
    env["PATH"] = str(fake)
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "-p",
            "no:xdist",
            "-p",
            "no:cacheprovider",
            "-q",
            "-rs",
            str(TESTS / "viz" / "test_browser_html.py"),
        ],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert re.search(r"\b6 skipped\b", done.stdout) and "passed" not in done.stdout, done.stdout[-3000:]
    assert "no headless Chromium on PATH" in done.stdout and "make test-browser" in done.stdout
    assert not calls.exists(), calls.read_text()
