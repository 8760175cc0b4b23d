"""A sweep sent to a separately started Dask cluster (``dask scheduler`` and ``dask worker``
processes on localhost, as a stand-in for a real cluster) writes the table the embedded cluster
writes, byte for byte but for the wall-time column."""

from __future__ import annotations

import io
import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from legsim.cli import main
from legsim.sweep.table import TIMING_COLUMNS

SWEEP = [
    "sweep",
    "compass_gait",
    "--grid",
    "initial.state.stanced=0.9:1.3:3",
    "--grid",
    "initial.state.hipd=-1.2:-0.4:3",
    "--walk",
    "--max-steps",
    "8",
    "--batch",
    "2",
    "--quiet",
]


def dask_command() -> list[str]:
    """The ``dask`` command of this Python's environment."""
    beside = Path(sys.executable).parent / "dask"
    if beside.exists():
        return [str(beside)]
    found = shutil.which("dask")
    if found is None:
        pytest.skip("the dask command line is not installed")
    return [found]


def without_timing(path: Path) -> bytes:
    table = pq.read_table(path).drop_columns(list(TIMING_COLUMNS))
    sink = io.BytesIO()
    pq.write_table(table, sink, compression="zstd")
    return sink.getvalue()


@pytest.fixture
def cluster(tmp_path):
    """A scheduler and one worker (two processes, one thread each) on localhost; their address."""
    scheduler_file = tmp_path / "scheduler.json"
    with open(tmp_path / "scheduler.log", "wb") as scheduler_log, open(tmp_path / "worker.log", "wb") as worker_log:
        common = {"cwd": tmp_path, "stderr": subprocess.STDOUT}
        scheduler = subprocess.Popen(
            [
                *dask_command(),
                "scheduler",
                "--host",
                "127.0.0.1",
                "--port",
                "0",
                "--no-dashboard",
                "--scheduler-file",
                str(scheduler_file),
            ],
            stdout=scheduler_log,
            **common,
        )
        processes = [scheduler]
        try:
            deadline = time.monotonic() + 60
            while not scheduler_file.exists() and time.monotonic() < deadline and scheduler.poll() is None:
                time.sleep(0.1)
            address = json.loads(scheduler_file.read_text())["address"]
            processes.append(
                subprocess.Popen(
                    [
                        *dask_command(),
                        "worker",
                        address,
                        "--nworkers",
                        "2",
                        "--nthreads",
                        "1",
                        "--no-dashboard",
                        "--local-directory",
                        str(tmp_path),
                    ],
                    stdout=worker_log,
                    **common,
                )
            )
            yield address
        finally:
            for proc in reversed(processes):
                proc.terminate()
            for proc in reversed(processes):
                try:
                    proc.wait(timeout=30)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait()


def test_a_hand_started_scheduler_gives_the_embedded_clusters_table(cluster, tmp_path, capsys):
    assert main([*SWEEP, "--out", str(tmp_path / "remote"), "--scheduler", cluster]) == 0
    assert "on the Dask scheduler at " + cluster in capsys.readouterr().out
    assert main([*SWEEP, "--out", str(tmp_path / "local"), "--workers", "2"]) == 0
    remote, local = tmp_path / "remote" / "results.parquet", tmp_path / "local" / "results.parquet"
    assert without_timing(remote) == without_timing(local)
    table = pq.read_table(remote)
    assert table.num_rows == 9 and set(table.column("task_status").to_pylist()) == {"done"}
    assert "converges" in table.column("outcome").to_pylist()


def test_an_unreachable_scheduler_is_an_error_naming_it(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr("legsim.sweep.engine.CONNECT_TIMEOUT", 2.0)
    assert main([*SWEEP, "--out", str(tmp_path / "x"), "--scheduler", "tcp://127.0.0.1:9"]) == 2
    assert "cannot reach the Dask scheduler at tcp://127.0.0.1:9" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()
