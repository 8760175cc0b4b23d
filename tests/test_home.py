"""Tests leave the home folder alone: a slice of the suite run with a fresh, empty ``HOME`` (and
no XDG folders set, so that every library's default location is under it) leaves it empty.

The slice holds tests that reach for the home folder, one kind each: a real Rerun server and a
viewer started by ``--spawn`` (Rerun's analytics config and queued events), plots (matplotlib's
font cache), a Dask sweep writing Parquet, and compiled kernels (legsim's and numba's caches).
``.ci/run`` makes the same check around the whole suite.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

# One test file or test per way of reaching the home folder; `legsim run --connect`
# (tests/commands/test_run_live.py) reaches it through the same Rerun client as the server tests.
SLICE = (
    "tests/output/rrd/test_live_server.py",
    "tests/viz/test_plots.py::test_write_plot_writes_a_png_of_the_figure_size",
    "tests/sweep/test_runner.py::test_a_local_dask_cluster_gives_the_table_of_this_process",
    "tests/sweep/test_runner.py::test_a_walk_sweep_draws_the_basin_and_an_orbit_sweep_the_stability_map",
    "tests/relaxed/test_paths.py::test_simultaneous_impacts_are_resolved_jointly_on_both_paths",
)


def test_a_slice_of_the_suite_leaves_a_fresh_home_empty(tmp_path):
    home = tmp_path / "home"
    home.mkdir()
    env = {
        name: value
        for name, value in os.environ.items()
        if not name.startswith("XDG_")
        and name not in ("LEGSIM_TEST_HOME", "LEGSIM_CACHE_DIR", "NUMBA_CACHE_DIR", "MPLCONFIGDIR")
    }
    env["HOME"] = str(home)
    result = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:xdist", "-p", "no:cacheprovider", *SLICE],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert result.returncode == 0, result.stdout[-4000:] + result.stderr[-2000:]
    # The slice proves something only where a Rerun server really ran.
    assert " passed" in result.stdout and "the rerun command" not in result.stdout, result.stdout[-2000:]
    left = sorted(str(p.relative_to(home)) for p in home.rglob("*"))
    assert left == [], f"the tests wrote in HOME: {left}"


def test_rerun_analytics_are_off_in_the_test_home():
    # conftest ran Rerun's documented opt-out there: `rerun analytics disable`.
    config = Path(os.environ["XDG_CONFIG_HOME"]) / "rerun" / "analytics.json"
    assert Path(os.environ["HOME"]) in config.parents
    assert json.loads(config.read_text())["analytics_enabled"] is False
