"""``legsim run --connect`` and ``--spawn`` against a real Rerun server: the ``rerun`` command,
headless, hosts a gRPC server and saves what it receives to a file, which holds the entities and
samples that ``--rrd`` writes for the same run (a URDF robot, whose geometry Rerun's loader makes
on the sending side)."""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from rerun.chunk import RrdReader

from helpers.rerun_server import free_port, settle, stop, wait_for
from legsim.cli import main
from legsim.output.rrd import read_rrd
from legsim.output.rrd.layout import FILE_DIGEST

RUN = ["quadruped_pronk", "--set", "integrator.t_final=0.12", "--quiet"]


def _rerun_binary() -> str | None:
    """The ``rerun`` command of this environment (next to its python), or on PATH."""
    local = Path(sys.executable).with_name("rerun")
    return str(local) if local.is_file() else shutil.which("rerun")


def _entities(path: Path) -> set[tuple[str, bool]]:
    """(entity path, static) of every chunk of the recording, Rerun's bookkeeping aside, and the
    seal of a written file (the SHA-256 of its own bytes: a viewer saves bytes of its own)."""
    return {
        (c.entity_path, c.is_static)
        for c in RrdReader(path).stream()
        if not c.entity_path.startswith("/__") and c.entity_path != FILE_DIGEST
    }


@pytest.fixture
def rerun_server(tmp_path):
    """(port, saved file) of a headless Rerun server, stopped after the test."""
    binary = _rerun_binary()
    if binary is None:
        pytest.skip("the rerun command (rerun-sdk's CLI) is not installed here")
    port, saved = free_port(), tmp_path / "received.rrd"
    server = subprocess.Popen(
        [binary, "--serve-grpc", "--port", str(port), "--save", str(saved)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        wait_for(port, server)
        yield port, saved, server
    finally:
        stop(server)


# The server's --save file ends without the footer a finished recording file has.
@pytest.mark.filterwarnings("ignore:RRD file has no footer")
def test_connect_sends_what_rrd_writes_to_a_real_rerun_server(rerun_server, tmp_path):
    port, saved, server = rerun_server
    written = tmp_path / "written.rrd"
    assert main(["run", *RUN, "--rrd", str(written), "--connect", f"rerun+http://127.0.0.1:{port}/proxy"]) == 0
    settle(saved)
    stop(server)
    received, expected = read_rrd(saved), read_rrd(written)
    assert len(received["times"]) == len(expected["times"]) == expected["meta"]["computed_samples"]
    np.testing.assert_array_equal(received["times"], expected["times"])
    assert _entities(saved) == _entities(written)
    assert any(path.startswith("/world/robot/quadruped/visual_geometries/") for path, _ in _entities(saved))


#: The port ``rr.spawn`` starts its viewer on and connects to (legsim passes no other).
SPAWN_PORT = 9876


def _processes_saving_to(saved: Path) -> list[int]:
    """The ids of the processes whose command line names ``saved`` (a file in this test's
    tmp_path: only the server this test had spawned)."""
    pids = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                if str(saved).encode() in (entry / "cmdline").read_bytes():
                    pids.append(int(entry.name))
            except OSError:
                continue
    return pids


def _answers(port: int) -> bool:
    try:
        socket.create_connection(("127.0.0.1", port), timeout=0.5).close()
        return True
    except OSError:
        return False


@pytest.mark.filterwarnings("ignore:RRD file has no footer")
def test_spawn_starts_rerun_and_sends_it_what_rrd_writes(tmp_path, monkeypatch):
    # rr.spawn starts the `rerun` found on PATH with viewer options: a `rerun` first on PATH that
    # adds --save makes it the headless server, which needs no display (legsim's check does).
    binary = _rerun_binary()
    if binary is None:
        pytest.skip("the rerun command (rerun-sdk's CLI) is not installed here")
    if not Path("/proc").is_dir():
        pytest.skip("finding the spawned server to stop it needs /proc")
    if _answers(SPAWN_PORT):
        pytest.skip(f"something already listens on port {SPAWN_PORT}, where --spawn would send the run")
    saved, written, bin_dir = tmp_path / "spawned.rrd", tmp_path / "written.rrd", tmp_path / "bin"
    bin_dir.mkdir()
    wrapper = bin_dir / "rerun"
    wrapper.write_text(f'#!/bin/sh\nexec "{binary}" --save "{saved}" "$@"\n')
    wrapper.chmod(0o755)
    monkeypatch.setenv("PATH", f"{bin_dir}{os.pathsep}{os.environ.get('PATH', '')}")
    monkeypatch.setenv("DISPLAY", ":0")
    # A machine where Rerun never ran: the viewer legsim starts must not turn its analytics on.
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "config"))
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "data"))
    monkeypatch.delenv("FORCE_RERUN_ANALYTICS", raising=False)
    try:
        assert main(["run", *RUN, "--rrd", str(written), "--spawn"]) == 0
        settle(saved)
    finally:
        for pid in _processes_saving_to(saved):
            os.kill(pid, signal.SIGINT)
        deadline = time.monotonic() + 30
        while _processes_saving_to(saved) and time.monotonic() < deadline:
            time.sleep(0.2)
        for pid in _processes_saving_to(saved):
            os.kill(pid, signal.SIGKILL)
    received, expected = read_rrd(saved), read_rrd(written)
    np.testing.assert_array_equal(received["times"], expected["times"])
    assert _entities(saved) == _entities(written)
    setting = json.loads((tmp_path / "config" / "rerun" / "analytics.json").read_text())
    assert setting["analytics_enabled"] is False
