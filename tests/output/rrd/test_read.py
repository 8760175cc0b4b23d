"""Reading recordings back: a recorded file reproduces the execution it came from (every
sample, the mode sequence, strips, transitions and geometry frames); bad files are rejected
with the file named."""

from __future__ import annotations

import os

import numpy as np
import pytest

from helpers.models import ball_model
from helpers.recordings import expected_series
from legsim.output.rrd import read_rrd, write_rrd
from legsim.output.trace import RecordingError, execution_trace, frame_times
from legsim.relaxed import simulate


def test_every_coordinate_sample_round_trips_exactly(hopper_run):
    _, ex, _, data = hopper_run
    expected = expected_series(ex)
    assert set(data["series"]) == set(expected) == {"z", "zd", "n"}
    for name, pairs in expected.items():
        t, v = data["series"][name]
        # Samples at one instant (a segment's last point and its strip's entry) may come in
        # either order, so compare sorted (time, value) pairs; float64 is stored, so exactly.
        assert sorted(zip(t.tolist(), v.tolist(), strict=False)) == sorted(pairs), name
    # n exists in stance only: its samples are exactly the stance samples.
    stance_points = sum(len(s.t) for s in ex.segments if s.mode == "stance") + 2 * sum(
        1 for s in ex.strips if s.mode == "stance"
    )
    assert len(data["series"]["n"][0]) == stance_points


def test_sample_times_modes_and_strip_flags(hopper_run):
    _, ex, _, data = hopper_run
    assert np.all(np.diff(data["times"]) >= 0)
    assert data["times"][0] == ex.t0 and data["times"][-1] == ex.t_end
    # Every sample lies in the piece its mode and strip flag say: check against sampling.
    inside = ~data["in_strip"]
    for t, mode in zip(data["times"][inside][::50], np.array(data["modes"], dtype=object)[inside][::50], strict=False):
        assert any(s.mode == mode and s.t_start <= t <= s.t_end for s in ex.segments)
    assert int(data["in_strip"].sum()) == 2 * len(ex.strips)


def test_mode_sequence_strips_and_transitions_round_trip(hopper_run):
    _, ex, _, data = hopper_run
    assert data["mode_sequence"] == ex.mode_sequence
    assert data["segments"] == [(s.mode, s.t_start, s.t_end) for s in ex.segments]
    assert [(s["mode"], s["name"], s["time"], s["exit_time"]) for s in data["strips"]] == [
        (s.mode, s.name, s.time, s.exit_time) for s in ex.strips
    ]
    assert len(data["transitions"]) == len(ex.transitions)
    for got, tr in zip(data["transitions"], ex.transitions, strict=False):
        assert (got["name"], got["source"], got["target"], got["index"]) == (tr.name, tr.source, tr.target, tr.index)
        assert (got["time"], got["landing_time"], got["exit_time"], got["depth"]) == (
            tr.time,
            tr.landing_time,
            tr.exit_time,
            tr.depth,
        )
        np.testing.assert_array_equal(got["state_before"], tr.state_before)
        np.testing.assert_array_equal(got["state_after"], tr.state_after)
    # The edges alternate flight -> stance -> flight, as the model allows.
    assert [(t["source"], t["target"]) for t in data["transitions"][:2]] == [("flight", "stance"), ("stance", "flight")]


