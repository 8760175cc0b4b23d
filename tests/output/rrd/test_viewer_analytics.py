"""legsim never turns on a third party's telemetry: a Rerun viewer it starts (``--spawn``) on a
machine where Rerun has no analytics setting yet starts with Rerun's analytics off (its
documented opt-out, ``rerun analytics disable``), and a setting the user made is left alone."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from helpers.rerun_server import free_port, stop, wait_for
from legsim.errors import LegsimError
from legsim.output.rrd import live


@pytest.fixture
def fresh_rerun(tmp_path, monkeypatch):
    """Rerun's folders, empty: a machine where Rerun never ran. Returns the setting's path."""
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "config"))
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "data"))
    monkeypatch.delenv(live.FORCE_ANALYTICS, raising=False)
    setting = live.rerun_analytics_setting()
    assert setting == tmp_path / "config" / "rerun" / "analytics.json" and not setting.exists()
    return setting


def _no_command(*args, **kwargs):
    raise AssertionError(f"no command should run here: {args}")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="Rerun's folders are XDG ones on Linux")
def test_without_a_rerun_setting_the_opt_out_is_run_and_said(fresh_rerun, capsys):
    live.viewer_analytics_off()
    assert json.loads(fresh_rerun.read_text())["analytics_enabled"] is False
    err = capsys.readouterr().err
    assert "turned its usage analytics off with `rerun analytics disable`" in err and str(fresh_rerun) in err
    live.viewer_analytics_off()  # a setting exists now: nothing more is run or said
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("enabled", [True, False])
def test_a_setting_the_user_made_is_left_alone(fresh_rerun, monkeypatch, capsys, enabled):
    fresh_rerun.parent.mkdir(parents=True)
    text = json.dumps({"analytics_enabled": enabled, "analytics_id": "user", "metadata": {}})
    fresh_rerun.write_text(text)
    monkeypatch.setattr(live.subprocess, "run", _no_command)
    live.viewer_analytics_off()
    assert fresh_rerun.read_text() == text and capsys.readouterr().err == ""


@pytest.mark.parametrize("value, runs", [("1", False), ("yes", False), ("0", True), ("maybe", True)])
def test_force_rerun_analytics_is_the_users_switch(fresh_rerun, monkeypatch, value, runs):
    # Set to a value Rerun reads as true, the user turned analytics on: legsim writes nothing.
    monkeypatch.setenv(live.FORCE_ANALYTICS, value)
    ran = []
    monkeypatch.setattr(live.subprocess, "run", lambda *a, **k: ran.append(a) or _disabled(fresh_rerun))
    live.viewer_analytics_off()
    assert bool(ran) is runs


def _disabled(setting):
    setting.parent.mkdir(parents=True, exist_ok=True)
    setting.write_text('{"analytics_enabled": false}')
    return subprocess.CompletedProcess([], 0, "", "")


def test_a_failed_opt_out_starts_no_viewer(fresh_rerun, monkeypatch, tmp_path):
    monkeypatch.setattr(live.subprocess, "run", lambda *a, **k: subprocess.CompletedProcess([], 1, "", "no luck"))
    monkeypatch.setattr(live.subprocess, "Popen", _no_command)
    with pytest.raises(LegsimError, match=r"`rerun analytics disable` failed \(exit code 1: no luck\)"):
        live.open_in_viewer(tmp_path / "x.rrd")


def test_opening_a_recording_turns_analytics_off_before_the_viewer_starts(fresh_rerun, monkeypatch, tmp_path):
    started = []
    monkeypatch.setattr(live.subprocess, "run", lambda *a, **k: _disabled(fresh_rerun))
    monkeypatch.setattr(live.subprocess, "Popen", lambda argv, **kw: started.append((argv, fresh_rerun.exists())))
    live.open_in_viewer(tmp_path / "x.rrd")
    assert started == [([sys.executable, "-m", "rerun_cli", str(tmp_path / "x.rrd")], True)]


def test_recording_and_streaming_leave_the_users_home_alone(tmp_path):
    # legsim's own side (rerun-sdk in this process) writes no analytics setting or event: a run
    # recorded to a file and sent to a running server, from an empty home without XDG folders.
    port, home = free_port(), tmp_path / "home"
    home.mkdir()
    server = subprocess.Popen(
        [sys.executable, "-m", "rerun_cli", "--save", str(tmp_path / "received.rrd"), "--port", str(port)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    env = {k: v for k, v in os.environ.items() if not k.startswith("XDG_") and k != "MPLCONFIGDIR"}
    run = ["run", "bouncing_ball", "--set", "integrator.t_final=0.5", "--quiet", "--rrd", str(tmp_path / "x.rrd")]
    try:
        wait_for(port, server)
        result = subprocess.run(
            [sys.executable, "-m", "legsim", *run, "--connect", str(port)],
            env={**env, "HOME": str(home)},
            capture_output=True,
            text=True,
            timeout=300,
        )
    finally:
        stop(server)
    assert result.returncode == 0, result.stderr
    assert list(home.rglob("*")) == []
