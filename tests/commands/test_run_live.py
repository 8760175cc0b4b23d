"""``legsim run --spawn / --connect ADDRESS / --rrd-rate HZ``: the recording streamed to a
Rerun viewer is the one ``--rrd`` writes, and every bad use is refused before the run."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

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
