"""The samples and frames of a run, before any renderer: the trace holds every computed point
and each strip's held state twice; frame times are capped."""

from __future__ import annotations

import numpy as np

from helpers.recordings import run_hopper
from legsim.output.trace import frame_times


def test_frame_times_are_capped():
    _, ex = run_hopper(t_final=1.0)
    times = frame_times(ex, fps=1000.0, max_frames=100)
    assert len(times) <= 100 and times[0] == ex.t0 and times[-1] == ex.t_end
    assert np.all(np.diff(times) > 0)


def test_trace_holds_every_segment_point_and_each_strip_twice():
    from helpers.recordings import expected_series
    from legsim.output.trace import execution_trace, trace_series

    _, ex = run_hopper()
    trace = execution_trace(ex)
    assert np.all(np.diff(trace.times) >= 0)
    assert int(trace.in_strip.sum()) == 2 * len(ex.strips)
    assert len(trace.segment_starts) == len(ex.segments) and len(trace.strip_samples) == len(ex.strips)
    assert [trace.modes[i] for i in trace.segment_starts] == ex.mode_sequence
    for name, pairs in expected_series(ex).items():
        rows, values = trace_series(ex, trace)[name]
        assert sorted(zip(trace.times[rows].tolist(), values.tolist(), strict=True)) == sorted(pairs), name
