"""Rerun recordings: a recorded file reproduces the execution it came from; writes are atomic;
bad files are rejected with the file named; ``legsim replay`` prints what was recorded.

"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

import numpy as np
import pytest

from legsim.builders import Model
from legsim.hybrid import HybridSystem, Mode, Transition
from legsim.record import RecordingError, execution_trace, frame_times, read_rrd, run_summary, write_rrd
from legsim.relaxed import simulate

from helpers.models import ball_model, hopper_model

def run_hopper(t_final: float = 1.5, eps: float = 2e-3):
    model = hopper_model()
    ex = simulate(model.system, np.array([0.5, 0.0]), "flight", t_final, 1e-3, eps)
    return model, ex


@pytest.fixture(scope="module")
def hopper_run(tmp_path_factory):
    model, ex = run_hopper()
    assert ex.status == "finished" and len(ex.transitions) >= 4  # the test needs several hops
    path = tmp_path_factory.mktemp("rrd") / "hopper.rrd"
    write_rrd(ex, None, path, model=model)
    return model, ex, path, read_rrd(path)


def expected_series(ex) -> dict[str, list[tuple[float, float]]]:
    """Per coordinate, the (time, value) pairs an execution holds, built from its segments
    and strips directly (not through legsim.record): every computed segment point, and each
    strip's held point q at its entry and at its exit."""
    out: dict[str, list[tuple[float, float]]] = {}
    for seg in ex.segments:
        for col, name in enumerate(ex.state_names[seg.mode]):
            out.setdefault(name, []).extend(zip(seg.t.tolist(), seg.x[:, col].tolist()))
    for strip in ex.strips:
        for col, name in enumerate(ex.state_names[strip.mode]):
            out.setdefault(name, []).extend([(strip.time, strip.state[col]), (strip.exit_time, strip.state[col])])
    return out


def test_every_coordinate_sample_round_trips_exactly(hopper_run):
    _, ex, _, data = hopper_run
    expected = expected_series(ex)
    assert set(data["series"]) == set(expected) == {"z", "zd", "n"}
    for name, pairs in expected.items():
        t, v = data["series"][name]
        # Samples at one instant (a segment's last point and its strip's entry) may come in
        # either order, so compare sorted (time, value) pairs; float64 is stored, so exactly.
        assert sorted(zip(t.tolist(), v.tolist())) == sorted(pairs), name
    # n exists in stance only: its samples are exactly the stance samples.
    stance_points = sum(len(s.t) for s in ex.segments if s.mode == "stance") + \
        2 * sum(1 for s in ex.strips if s.mode == "stance")
    assert len(data["series"]["n"][0]) == stance_points


def test_sample_times_modes_and_strip_flags(hopper_run):
    _, ex, _, data = hopper_run
    assert np.all(np.diff(data["times"]) >= 0)
    assert data["times"][0] == ex.t0 and data["times"][-1] == ex.t_end
    # Every sample lies in the piece its mode and strip flag say: check against sampling.
    inside = ~data["in_strip"]
    for t, mode in zip(data["times"][inside][::50], np.array(data["modes"], dtype=object)[inside][::50]):
        assert any(s.mode == mode and s.t_start <= t <= s.t_end for s in ex.segments)
    assert int(data["in_strip"].sum()) == 2 * len(ex.strips)


def test_mode_sequence_strips_and_transitions_round_trip(hopper_run):
    _, ex, _, data = hopper_run
    assert data["mode_sequence"] == ex.mode_sequence
    assert data["segments"] == [(s.mode, s.t_start, s.t_end) for s in ex.segments]
    assert [(s["mode"], s["name"], s["time"], s["exit_time"]) for s in data["strips"]] == \
        [(s.mode, s.name, s.time, s.exit_time) for s in ex.strips]
    assert len(data["transitions"]) == len(ex.transitions)
    for got, tr in zip(data["transitions"], ex.transitions):
        assert (got["name"], got["source"], got["target"], got["index"]) == (tr.name, tr.source, tr.target, tr.index)
        assert (got["time"], got["landing_time"], got["exit_time"], got["depth"]) == \
            (tr.time, tr.landing_time, tr.exit_time, tr.depth)
        np.testing.assert_array_equal(got["state_before"], tr.state_before)
        np.testing.assert_array_equal(got["state_after"], tr.state_after)
    # The edges alternate flight -> stance -> flight, as the model allows.
    assert [(t["source"], t["target"]) for t in data["transitions"][:2]] == [("flight", "stance"), ("stance", "flight")]


