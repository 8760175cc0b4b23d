"""``legsim run --spawn / --connect ADDRESS / --rrd-rate HZ``: the recording streamed to a
Rerun viewer is the one ``--rrd`` writes, and every bad use is refused before the run."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from helpers.peers import HTTP2_SETTINGS, closed_port, silent_peer
from helpers.rerun_server import free_port, settle, stop, wait_for
from legsim.cli import main
from legsim.errors import LegsimError
from legsim.output.rrd import read_rrd
from legsim.output.rrd.live import viewer_url

SHORT = ["bouncing_ball", "--set", "integrator.t_final=1.0", "--quiet"]


def test_connect_streams_the_recording_rrd_writes(tmp_path):
    # Rerun's own server stands in for a viewer: it saves what it receives to a file.
    port = free_port()
    saved, written = tmp_path / "received.rrd", tmp_path / "written.rrd"
    server = subprocess.Popen(
        [sys.executable, "-m", "rerun_cli", "--save", str(saved), "--port", str(port)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        wait_for(port, server)
        assert main(["run", *SHORT, "--rrd", str(written), "--connect", str(port), "--rrd-rate", "50"]) == 0
        settle(saved)
    finally:
        stop(server)
    received, expected = read_rrd(saved), read_rrd(written)
    assert received["meta"]["rate"] == expected["meta"]["rate"] == 50
    np.testing.assert_array_equal(received["times"], expected["times"])
    assert received["transitions"][0]["time"] == expected["transitions"][0]["time"]
    assert received["modes"] == expected["modes"]
    for name, (_t, values) in expected["series"].items():
        np.testing.assert_array_equal(received["series"][name][1], values)


def test_connect_to_an_address_nobody_answers_is_refused_before_the_run(tmp_path, capsys):
    out = tmp_path / "x.rrd"
    port = free_port()
    assert main(["run", *SHORT, "--rrd", str(out), "--connect", str(port)]) == 2
    err = capsys.readouterr().err
    assert f"--connect {port}: no Rerun viewer answers at 127.0.0.1:{port}" in err
    assert not out.exists()


def test_spawn_without_a_display_is_refused(monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert main(["run", *SHORT, "--spawn"]) == 2
    assert "--spawn needs a display, and there is none here" in capsys.readouterr().err


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--rrd-rate", "10"], "--rrd-rate thins a recording: give --rrd FILE, --spawn or --connect"),
        (["--rrd", "x.rrd", "--rrd-rate", "0"], "--rrd-rate must be finite and > 0"),
        (["--rrd", "x.rrd", "--rrd-rate", "nan"], "--rrd-rate must be finite and > 0"),
    ],
)
def test_a_bad_rate_is_named(argv, message, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["run", *SHORT, *argv]) == 2
    assert message in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_spawn_and_connect_exclude_each_other(capsys):
    assert main(["run", *SHORT, "--spawn", "--connect", "9876"]) == 2
    assert "not allowed with argument" in capsys.readouterr().err


@pytest.mark.parametrize(
    "address, url",
    [
        ("9876", "rerun+http://127.0.0.1:9876/proxy"),
        ("viewer.local:9000", "rerun+http://viewer.local:9000/proxy"),
        ("rerun+https://viewer.local:443/proxy", "rerun+https://viewer.local:443/proxy"),
    ],
)
def test_viewer_addresses(address, url):
    assert viewer_url(address) == url


@pytest.mark.parametrize("address", ["http://host:9876/proxy", "host:99999", "rerun+http://host:9876/other", ":"])
def test_a_bad_viewer_address_is_named(address):
    with pytest.raises(LegsimError, match=r"--connect .*: not a Rerun viewer address"):
        viewer_url(address)


def run_connect(port: int, *argv: str, timeout: float = 60) -> tuple[subprocess.CompletedProcess, float]:
    """``legsim run`` of the short ball with ``--connect PORT`` in a new process (a hang must end
    this test, not the test run), and the seconds it took."""
    began = time.monotonic()
    done = subprocess.run(
        [sys.executable, "-m", "legsim.cli", "run", *SHORT, "--connect", str(port), *argv],
        capture_output=True,
        text=True,
        timeout=timeout,
    )
    return done, time.monotonic() - began


def test_connect_to_a_peer_that_accepts_and_never_answers_ends_at_the_deadline(tmp_path):
    # It waited forever (Rerun's client flushes without a deadline), ignoring SIGTERM.
    with silent_peer() as peer:
        done, seconds = run_connect(peer.port, "--connect-timeout", "1", "--rrd", str(tmp_path / "x.rrd"))
    assert done.returncode == 2 and seconds < 10
    assert done.stderr == (
        f"legsim: error: --connect {peer.port}: 127.0.0.1:{peer.port} accepted the connection but did not answer "
        f"within 1 s (--connect-timeout); is a Rerun viewer running there?\n"
    )
    assert not (tmp_path / "x.rrd").exists()  # refused before the run


def test_connect_to_a_viewer_that_answers_and_then_stalls_ends_at_the_deadline():
    with silent_peer(first=HTTP2_SETTINGS) as peer:
        done, seconds = run_connect(peer.port, "--connect-timeout", "1")
        time.sleep(0.3)
        # The probe's connection, and the killed sender's (Rerun's client may have opened more).
        assert peer.accepted >= 2 and peer.closed == peer.accepted
    assert done.returncode == 2 and seconds < 10
    assert done.stderr == (
        f"legsim: error: --connect {peer.port}: the viewer at 127.0.0.1:{peer.port} did not take the recording "
        f"within 1 s (--connect-timeout); is it still running?\n"
    )


def test_a_closed_viewer_port_is_refused_at_once():
    done, seconds = run_connect(closed_port())
    assert done.returncode == 2 and "(Connection refused)" in done.stderr and seconds < 10


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_ends_a_live_recording_within_2_s(tmp_path, sig):
    with silent_peer(first=HTTP2_SETTINGS) as peer:
        proc = subprocess.Popen(
            [sys.executable, "-m", "legsim.cli", "run", *SHORT, "--connect", str(peer.port), "--connect-timeout", "60"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env={**os.environ, "TMPDIR": str(tmp_path)},
        )
        deadline = time.monotonic() + 60
        # The second connection is the check just before the recording is made and sent (the first,
        # before the run): the signal lands while the recording is made, its folder made, or sent.
        while peer.accepted < 2 and time.monotonic() < deadline:
            time.sleep(0.02)
        sent = time.monotonic()
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=30)
        elapsed = time.monotonic() - sent
        time.sleep(0.3)
        assert peer.closed == peer.accepted  # the sending process was killed with its command
    assert proc.returncode == (143 if sig == signal.SIGTERM else 130) and elapsed < 2.0
    assert err == ("legsim: terminated\n" if sig == signal.SIGTERM else "legsim: interrupted\n")
    left = sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*"))
    assert left == [], f"the temporary recording is not gone: {left}"  # named: a rare failure to diagnose


def test_connect_timeout_is_checked_and_needs_connect(capsys):
    assert main(["run", *SHORT, "--connect-timeout", "0", "--connect", "9"]) == 2
    assert "--connect-timeout must be finite and > 0" in capsys.readouterr().err
    assert main(["run", *SHORT, "--connect-timeout", "3"]) == 2
    assert "--connect-timeout bounds the waits of --connect: give --connect ADDRESS" in capsys.readouterr().err
