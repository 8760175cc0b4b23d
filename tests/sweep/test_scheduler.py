"""A sweep sent to a separately started Dask cluster (``dask scheduler`` and ``dask worker``
processes on localhost, as a stand-in for a real cluster) writes the table the embedded cluster
writes, byte for byte but for the wall-time column."""

from __future__ import annotations

import contextlib
import io
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from helpers.peers import closed_port, silent_peer
from helpers.reliability import watchdog
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


@contextlib.contextmanager
def hand_started_cluster(tmp_path: Path) -> Iterator[tuple[str, subprocess.Popen]]:
    """A scheduler and one worker (two processes, one thread each) on localhost: the scheduler's
    address and process."""
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
            yield address, scheduler
        finally:
            for proc in processes:
                proc.send_signal(signal.SIGCONT)  # a test may have stopped it
            # The worker first, while its scheduler still answers: a worker whose scheduler is
            # gone waits out its reconnection timeouts before it exits.
            for proc in reversed(processes):
                proc.terminate()
                try:
                    proc.wait(timeout=30)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait()


@pytest.fixture
def cluster(tmp_path):
    """A hand-started cluster's address (``hand_started_cluster``)."""
    with hand_started_cluster(tmp_path) as (address, _):
        yield address


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


def test_a_scheduler_that_accepts_and_never_answers_is_given_up_at_the_deadline(tmp_path, capsys):
    # Dask's handshake waited for its answer forever, whatever the client's timeout.
    with silent_peer() as peer, watchdog(60):
        port = peer.port
        began = time.monotonic()
        code = main(
            [*SWEEP, "--out", str(tmp_path / "x"), "--scheduler", f"tcp://127.0.0.1:{port}", "--connect-timeout", "1"]
        )
        elapsed = time.monotonic() - began
    assert code == 2 and elapsed < 5
    assert (
        f"the Dask scheduler at tcp://127.0.0.1:{port} accepted the connection but did not answer within 1 s "
        f"(--connect-timeout)" in capsys.readouterr().err
    )
    assert not (tmp_path / "x").exists()


def test_a_closed_scheduler_port_is_refused_at_once(tmp_path, capsys):
    # Dask retried the refused connection until its timeout: 21 s.
    port = closed_port()
    began = time.monotonic()
    assert main([*SWEEP, "--out", str(tmp_path / "x"), "--scheduler", f"127.0.0.1:{port}"]) == 2
    assert time.monotonic() - began < 3
    err = capsys.readouterr().err
    assert f"cannot reach the Dask scheduler at 127.0.0.1:{port}: 127.0.0.1:{port}: Connection refused" in err


@pytest.mark.parametrize(
    "address", ["tcp://127.0.0.1:8786:9", "::::", "http://127.0.0.1:8786", "scheduler", "tcp://h:0"]
)
def test_a_malformed_scheduler_address_is_named(address, tmp_path, capsys):
    # Some were internal errors from Dask's address parser.
    assert main([*SWEEP, "--out", str(tmp_path / "x"), "--scheduler", address]) == 2
    assert f"--scheduler {address!r}: not a Dask scheduler address; give tcp://HOST:PORT" in capsys.readouterr().err


def test_a_malformed_address_from_the_environment_is_named_as_such(tmp_path, capsys, monkeypatch):
    # The message named --scheduler, an option the user had not given.
    monkeypatch.setenv("DASK_SCHEDULER_ADDRESS", "nonsense:::")
    assert main([*SWEEP, "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("legsim: error: $DASK_SCHEDULER_ADDRESS 'nonsense:::': not a Dask scheduler address")


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_an_interrupted_dask_sweep_ends_within_2_s_without_worker_tracebacks(tmp_path, sig):
    """The signal goes to the whole process group, as Ctrl-C at a terminal does: the workers
    printed a 30-line KeyboardInterrupt traceback each."""
    out = tmp_path / "s"
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "legsim.cli",
            "sweep",
            "bouncing_ball",
            "--grid",
            "initial.state.z=0.5:2:4000",
            "--set",
            "integrator.t_final=2",
            "--workers",
            "2",
            "--batch",
            "20",
            "--out",
            str(out),
            "--quiet",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    deadline = time.monotonic() + 120
    while not list((out / "results.parts").glob("part-*.parquet")) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert proc.poll() is None, "the sweep ended before the test saw its first batch"
    sent = time.monotonic()
    os.killpg(proc.pid, sig)
    _, err = proc.communicate(timeout=60)
    elapsed = time.monotonic() - sent
    assert proc.returncode == (130 if sig == signal.SIGINT else 143), (proc.returncode, elapsed, err[-2000:])
    assert err == ("legsim: interrupted\n" if sig == signal.SIGINT else "legsim: terminated\n")
    assert elapsed < 2.0, f"the sweep ended {elapsed:.2f} s after the signal"
    table = pq.read_table(out / "results.parquet")
    assert 0 < table.num_rows < 4000 and set(table.column("task_status").to_pylist()) == {"done"}


def test_a_scheduler_that_stops_answering_during_the_sweep_ends_it_with_the_rows_so_far(tmp_path):
    # The sweep waited forever for batches a stopped scheduler would never report (Ctrl-C
    # alone ended it).
    out = tmp_path / "s"
    with hand_started_cluster(tmp_path) as (address, scheduler):
        proc = subprocess.Popen(
            [sys.executable, "-m", "legsim.cli", "sweep", "bouncing_ball", "--grid", "initial.state.z=0.5:2:400",
             "--set", "integrator.t_final=2", "--batch", "5", "--out", str(out), "--quiet",
             "--scheduler", address, "--connect-timeout", "2"],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        )  # fmt: skip
        deadline = time.monotonic() + 120
        while not list((out / "results.parts").glob("part-*.parquet")) and time.monotonic() < deadline:
            time.sleep(0.05)
        scheduler.send_signal(signal.SIGSTOP)
        stopped = time.monotonic()
        try:
            _, err = proc.communicate(timeout=60)
        finally:
            proc.kill()  # a hang fails the test, and leaves no sweep behind
            proc.wait()
        elapsed = time.monotonic() - stopped
    # At most 2 s without a finished batch, 2 s for the scheduler's answer, then the client's
    # close (bounded by Dask at twice the timeout); the margin is for a loaded machine.
    assert proc.returncode == 2 and elapsed < 15, (elapsed, err)
    assert err == (
        f"legsim: error: the Dask scheduler at {address} stopped answering during the sweep (no batch came back "
        f"and no answer within 2 s each, --connect-timeout; TimeoutError); the rows finished so far are kept: "
        f"continue with --resume\n"
    )
    table = pq.read_table(out / "results.parquet")
    assert 0 < table.num_rows < 400 and set(table.column("task_status").to_pylist()) == {"done"}