def test_summary_round_trips_with_energies(hopper_run):
    model, ex, _, data = hopper_run
    s = data["summary"]
    base = ex.summary()
    for key, value in base.items():
        assert s[key] == value, key
    e = model.system.energy
    assert s["energy_initial"] == pytest.approx(e("flight", np.array([0.5, 0.0])), rel=1e-15)
    assert s["energy_final"] == pytest.approx(e(ex.final_mode, ex.final_state), rel=1e-15)
    # Lift-off with c = 0.9 loses energy: the recorded energies say so.
    assert s["energy_final"] < s["energy_initial"]
    assert s == json.loads(json.dumps(run_summary(ex, None, model)))


def test_geometry_frames_match_the_model(hopper_run):
    model, ex, _, data = hopper_run
    frames = data["frames"]
    np.testing.assert_array_equal(frames.times, frame_times(ex))
    # Each transition's strip entry and exit is a frame, so the viewer shows every contact.
    for s in ex.strips:
        assert s.time in frames.times and s.exit_time in frames.times
    samples = ex.sample(frames.times)
    assert frames.modes == samples.modes
    for i in range(0, len(frames), 37):
        want = model.geometry(samples.modes[i], samples.states[i])
        for part, line in want.items():
            # Rerun stores line strips as float32: compare to that precision.
            np.testing.assert_allclose(frames.parts[part][i], line, rtol=0, atol=1e-6 * (1 + np.abs(line).max()))
    np.testing.assert_array_equal(data["scenery"]["ground"], model.scenery["ground"])
    assert data["meta"]["point_parts"] == ["foot"]
    assert all(line.shape == (1, 2) for line in frames.parts["foot"])


def test_frame_times_are_capped():
    _, ex = run_hopper(t_final=1.0)
    times = frame_times(ex, fps=1000.0, max_frames=100)
    assert len(times) <= 100 and times[0] == ex.t0 and times[-1] == ex.t_end
    assert np.all(np.diff(times) > 0)


def test_model_without_geometry_records_states_only(tmp_path):
    model = ball_model()
    ex = simulate(model.system, np.array([1.0, 0.0]), "flight", 1.2, 1e-3, 1e-3)
    path = write_rrd(ex, None, tmp_path / "ball.rrd", model=model)
    data = read_rrd(path)
    assert data["frames"] is None and data["scenery"] == {}
    assert data["mode_sequence"] == ex.mode_sequence
    assert "energy_initial" not in data["summary"]  # the ball defines no energy
    t, z = data["series"]["z"]
    trace = execution_trace(ex)
    np.testing.assert_array_equal(t, trace.times)


def test_strip_cut_by_max_transitions_is_recorded(tmp_path):
    model = ball_model(c=0.5)
    ex = simulate(model.system, np.array([1.0, 0.0]), "flight", 5.0, 1e-3, 1e-3, max_transitions=3)
    assert ex.status == "max_transitions" and len(ex.strips) == len(ex.transitions) + 1
    data = read_rrd(write_rrd(ex, None, tmp_path / "cut.rrd", model=model))
    assert len(data["strips"]) == 4 and len(data["transitions"]) == 3
    assert data["summary"]["status"] == "max_transitions"
    assert data["summary"]["final_in_strip"] is True


# -- atomicity ----------------------------------------------------------------------------------
def _broken_geometry(model: Model, after: float) -> Model:
    def geometry(mode, x):
        if x[0] < after:
            raise ValueError("boom")
        return model.geometry(mode, x)

    return Model(model.system, model.initial_mode, model.initial_state, geometry=geometry, scenery=model.scenery)


