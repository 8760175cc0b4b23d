"""The writer streams a run to its recording a chunk of samples at a time: the chunks hold
exactly the samples of the whole trace thinned at once, the recording is the same whatever the
chunk size, and the writer's Python memory does not grow with the run's length."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import legsim.output.rrd.write as writer
from helpers.recordings import run_hopper
from legsim.output.rrd import read_rrd, write_rrd
from legsim.output.rrd.stream import chunks, kept_samples
from legsim.output.trace import execution_trace

TESTS = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("rate", [None, 40.0, 3.0])
@pytest.mark.parametrize("size", [1, 7, 100000])
def test_chunks_hold_the_samples_of_the_whole_trace_thinned_at_once(rate, size):
    # The hopper changes dimension between modes, so the chunks cut across blocks of either width.
    _, ex = run_hopper()
    trace = execution_trace(ex)
    keep = kept_samples(trace, rate)
    pieces = list(chunks(ex, rate, size))
    assert all(len(c.times) == size for c in pieces[:-1]) and 0 < len(pieces[-1].times) <= size
    assert [c.first for c in pieces] == list(np.cumsum([0] + [len(c.times) for c in pieces[:-1]]))
    np.testing.assert_array_equal(np.concatenate([c.times for c in pieces]), trace.times[keep])
    renumber = np.full(len(trace.times), -1)
    renumber[keep] = np.arange(len(keep))
    for name in ("segment_starts", "strip_samples"):
        got = np.concatenate([getattr(c, name) for c in pieces])
        np.testing.assert_array_equal(got, renumber[getattr(trace, name)], err_msg=name)
    for mode, (rows, states) in trace.blocks.items():
        kept = renumber[rows] >= 0
        got_rows = np.concatenate([c.blocks[mode][0] for c in pieces if mode in c.blocks])
        got_states = np.concatenate([c.blocks[mode][1] for c in pieces if mode in c.blocks])
        np.testing.assert_array_equal(got_rows, renumber[rows][kept])
        np.testing.assert_array_equal(got_states, states[kept])


def _same_recording(a: dict, b: dict) -> None:
    for key in ("times", "in_strip"):
        np.testing.assert_array_equal(a[key], b[key])
    for key in ("modes", "mode_sequence", "segments", "strips", "summary"):
        assert a[key] == b[key], key
    assert a["series"].keys() == b["series"].keys()
    for name in a["series"]:
        np.testing.assert_array_equal(a["series"][name][1], b["series"][name][1])
        np.testing.assert_array_equal(a["series_rows"][name], b["series_rows"][name])
    assert len(a["transitions"]) == len(b["transitions"])
    for ta, tb in zip(a["transitions"], b["transitions"], strict=True):
        assert {k: v for k, v in ta.items() if "state" not in k} == {k: v for k, v in tb.items() if "state" not in k}
    np.testing.assert_array_equal(a["frame_rows"], b["frame_rows"])
    for part, lines in a["frames"].parts.items():
        for la, lb in zip(lines, b["frames"].parts[part], strict=True):
            np.testing.assert_array_equal(la, lb)


@pytest.mark.parametrize("rate", [None, 40.0])
def test_the_recording_is_the_same_in_small_chunks_as_in_one(rate, tmp_path, monkeypatch):
    model, ex = run_hopper()
    monkeypatch.setattr(writer, "CHUNK", 10**9)
    whole = read_rrd(write_rrd(ex, None, tmp_path / "one.rrd", model=model, rate=rate))
    monkeypatch.setattr(writer, "CHUNK", 5)
    chunked = read_rrd(write_rrd(ex, None, tmp_path / "many.rrd", model=model, rate=rate))
    assert len(whole["times"]) > 10 * 5  # many chunks
    _same_recording(whole, chunked)


# Every chunk holds 512 samples, so its transient (its columns; with the robot, the samples'
# drawn parts, some 1.6 MB) is the same in a short and a long run to some 0.03 MB. A writer
# holding any array over the whole run grows by at least 8 bytes per number: the time, row and
# two state values alone of the 38 000 (states only) or 14 000 (with the robot) more samples
# are 1.2 MB and 0.45 MB; the writer that held the whole trace grew by 4.9 MB and 7 MB here.
@pytest.mark.parametrize(("drawn", "h_long", "bound"), [(False, 5e-5, 0.1e6), (True, 1.25e-4, 0.2e6)])
def test_the_writers_memory_does_not_grow_with_the_run(drawn, h_long, bound, tmp_path):
    what = "drawn" if drawn else "states"
    command = [sys.executable, "-m", "helpers.writer_memory", what, str(h_long), str(tmp_path)]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(TESTS), os.environ.get("PYTHONPATH", "")])}
    out = subprocess.run(command, capture_output=True, text=True, env=env, timeout=300)
    assert out.returncode == 0, out.stderr
    (_, _), (short, short_peak), (long, long_peak) = json.loads(out.stdout)
    assert long >= 7.5 * short > 7.5 * 3 * 512
    assert long_peak - short_peak < bound, (short_peak, long_peak)