def test_geometry_frames_match_the_model(hopper_run):
    model, ex, _, data = hopper_run
    frames, rows = data["frames"], data["frame_rows"]
    # The frames are recorded samples, the last one at or before each time of frame_times's
    # grid (the hopper's step is 1 ms, the grid's 1/60 s).
    trace = execution_trace(ex)
    np.testing.assert_array_equal(frames.times, trace.times[rows])
    grid = frame_times(ex)
    assert len(frames) >= len(grid) - 1
    assert np.all(grid - frames.times[np.searchsorted(frames.times, grid, side="right") - 1] < 1e-3 + 1e-12)
    # Each transition's strip entry and exit is a frame, so the viewer shows every contact.
    for s in ex.strips:
        assert s.time in frames.times and s.exit_time in frames.times
    assert frames.modes == [trace.modes[r] for r in rows]
    state_of = {}
    for _mode, (mode_rows, states) in trace.blocks.items():
        state_of.update(zip(mode_rows.tolist(), states, strict=False))
    for i, row in enumerate(rows.tolist()):
        want = model.geometry(trace.modes[row], state_of[row])
        for part, line in want.items():
            # Rerun stores transforms and shapes as float32: compare to that precision.
            np.testing.assert_allclose(frames.parts[part][i], line, rtol=0, atol=1e-6 * (1 + np.abs(line).max()))
    np.testing.assert_array_equal(data["scenery"]["ground"], model.scenery["ground"])
    assert data["meta"]["point_parts"] == ["foot"]
    assert all(line.shape == (1, 2) for line in frames.parts["foot"])


def test_model_without_geometry_records_states_only(tmp_path):
    model = ball_model()
    ex = simulate(model.system, np.array([1.0, 0.0]), "flight", 1.2, 1e-3, 1e-3)
    path = write_rrd(ex, None, tmp_path / "ball.rrd", model=model)
    data = read_rrd(path)
    assert data["frames"] is None and data["scenery"] == {}
    assert data["mode_sequence"] == ex.mode_sequence
    assert "energy_initial" not in data["summary"]  # the ball defines no energy
    t, _z = data["series"]["z"]
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


# -- bad files ----------------------------------------------------------------------------------
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


def test_a_rerun_file_cut_short_is_named_as_such(tmp_path):
    """A copy taken while its writer still ran has no footer (and here no legsim data): the
    message says it was cut short, not that another program wrote it."""
    import shutil
    import uuid

    import rerun as rr

    writing, copy = tmp_path / "writing.rrd", tmp_path / "copy.rrd"
    rec = rr.RecordingStream("legsim", recording_id=uuid.uuid4())
    rec.save(writing)
    rec.log("points", rr.Points3D([[0, 0, 0]]))
    rec.flush()
    shutil.copy(writing, copy)
    rec.disconnect()
    with pytest.raises(RecordingError, match=r"copy\.rrd: a Rerun recording cut short \(it has no footer\)"):
        read_rrd(copy)
    with pytest.raises(RecordingError, match=r"writing\.rrd: a Rerun recording without legsim data"):
        read_rrd(writing)  # finished: its footer is there


def test_a_recording_of_the_earlier_layout_is_refused_by_name(tmp_path):
    import json
    import uuid

    import rerun as rr

    # The earlier layout's document, as legsim-rrd-1 wrote it (entity legsim/meta).
    rec = rr.RecordingStream("legsim", recording_id=uuid.uuid4())
    memory = rec.memory_recording()
    rec.log("legsim/meta", rr.TextDocument(json.dumps({"format": "legsim-rrd-1", "summary": {}})), static=True)
    rec.flush()
    old = tmp_path / "old.rrd"
    old.write_bytes(memory.drain_as_bytes())
    with pytest.raises(
        RecordingError,
        match=r"old\.rrd: a legsim recording of layout legsim-rrd-1, written by an "
        r"earlier legsim; this version reads layout legsim-rrd-2 only",
    ):
        read_rrd(old)


def test_a_folder_or_fifo_given_as_a_recording_is_named_as_such(tmp_path):
    folder = tmp_path / "d.rrd"
    folder.mkdir()
    with pytest.raises(RecordingError, match=r"d\.rrd: not a recording file \(it is a directory\)"):
        read_rrd(folder)
    fifo = tmp_path / "f.rrd"
    os.mkfifo(fifo)
    with pytest.raises(RecordingError, match=r"f\.rrd: not a recording file \(it is a FIFO\)"):
        read_rrd(fifo)
