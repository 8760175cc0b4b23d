"""Where an execution meets a section: the level set s(x) = 0 of a function of one mode's state,
crossed in a given direction and found on the stored flow's cubic Hermite interpolant
(``Segment.interpolate``, accurate to the step's order 4), or the takings of a named transition.

Return maps (``legsim.orbits``), sweeps of gaits (``legsim.sweep``) and the along-the-orbit
comparison of ``--check-accuracy`` (``legsim.accuracy``) all locate their section crossings here.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator

import numpy as np
from scipy.optimize import brentq

from .execution import Execution, RunSoFar, Segment

#: A crossing: its time (s) and the state there (the segment's width: the plant's coordinates,
#: then a controller's memory).
Crossing = tuple[float, np.ndarray]


def first_crossing(
    seg: Segment, s: Callable[[np.ndarray], float], direction: int, not_before: float
) -> Crossing | None:
    """First crossing (t, x) of s = 0 on a segment's dense output strictly after ``not_before``
    (s), in ``direction`` (-1: s from > 0 to <= 0; +1: from < 0 to >= 0; 0: either), or None."""
    start = max(int(np.searchsorted(seg.t, not_before, side="right")) - 1, 0)
    s1 = s(seg.x[start])
    for i in range(start, len(seg.t) - 1):
        s0, s1 = s1, s(seg.x[i + 1])
        down = s0 > 0.0 >= s1
        up = s0 < 0.0 <= s1
        if not ((direction <= 0 and down) or (direction >= 0 and up)):
            continue
        tc = seg.t[i + 1] if s1 == 0.0 else _crossing_time(seg, s, seg.t[i], seg.t[i + 1])
        if tc <= not_before:
            continue
        return tc, seg.interpolate(np.array([tc]))[0]
    return None


def returns(
    execution: Execution | RunSoFar,
    mode: str,
    s: Callable[[np.ndarray], float],
    direction: int,
    min_transitions: int = 1,
    min_time: float = 0.0,
) -> Iterator[tuple[int, float, np.ndarray]]:
    """The crossings of s = 0 in ``direction`` in the segments of ``mode`` that count as returns
    to the section, in time order, each as (k, t, x) with k its segment's index (segment k
    follows transitions[k - 1]). A crossing counts only ``min_transitions`` segments and
    ``min_time`` (s) after the last one counted, and with ``min_transitions`` > 0 only a
    segment's first crossing counts: a state that slides along the section (the flow grazing
    it back and forth) returns once, as in a return map. ``min_transitions`` = 0 and
    ``min_time`` = 0 give every crossing."""
    last_k, last_t = 0, execution.t0
    for k, seg in enumerate(execution.segments):
        if seg.mode != mode or len(seg.t) < 2 or k - last_k < min_transitions:
            continue
        hit = first_crossing(seg, s, direction, last_t + min_time)
        while hit is not None:
            yield k, hit[0], hit[1]
            last_k, last_t = k, hit[0]
            if min_transitions > 0:
                break
            hit = first_crossing(seg, s, direction, last_t + min_time)


def takings(execution: Execution, transition: str, mode: str) -> list[Crossing]:
    """Every taking of ``transition`` into ``mode``: the time the run leaves its strip (s) and
    the state after its reset."""
    return [
        (float(r.exit_time), np.asarray(r.state_after, dtype=float))
        for r in execution.transitions
        if r.name == transition and r.target == mode
    ]


def _crossing_time(seg: Segment, s: Callable[[np.ndarray], float], t0: float, t1: float) -> float:
    """The root of s along the interpolant between two stored points with a sign change; the
    interpolant's ends are the stored points, so the bracket holds."""

    def along(t: float) -> float:
        return s(seg.interpolate(np.array([t]))[0])

    return float(brentq(along, t0, t1, xtol=1e-15 * max(1.0, abs(t1)), rtol=4 * np.finfo(float).eps))