def test_failing_write_leaves_no_file(tmp_path):
    model, ex = run_hopper(t_final=0.8)
    out = tmp_path / "out"
    with pytest.raises(Exception, match="geometry failed in mode"):
        write_rrd(ex, None, out / "x.rrd", model=_broken_geometry(model, 0.1))
    assert not (out / "x.rrd").exists()
    assert list(out.iterdir()) == [] if out.exists() else True


def test_failing_write_keeps_the_previous_file(tmp_path):
    model, ex = run_hopper(t_final=0.8)
    path = write_rrd(ex, None, tmp_path / "x.rrd", model=model)
    before = path.read_bytes()
    with pytest.raises(Exception, match="geometry failed"):
        write_rrd(ex, None, path, model=_broken_geometry(model, 0.1))
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.rrd"]  # no temporary left behind


def test_interrupted_write_removes_the_temporary(tmp_path, monkeypatch):
    model, ex = run_hopper(t_final=0.5)

    def fail(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", fail)
    with pytest.raises(RecordingError, match=r"x\.rrd: cannot write the recording: disk full"):
        write_rrd(ex, None, tmp_path / "x.rrd", model=model)
    assert list(tmp_path.iterdir()) == []


def test_written_file_has_ordinary_permissions(tmp_path):
    model, ex = run_hopper(t_final=0.3)
    path = write_rrd(ex, None, tmp_path / "x.rrd", model=model)
    umask = os.umask(0)
    os.umask(umask)
    assert path.stat().st_mode & 0o777 == 0o666 & ~umask


# -- bad input ----------------------------------------------------------------------------------
def test_missing_file_is_named(tmp_path):
    with pytest.raises(RecordingError, match=r"nope\.rrd: no such recording file"):
        read_rrd(tmp_path / "nope.rrd")


def test_garbage_file_is_named(tmp_path):
    bad = tmp_path / "bad.rrd"
    bad.write_bytes(b"this is not a recording")
    with pytest.raises(RecordingError, match=r"bad\.rrd: not a readable Rerun recording"):
        read_rrd(bad)


def test_truncated_recording_is_named(hopper_run, tmp_path):
    _, _, path, _ = hopper_run
    cut = tmp_path / "cut.rrd"
    cut.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    with pytest.raises(RecordingError, match=r"cut\.rrd: (not a readable Rerun recording|incomplete)"):
        read_rrd(cut)


def test_foreign_rerun_file_is_named(tmp_path):
    import uuid

    import rerun as rr

    rec = rr.RecordingStream("someone-else", recording_id=uuid.uuid4())
    memory = rec.memory_recording()
    rec.log("points", rr.Points3D([[0, 0, 0]]))
    rec.flush()
    foreign = tmp_path / "foreign.rrd"
    foreign.write_bytes(memory.drain_as_bytes())
    with pytest.raises(RecordingError, match=r"foreign\.rrd: a Rerun recording without legsim data"):
        read_rrd(foreign)


def test_write_needs_an_execution_and_a_path(tmp_path):
    with pytest.raises(RecordingError, match="needs a legsim Execution"):
        write_rrd({"not": "an execution"}, None, tmp_path / "x.rrd")
    _, ex = run_hopper(t_final=0.2)
    with pytest.raises(RecordingError, match="needs a path"):
        write_rrd(ex, None)


def test_core_import_does_not_import_rerun():
    import subprocess
    import sys

    code = "import sys, legsim, legsim.record, legsim.commands.replay; print('rerun' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


# -- legsim replay ------------------------------------------------------------------------------
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
    final = ", ".join(f"{n} = {v:.6g}" for n, v in zip(ex.state_names[ex.final_mode], ex.final_state))
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
    cli = pytest.importorskip("legsim.cli")
    _, ex, path, _ = hopper_run
    assert cli.main(["replay", str(path), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["mode_sequence"] == ex.mode_sequence
    assert cli.main(["replay", str(Path(path).with_name("missing.rrd"))]) == 2
    assert "missing.rrd: no such recording file" in capsys.readouterr().err
