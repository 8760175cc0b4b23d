"""``legsim replay``: prints what was recorded (the run's summary keys, transitions, mode
sequence), names a bad file, and says when --spawn has no display."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import pytest

from helpers.recordings import recorded_hopper
from legsim.output.summary import run_summary
from legsim.output.trace import RecordingError


@pytest.fixture(scope="module")
def hopper_run(tmp_path_factory):
    return recorded_hopper(tmp_path_factory.mktemp("rrd"))


def _replay(path, **kw):
    from legsim.commands import replay

    parser = argparse.ArgumentParser()
    replay.add_arguments(parser)
    argv = [str(path)]
    for key, value in kw.items():
        argv += [f"--{key}"] if value is True else [f"--{key}", str(value)]
    return replay.run(parser.parse_args(argv))


def test_replay_json_has_the_run_keys(hopper_run, capsys):
    model, ex, path, _ = hopper_run
    assert _replay(path, json=True) == 0
    got = json.loads(capsys.readouterr().out)
    want = run_summary(ex, None, model)
    assert {k: v for k, v in got.items() if k != "outputs"} == json.loads(json.dumps(want))
    assert got["outputs"] == {}


def test_replay_text_lists_modes_transitions_and_final_state(hopper_run, capsys):
    _, ex, path, _ = hopper_run
    assert _replay(path) == 0
    out = capsys.readouterr().out
    tr = ex.transitions[0]
    assert f"t = {tr.time:.9g} s  touchdown: flight -> stance" in out
    assert f"mode sequence ({len(ex.segments)} segments): flight -> stance -> flight" in out
    final = ", ".join(f"{n} = {v:.6g}" for n, v in zip(ex.state_names[ex.final_mode], ex.final_state, strict=True))
    assert final in out


def test_replay_spawn_without_display_says_so(hopper_run, monkeypatch, capsys):
    from legsim.errors import LegsimError

    _, _, path, _ = hopper_run
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(LegsimError, match="--spawn needs a display, and there is none here"):
        _replay(path, spawn=True)


def test_replay_of_a_bad_file_names_it(tmp_path):
    bad = tmp_path / "bad.rrd"
    bad.write_text("no")
    with pytest.raises(RecordingError, match=r"bad\.rrd"):
        _replay(bad)


def test_replay_through_the_cli(hopper_run, capsys):
    from legsim import cli

    _, ex, path, _ = hopper_run
    assert cli.main(["replay", str(path), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["mode_sequence"] == ex.mode_sequence
    assert cli.main(["replay", str(Path(path).with_name("missing.rrd"))]) == 2
    assert "missing.rrd: no such recording file" in capsys.readouterr().err


def test_replay_never_writes_over_the_recording_it_reads(hopper_run, tmp_path):
    from legsim.errors import OutputError

    _, _, path, _ = hopper_run
    # A copy named like a page: only its identity with the input refuses it.
    page = tmp_path / "hopper.html"
    page.write_bytes(Path(path).read_bytes())
    before = page.read_bytes()
    with pytest.raises(OutputError, match=rf"^--html {page}: is an input of this run"):
        _replay(page, html=page)
    assert page.read_bytes() == before and sorted(p.name for p in tmp_path.iterdir()) == ["hopper.html"]


def test_replay_writes_its_outputs_through_temporary_files(hopper_run, tmp_path, capsys):
    _, _, path, _data = hopper_run
    assert _replay(path, plot=tmp_path / "p.png", html=tmp_path / "p.html") == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.html", "p.png"]
    assert (tmp_path / "p.png").read_bytes()[:4] == b"\x89PNG" and "<html" in (tmp_path / "p.html").read_text()
    assert f"wrote {tmp_path / 'p.png'} (plot)" in capsys.readouterr().out
