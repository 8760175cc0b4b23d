"""The samples of an execution a chunk at a time, thinned to a rate: what the writer records,
without ever holding all of them.

The samples are those of ``legsim.output.trace.execution_trace`` (every computed point of
every segment, each strip's held point at its entry and exit), numbered in order after the
thinning. ``chunks`` walks the execution's pieces and yields ``Chunk``s of ``size``
samples, so that what the writer holds beyond the execution's own arrays is one chunk, plus a
few numbers per piece (segment or strip).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np

from ...execution import Execution
from ..trace import Trace, _piece, _piece_states, _piece_times

#: Samples per chunk.
CHUNK = 4096


@dataclass
class Chunk:
    """Consecutive recorded samples ``first``, ``first + 1``, ...: their ``times`` (n,) s,
    ``mode_index`` (n,) into ``mode_names``, ``blocks`` mode -> (rows (m,), states (m, dim)) with
    the rows numbered in the whole recording, and the rows where the segments (``segment_starts``)
    and the strips (``strip_samples``) that start in this chunk start."""

    first: int
    times: np.ndarray
    mode_names: list[str]
    mode_index: np.ndarray
    blocks: dict[str, tuple[np.ndarray, np.ndarray]]
    segment_starts: np.ndarray
    strip_samples: np.ndarray

    @property
    def rows(self) -> np.ndarray:
        return np.arange(self.first, self.first + len(self.times))


def sample_count(execution: Execution) -> int:
    """The number of samples of ``execution`` before any thinning."""
    return sum(len(seg.t) for seg in execution.segments) + 2 * len(execution.strips)


def keep_mask(times: np.ndarray, previous_bin: float, t0: float, rate: float) -> np.ndarray:
    """Which of consecutive samples at ``times`` (s) start a new interval of 1/``rate`` s counted
    from ``t0``; ``previous_bin`` is the interval of the sample before them (NaN: none)."""
    bins = np.floor((times - t0) * rate)
    before = np.concatenate([[previous_bin], bins[:-1]])
    return bins != before


def kept_samples(trace: Trace, rate: float | None) -> np.ndarray:
    """The rows of ``trace`` to record: all of them without a rate; with one, the first sample
    in each interval of 1/rate s from the start, and the first and last sample of every piece
    (segment or strip), so that each transition's state before and after its reset is kept."""
    n = len(trace.times)
    if not thins(rate, n, trace.times[0] if n else 0.0, trace.times[-1] if n else 0.0):
        return np.arange(n)
    assert rate is not None
    starts = np.sort(np.concatenate([trace.segment_starts, trace.strip_samples])).astype(np.int64)
    ends = np.concatenate([starts[1:] - 1, [n - 1]])
    keep = keep_mask(trace.times, np.nan, float(trace.times[0]), rate)
    keep[starts] = True
    keep[ends] = True
    return np.flatnonzero(keep)


def thins(rate: float | None, n: int, t_first: float, t_last: float) -> bool:
    """Whether ``rate`` (per s) drops any of ``n`` samples from ``t_first`` to ``t_last`` s."""
    return rate is not None and n > 0 and rate * float(t_last - t_first) < n


@dataclass
class _Buffer:
    """The samples gathered for the next chunk."""

    first: int
    times: list[np.ndarray] = field(default_factory=list)
    modes: list[str] = field(default_factory=list)
    states: list[np.ndarray] = field(default_factory=list)
    segment_starts: list[int] = field(default_factory=list)
    strip_samples: list[int] = field(default_factory=list)
    count: int = 0

    def add(self, mode: str, times: np.ndarray, states: np.ndarray) -> None:
        self.times.append(times)
        self.modes.append(mode)
        self.states.append(states)
        self.count += len(times)

    def chunk(self) -> Chunk:
        mode_names = list(dict.fromkeys(self.modes))
        code = {mode: i for i, mode in enumerate(mode_names)}
        lengths = np.array([len(t) for t in self.times], dtype=np.int64)
        starts = self.first + np.cumsum(lengths) - lengths
        blocks = {}
        for mode in mode_names:
            mine = [i for i, m in enumerate(self.modes) if m == mode]
            rows = np.concatenate([np.arange(starts[i], starts[i] + lengths[i]) for i in mine])
            blocks[mode] = (rows, np.concatenate([self.states[i] for i in mine]).astype(float, copy=False))
        return Chunk(
            first=self.first,
            times=np.concatenate(self.times) if self.times else np.empty(0),
            mode_names=mode_names,
            mode_index=np.repeat(np.array([code[m] for m in self.modes], dtype=np.int64), lengths),
            blocks=blocks,
            segment_starts=np.array(self.segment_starts, dtype=np.int64),
            strip_samples=np.array(self.strip_samples, dtype=np.int64),
        )


def chunks(execution: Execution, rate: float | None, size: int = CHUNK) -> Iterator[Chunk]:
    """The recorded samples of ``execution``, thinned to ``rate`` (``kept_samples``), in chunks
    of ``size`` samples (the last one fewer)."""
    _, pieces = execution._pieces()
    t0, t_last = _time_span(execution, pieces)
    thinning = thins(rate, sample_count(execution), t0, t_last)
    buffer, previous_bin = _Buffer(0), np.nan
    for kind, k in pieces:
        (buffer.strip_samples if kind == "strip" else buffer.segment_starts).append(buffer.first + buffer.count)
        times, states, mode = (
            _piece_times(execution, kind, k),
            _piece_states(execution, kind, k),
            _piece(execution, kind, k).mode,
        )
        start = 0
        while start < len(times):
            # A long piece is cut where the chunk is full, so that no chunk exceeds ``size``.
            stop = min(len(times), start + size - buffer.count)
            t, x = times[start:stop], states[start:stop]
            keep = np.ones(len(t), dtype=bool)
            if thinning:
                assert rate is not None
                keep = keep_mask(t, previous_bin, t0, rate)
                previous_bin = float(np.floor((t[-1] - t0) * rate))
                keep[0] |= start == 0
                keep[-1] |= stop == len(times)
            buffer.add(mode, t[keep], x[keep])
            if buffer.count >= size:
                yield buffer.chunk()
                buffer = _Buffer(buffer.first + buffer.count)
            start = stop
    if buffer.count or buffer.segment_starts or buffer.strip_samples:
        yield buffer.chunk()


def _time_span(execution: Execution, pieces: list[tuple[str, int]]) -> tuple[float, float]:
    """The times (s) of the first and the last sample of the pieces (0, 0 without any)."""
    ends = [_piece_times(execution, *p) for p in pieces[:1] + pieces[-1:]]
    if not all(len(t) for t in ends):  # an empty end piece: look further (rare)
        ends = [t for t in (_piece_times(execution, *p) for p in pieces) if len(t)]
    return (float(ends[0][0]), float(ends[-1][-1])) if ends else (0.0, 0.0)
