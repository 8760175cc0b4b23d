"""Thinned recordings (``write_rrd(rate=...)``, ``legsim run --rrd-rate``): a long run fits in a
small file, at most ``rate`` samples per simulated second are kept besides each piece's ends,
and every transition's states before and after its reset are recorded exactly."""

from __future__ import annotations

import numpy as np
import pytest

from legsim.cli import main
from legsim.output.rrd import read_rrd
from legsim.output.rrd.stream import kept_samples
from legsim.output.trace import execution_trace
from legsim.scene import load_scene

#: Example 1 of the oscillator (paper 000) at h = 1e-4 s over 10 s: 1e5 steps, 4 impacts.
LONG_RUN = ["integrator.h=1e-4", "integrator.t_final=10.0"]
RATE = 100.0


@pytest.fixture(scope="module")
def long_run(tmp_path_factory):
    """(execution, path, read_rrd(path)) of the long run recorded by `legsim run --rrd-rate`."""
    path = tmp_path_factory.mktemp("rrd") / "ex1.rrd"
    sets = [arg for item in LONG_RUN for arg in ("--set", item)]
    assert main(["run", "oscillator_ex1", *sets, "--rrd", str(path), "--rrd-rate", str(RATE), "--quiet"]) == 0
    # The run is deterministic: the same scene simulated here is the execution recorded.
    ex = load_scene("oscillator_ex1", overrides=LONG_RUN).simulate()
    return ex, path, read_rrd(path)


def test_a_run_of_1e5_samples_at_100_hz_is_under_5_mb(long_run):
    ex, path, data = long_run
    assert len(execution_trace(ex).times) >= 100_000
    assert path.stat().st_size < 5e6
    assert data["meta"]["rate"] == RATE and data["meta"]["computed_samples"] >= 100_000


def test_at_most_rate_samples_per_second_besides_each_piece_ends(long_run):
    ex, _, data = long_run
    times = data["times"]
    pieces = len(ex.segments) + len(ex.strips)
    assert len(times) <= np.floor(RATE * (times[-1] - times[0])) + 1 + 2 * pieces
    # Between the kept ends of the pieces, no two samples share a 1/rate s interval.
    bins = np.floor((times - times[0]) * RATE)
    assert np.count_nonzero(np.diff(bins) == 0) <= 2 * pieces


def test_every_transition_and_its_states_are_kept(long_run):
    ex, _, data = long_run
    assert len(ex.transitions) >= 3
    recorded = data["transitions"]
    assert [t["time"] for t in recorded] == [t.time for t in ex.transitions]
    names = ex.state_names[ex.segments[0].mode]
    for tr, rec in zip(ex.transitions, recorded, strict=False):
        np.testing.assert_array_equal(rec["state_before"], tr.state_before)
        np.testing.assert_array_equal(rec["state_after"], tr.state_after)
        # The state after the reset is the first sample of the next segment, at the strip's exit.
        first_after = _state_at_first_sample(data, names, tr.exit_time, after_strip=True)
        np.testing.assert_array_equal(first_after, tr.state_after)
    for strip in ex.strips:
        np.testing.assert_array_equal(_state_at_first_sample(data, names, strip.time, after_strip=False), strip.state)


def _state_at_first_sample(data, names, time, after_strip):
    """The recorded state at the first sample at ``time`` (inside a strip, or the first after it)."""
    rows = np.flatnonzero((data["times"] == time) & (data["in_strip"] != after_strip))
    assert len(rows), f"no recorded sample at t = {time}"
    row = rows[0]
    values = []
    for name in names:
        at = np.flatnonzero(data["series_rows"][name] == row)
        values.append(data["series"][name][1][at[0]])
    return np.array(values)


def test_without_a_rate_every_sample_is_kept():
    ex = load_scene("bouncing_ball", overrides=["integrator.t_final=1.0"]).simulate()
    trace = execution_trace(ex)
    np.testing.assert_array_equal(kept_samples(trace, None), np.arange(len(trace.times)))
    # A rate above the samples' own density keeps them all too.
    np.testing.assert_array_equal(kept_samples(trace, 1e9), np.arange(len(trace.times)))
