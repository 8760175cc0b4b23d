"""Where a watch's condition holds between two checked points (``legsim.relaxed.watches``): the
first hold of a visit (``first_hold``), at a checked point or between two, found from the parts'
values, their rates along the flow and, for a value smooth only piecewise, their pieces.

Where the cubic through two neighbours' values and rates of one part dips below zero, the
interpolant is evaluated at the cubic's least point (and, if the condition does not hold there,
both sides of that point are searched by the same test, ``DIP_SPLITS`` levels deep), so a dip that
misses every checked point is seen too. The cubic is only a model of the value: how far the value
lies from it is measured at each step's middle (its distance from the cubic through the step's
ends, ``cubic_misfits``), and a half step is searched the same way wherever its cubic's least
inside it comes within that distance of zero, so a narrow dip the cubic smooths over is seen where
the step's middle shows the value far from cubic. That distance is an estimate, not a bound: a
dip narrow enough to leave the middle near the cubic (most of those away from the middle's side
of the step) is still not seen.

A cubic vouches only for a smooth value: a watch whose parts are smooth piecewise (a foot's depth
below a profile, whose slope jumps at each corner) says which piece each part is on
(``Watch.piece``), and between two checked points where a part's piece changes, each change is
located on the step's interpolant (on grids refined in the cell where the piece changed,
``PIECE_GRID``), the condition checked on both sides of it, and each smooth stretch between tested
by its cubic (``across_pieces``). A piece the part enters and leaves within one cell of the finest
grid (2^-12 of half a step) is not seen. A piece that a part leaves and returns to between two
checked points (a foot whose x turns past a profile's corner and back) shows no change there; a
watch that can tell where the part may be on another piece then (``Watch.probe``: the turns of a
foot's x on its cubic) has the piece read at those times, and where it differs, the chain of the
two ends and the probed points is searched stretch by stretch: across its changes where two
neighbours' pieces differ, by its cubic where they agree.

Where a condition first holds between two checked points, the time is located by bisection on
the points' cubic Hermite interpolant (``watches.locate``).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from ..errors import SimulationError
from ..execution import hermite_values
from .watches import Hold, PartsAt, Stored, Watch, condition, locate, point, stored_index

#: Levels of search in a part of a step where the cubic through its ends' values and rates dips
#: below zero but the interpolant at the cubic's least point does not: each level splits at that
#: point and searches both sides, so 4 levels make at most 31 probes.
DIP_SPLITS = 4
#: Where a part's piece changes inside a step is searched on a grid of PIECE_GRID points, then
#: on the same grid in the cell where it changed, PIECE_LEVELS times: the change is then known to
#: 16^-3 = 2^-12 of the stretch searched (0.12 us of a 0.5 ms half step), in 3 calls of the watch.
PIECE_GRID = 15
PIECE_LEVELS = 3
#: Most changes of piece a part is followed through between two checked points (a foot crossing
#: that many profile corners in half a step); past them the rest of the stretch is tested whole.
PIECE_CHANGES = 8


def first_hold(
    watch: Watch,
    mode: str,
    checked: tuple[np.ndarray, np.ndarray],
    stored: Stored,
    values: Any = None,
    parts_at: PartsAt | None = None,
) -> Hold | None:
    """Where the condition first holds among a visit's ``checked`` points (``refined`` of its
    ``stored`` points t, x, dx), or between two of them by the watch's rate, or None; ``values``
    (the condition's, (N,)) and its parts, their rates, pieces and probes (``PartsAt``) at the
    checked points when known."""
    t, x = checked
    if t.shape[0] == 0:
        return None
    parts_at = _parts_at(watch, mode, t, x, parts_at)
    if values is None:
        values = watch.values(mode, t, x) if parts_at is None else condition(parts_at.parts)
    v = np.asarray(values)
    below = np.flatnonzero(v < 0.0)
    k = int(below[0]) if below.size else t.shape[0]
    if k == 0:
        return Hold(0, float(t[0]))
    held = (
        None
        if k == t.shape[0]
        else Hold(k, locate(watch, mode, *stored, stored_index(k), True, (float(t[k - 1]), float(t[k]))))
    )
    if parts_at is not None:
        # Up to the first checked point that holds, to the end of its step: a part may dip before
        # it within the step, and the step's misfit needs both its ends (a dip found after the
        # point is later than it, and dropped below).
        parts, rates, pieces, probes = parts_at
        stop = min(k + 1 + k % 2, t.shape[0])
        upto = PartsAt(
            parts[:stop],
            rates[:stop],
            None if pieces is None else pieces[:stop],
            None if probes is None else probes[: stop - 1],
        )
        dip = first_dip(watch, mode, (t[:stop], x[:stop]), upto, stored)
        if dip is not None and (held is None or dip.time < held.time):
            return dip
    return held


def _parts_at(watch: Watch, mode: str, t: np.ndarray, x: np.ndarray, given: PartsAt | None) -> PartsAt | None:
    """The parts, their rates, pieces and probes at the points (``given``, or the watch's), None
    without a rate."""
    if watch.rate is None:
        return None
    if given is None:
        # on the whole arrays, which a watch may keep what it computed on for the rates
        parts = watch.parts(mode, t, x)
        pieces = None if watch.piece is None else watch.pieces(mode, t, x)
        probes = None if watch.probe is None else watch.probes(mode, t, x)
        given = PartsAt(parts, watch.rates(mode, t, x), pieces, probes)
    for what, a in (("rates", given.rates), ("pieces", given.pieces)):
        if a is not None and a.shape != given.parts.shape:
            raise SimulationError(
                f"watch {watch.name!r}: its {what}' shape {a.shape} is not its values' {given.parts.shape}"
            )
    rows, parts = max(t.shape[0] - 1, 0), given.parts.shape[1]
    if given.probes is not None and rows and given.probes.shape[:2] != (rows, parts):
        raise SimulationError(
            f"watch {watch.name!r}: its probe gave shape {given.probes.shape} (rows, parts, probes) for "
            f"{t.shape[0]} points of {parts} parts"
        )
    return given


def cubic_least(
    v0: np.ndarray, v1: np.ndarray, r0: np.ndarray, r1: np.ndarray, dt: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The local minimum inside (0, 1) of the cubic through (0, v0) and (dt, v1) with slopes r0,
    r1, on each interval (arrays of one shape): its place as a fraction s of dt and its value; s
    is nan where the cubic has none. (Where both ends are >= 0 and it is < 0, it is the least.)"""
    with np.errstate(all="ignore"):  # an interval without a minimum, or with infinite ends, gives nan
        a, b, d = dt * r0, dt * r1, v1 - v0
        c2, c3 = 3.0 * d - 2.0 * a - b, a + b - 2.0 * d  # p(s) = v0 + a s + c2 s^2 + c3 s^3
        disc = c2 * c2 - 3.0 * a * c3
        # the root of p' where p'' = 2 sqrt(disc) > 0, written without cancellation
        root = np.sqrt(disc)
        s = np.where(c2 > 0.0, -a / (c2 + root), (root - c2) / (3.0 * c3))
        s = np.where((disc > 0.0) & (s > 0.0) & (s < 1.0), s, np.nan)
        return s, v0 + s * (a + s * (c2 + s * c3))


def cubic_misfits(t: np.ndarray, v: np.ndarray, r: np.ndarray, unsmooth: np.ndarray) -> np.ndarray:
    """How far a part's value may lie from the cubic through two neighbouring checked points'
    values and rates, (N - 1, m), from the checked points of ``refined`` (t (N,); values v and
    rates r (N, m); stored points at even indices, their steps' middles between): for both halves
    of a stored step, the distance at its middle of the part's value from the cubic through the
    step's ends. The halves' own cubics are about 16 times closer for a value smooth on the
    step's scale (the error goes as dt^4), so this margin keeps a factor 16 to spare there; for
    a feature narrower than the step it is an estimate, not a bound. 0 where there is no
    estimate (a step whose middle ends the points, a part changing piece in it, a value that is
    not finite)."""
    out = np.zeros((max(t.shape[0] - 1, 0), v.shape[1]))
    steps = (t.shape[0] - 1) // 2
    if steps == 0:
        return out
    start, middle, end = v[0 : 2 * steps : 2], v[1 : 2 * steps : 2], v[2 : 2 * steps + 1 : 2]
    dt = (t[2 : 2 * steps + 1 : 2] - t[0 : 2 * steps : 2])[:, None]
    with np.errstate(invalid="ignore"):  # an inactive part's infinite values
        cubic = 0.5 * (start + end) + 0.125 * dt * (r[0 : 2 * steps : 2] - r[2 : 2 * steps + 1 : 2])
        misfit = np.abs(middle - cubic)
    smooth = np.isfinite(misfit) & ~unsmooth[0 : 2 * steps : 2] & ~unsmooth[1 : 2 * steps : 2]
    out[0 : 2 * steps : 2] = out[1 : 2 * steps : 2] = np.where(smooth, misfit, 0.0)
    return out


class Searches(NamedTuple):
    """What ``first_dip`` searches between each two neighbouring checked points, (N - 1, m) each
    (P probes a part at most): the parts whose cubic comes within its margin of zero (``dips``,
    ``margins``), those whose piece changes (``changes``), and those the probes find on another
    piece (``detours``), with the probes' times and the pieces there (``probe_times``,
    ``probe_pieces``: (N - 1, m, P), nan where a probe finds no other piece)."""

    dips: np.ndarray
    margins: np.ndarray
    changes: np.ndarray
    detours: np.ndarray
    probe_times: np.ndarray
    probe_pieces: np.ndarray


def first_dip(
    watch: Watch, mode: str, checked: tuple[np.ndarray, np.ndarray], parts_at: PartsAt, stored: Stored
) -> Hold | None:
    """The first hold between two neighbours of the ``checked`` points (t (N,), x (N, n)), with
    the watch's parts, their rates, pieces and probes there (``parts_at``): where the cubic
    through a part's values and rates comes within its misfit of zero (``cubic_misfits``) and the
    interpolant confirms it, or where parts' pieces change (at the checked points, or at a probe
    between them) and the search across the changes finds it (module docstring); in the
    earliest such interval, the earliest of its parts' holds."""
    t = checked[0]
    searches = _searches(watch, mode, checked, parts_at, stored)
    for j in np.flatnonzero((searches.dips | searches.changes | searches.detours).any(axis=1)):
        k = stored_index(int(j) + 1)
        found = [inside for inside in _found_between(watch, mode, stored, parts_at, t, int(j), searches) if inside]
        holds = [Hold(int(j) + 1, locate(watch, mode, *stored, k, True, (float(t[j]), inside[0])), inside)
                 for inside in found]  # fmt: skip
        if holds:
            return min(holds, key=lambda hold: hold.time)
    return None


def _searches(
    watch: Watch, mode: str, checked: tuple[np.ndarray, np.ndarray], parts_at: PartsAt, stored: Stored
) -> Searches:
    """What to search between the ``checked`` points (``Searches``)."""
    t, x = checked
    v, r, pieces, probes = parts_at
    _, least = cubic_least(v[:-1], v[1:], r[:-1], r[1:], np.diff(t)[:, None])
    unsmooth = np.zeros(least.shape, dtype=bool) if pieces is None else pieces[:-1] != pieces[1:]
    probe_times, probe_pieces = _detours(watch, mode, t, pieces, probes, unsmooth, stored)
    detours = ~np.isnan(probe_times).all(axis=-1)
    margins = cubic_misfits(t, v, r, unsmooth | detours)
    cleared = _cleared(watch, mode, t, x, unsmooth | detours)
    dips = (least < margins) & ~(unsmooth | detours)
    return Searches(dips, margins, unsmooth & ~cleared, detours & ~cleared, probe_times, probe_pieces)


def _found_between(
    watch: Watch, mode: str, stored: Stored, parts_at: PartsAt, t: np.ndarray, j: int, searches: Searches
) -> list[Inside | None]:
    """The points found where the condition holds between checked points j and j + 1 (at times
    t (N,)), by each search ``searches`` names there."""
    v, r, pieces, _ = parts_at
    k = stored_index(j + 1)
    times = np.broadcast_to(t[j : j + 2, None], v[j : j + 2].shape)
    ends = np.stack([times, v[j : j + 2], r[j : j + 2]], axis=-1)  # (2, parts, 3): t, value, rate
    found = [
        _confirmed(watch, mode, stored, k, int(p), _end(ends[0, p]), _end(ends[1, p]), DIP_SPLITS,
                   float(searches.margins[j, p]))
        for p in np.flatnonzero(searches.dips[j])
    ]  # fmt: skip
    if searches.changes[j].any():
        assert pieces is not None
        which = np.flatnonzero(searches.changes[j])
        found.append(across_pieces(watch, mode, stored, k, which, ends[0, which], ends[1, which],
                                   pieces[j : j + 2, which].T, PIECE_CHANGES))  # fmt: skip
    for p in np.flatnonzero(searches.detours[j]):
        assert pieces is not None
        at, labels = searches.probe_times[j, p], searches.probe_pieces[j, p]
        order = np.argsort(at)[: int(np.count_nonzero(~np.isnan(at)))]  # the probes that found one, in time order
        probed = np.stack([at[order], labels[order]], axis=1)
        found.append(_detour(watch, mode, stored, k, int(p), ends[:, p], float(pieces[j, p]), probed))
    return found


def _cleared(watch: Watch, mode: str, t: np.ndarray, x: np.ndarray, searched: np.ndarray) -> np.ndarray:
    """Which parts the watch's ``clear`` rules out between each two checked points where some
    part is to be searched across pieces (``searched``, (N - 1, m)), of its shape; none without
    ``clear``."""
    out = np.zeros(searched.shape, dtype=bool)
    rows = np.flatnonzero(searched.any(axis=1))
    if watch.clear is None or rows.size == 0:
        return out
    try:
        cleared = np.asarray(watch.clear(mode, t[rows], x[rows], t[rows + 1], x[rows + 1]), dtype=bool)
    except Exception as exc:
        raise SimulationError(
            f"watch {watch.name!r}: its clear failed in mode '{mode}': {type(exc).__name__}: {exc}"
        ) from exc
    if cleared.shape != (rows.size, searched.shape[1]):
        raise SimulationError(
            f"watch {watch.name!r}: its clear gave shape {cleared.shape} for {rows.size} stretches of "
            f"{searched.shape[1]} parts"
        )
    out[rows] = cleared
    return out


def _detours(
    watch: Watch, mode: str, t: np.ndarray, pieces: np.ndarray | None, probes: np.ndarray | None,
    unsmooth: np.ndarray, stored: Stored,
) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Where the watch's probes (``probes``, (N - 1, m, P) times between the checked points at
    times t (N,)) find a part on another piece between two checked points at which it is on one
    (``unsmooth`` false): the probes' times and the pieces there, (N - 1, m, P) each, nan
    elsewhere (everywhere without probes)."""
    shape = (*unsmooth.shape, 0 if probes is None else probes.shape[2])
    times, labels = np.full(shape, np.nan), np.full(shape, np.nan)
    if probes is None or pieces is None or t.shape[0] < 2:
        return times, labels
    with np.errstate(invalid="ignore"):
        inside = ~unsmooth[..., None] & (probes > t[:-1, None, None]) & (probes < t[1:, None, None])
    j, p, q = np.nonzero(inside)
    if j.size == 0:
        return times, labels
    at = probes[j, p, q]
    read = watch.pieces(mode, at, _states_at(stored, stored_index(j + 1), at))[np.arange(j.size), p]
    other = read != pieces[j, p]
    times[j[other], p[other], q[other]], labels[j[other], p[other], q[other]] = at[other], read[other]
    return times, labels


def _detour(
    watch: Watch, mode: str, stored: Stored, k: int, part: int, ends: np.ndarray, piece: float, probed: np.ndarray
) -> Inside | None:
    """The earliest point of stored step k's interpolant found where the condition holds for a
    part that is on ``piece`` at both ``ends`` ((2, 3): t, value, rate) and on others at the
    ``probed`` times ((P, 2): each time and the piece there, in time order): the probed points
    themselves, and each stretch of the chain of ends and probed points searched across its
    changes of piece where its two pieces differ (``across_pieces``), by its cubic where they
    agree (``_confirmed``)."""
    at = probed[:, 0]
    states = _states_at(stored, k, at)
    parts, rates = watch.parts(mode, at, states), watch.rates(mode, at, states)
    held = condition(parts)
    found: list[Inside | None] = [(float(at[i]), states[i], float(held[i])) for i in np.flatnonzero(held < 0.0)]
    chain = np.concatenate([ends[:1], np.stack([at, parts[:, part], rates[:, part]], axis=1), ends[1:]])
    labels = np.concatenate([[piece], probed[:, 1], [piece]])
    which = np.array([part])
    for a in range(chain.shape[0] - 1):
        start, end = chain[a : a + 1], chain[a + 1 : a + 2]
        if labels[a] != labels[a + 1]:
            pair = np.array([[labels[a], labels[a + 1]]])
            found.append(across_pieces(watch, mode, stored, k, which, start, end, pair, PIECE_CHANGES))
        else:
            found.append(_confirmed(watch, mode, stored, k, part, _end(start[0]), _end(end[0]), DIP_SPLITS))
    holds = [f for f in found if f is not None]
    return min(holds, key=lambda f: f[0]) if holds else None


#: A point of a step's interpolant where a condition holds: (t, x, v).
Inside = tuple[float, np.ndarray, float]
#: A part at one end of a stretch of a step: (t, its value, its rate).
End = tuple[float, float, float]


def _end(values: Any) -> End:
    """Three numbers (t, value, rate) as an ``End``."""
    t, v, r = values
    return float(t), float(v), float(r)


def across_pieces(
    watch: Watch, mode: str, stored: Stored, k: int, which: np.ndarray,
    start: np.ndarray, end: np.ndarray, pieces: np.ndarray, changes: int,
) -> Inside | None:  # fmt: skip
    """The earliest point of stored step k's interpolant found where the condition holds, for the
    parts ``which`` (P,) whose piece changes between ``start`` and ``end`` ((P, 3): each part's
    t, value and rate there; ``pieces`` (P, 2) its piece at each): for each part, the smooth
    stretch up to its first change tested by its cubic (``_confirmed``), the condition checked
    on both sides of the change, and the rest searched the same way, ``changes`` changes deep."""
    before, after, piece_after = _piece_changes(watch, mode, stored, k, which, start[:, 0], end[:, 0], pieces)
    found, upto, rest = _both_sides(watch, mode, stored, k, which, before, after)
    further = (piece_after != pieces[:, 1]) & (changes > 1)
    found += _stretches(watch, mode, stored, k, which, start, upto, np.ones(which.shape[0], dtype=bool))
    found += _stretches(watch, mode, stored, k, which, rest, end, ~further)
    if further.any():
        pieces_after = np.stack([piece_after, pieces[:, 1]], axis=1)[further]
        found.append(across_pieces(watch, mode, stored, k, which[further], rest[further], end[further],
                                   pieces_after, changes - 1))  # fmt: skip
    holds = [f for f in found if f is not None]
    return min(holds, key=lambda f: f[0]) if holds else None


def _both_sides(
    watch: Watch, mode: str, stored: Stored, k: int, which: np.ndarray, before: np.ndarray, after: np.ndarray
) -> tuple[list[Inside | None], np.ndarray, np.ndarray]:
    """The condition just ``before`` and just ``after`` each part's change of piece ((P,) times,
    s): the points there where it holds, and each part's (t, value, rate) at both, (P, 3) each."""
    times = np.concatenate([before, after])
    states = _states_at(stored, k, times)
    values, rates = watch.parts(mode, times, states), watch.rates(mode, times, states)
    held = condition(values)
    holds: list[Inside | None] = [(float(times[i]), states[i], float(held[i])) for i in np.flatnonzero(held < 0.0)]
    at_part = np.arange(times.shape[0]), np.concatenate([which, which])  # row i: part which[i % P]
    upto, rest = np.split(np.stack([times, values[at_part], rates[at_part]], axis=1), 2)
    return holds, upto, rest


def _states_at(stored: Stored, k: Any, times: np.ndarray) -> np.ndarray:
    """The interpolant of stored step k (one step, or one per time) at ``times`` (m,) inside it,
    (m, n)."""
    t, x, dx = stored
    k = np.broadcast_to(np.asarray(k), times.shape)
    dt = (t[k] - t[k - 1])[:, None]
    return hermite_values(x[k - 1], dx[k - 1], x[k], dx[k], dt, (times - t[k - 1])[:, None] / dt)


def _stretches(
    watch: Watch, mode: str, stored: Stored, k: int, which: np.ndarray, start: np.ndarray, end: np.ndarray,
    tested: np.ndarray,
) -> list[Inside | None]:  # fmt: skip
    """``_confirmed`` on each smooth stretch of the parts ``which`` (P,) from ``start`` to ``end``
    ((P, 3): t, value, rate) that is ``tested`` and whose cubic dips below zero."""
    ta, va, ra = start.T
    tb, vb, rb = end.T
    _, least = cubic_least(va, vb, ra, rb, tb - ta)
    return [
        _confirmed(watch, mode, stored, k, int(which[i]), _end(start[i]), _end(end[i]), DIP_SPLITS)
        for i in np.flatnonzero(tested & (least < 0.0))
    ]


def _piece_changes(
    watch: Watch, mode: str, stored: Stored, k: int, which: np.ndarray, ta: np.ndarray, tb: np.ndarray,
    pieces: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """Where each part of ``which`` (P,) first changes from its piece ``pieces[:, 0]`` on stored
    step k's interpolant between ta and tb ((P,), s), searched on ever finer grids, all parts in
    one call of the watch a level: the times just before and just after the change and the piece
    after it (``pieces[:, 1]``, the one at tb, until a probe finds another), (P,) each."""
    lo, hi, piece = ta.astype(float), tb.astype(float), pieces[:, 1].astype(float)
    rows = np.arange(which.shape[0])
    inner = np.arange(1, PIECE_GRID + 1) / (PIECE_GRID + 1)
    for _ in range(PIECE_LEVELS):
        grid = lo[:, None] + (hi - lo)[:, None] * inner  # (P, PIECE_GRID)
        states = _states_at(stored, k, grid.reshape(-1))
        # row i of part which[i]: its own column of its own grid's labels, (P, PIECE_GRID)
        labels = watch.pieces(mode, grid.reshape(-1), states).reshape(*grid.shape, -1)[rows, :, which]
        changed = labels != pieces[:, :1]
        first = np.argmax(changed, axis=1)
        seen = changed.any(axis=1)
        cell_start = np.where(first > 0, grid[rows, np.maximum(first - 1, 0)], lo)
        lo = np.where(seen, cell_start, grid[:, -1])
        hi = np.where(seen, grid[rows, first], hi)
        piece = np.where(seen, labels[rows, first], piece)
    return lo, hi, piece


def _confirmed(
    watch: Watch, mode: str, stored: Stored, k: int, part: int,
    start: End, end: End, splits: int, margin: float = 0.0,
) -> Inside | None:  # fmt: skip
    """A point (t, x, v) of stored step k's interpolant between ``start`` and ``end`` (t, the
    part's value and rate) where the condition holds, searched at the least point of the part's
    cubic where that is below ``margin`` (how far from the cubic the value may be, >= 0) and,
    where it does not hold there, on each side of it, ``splits`` levels deep."""
    (ta, va, ra), (tb, vb, rb) = start, end
    s, least = (float(u[0]) for u in cubic_least(*(np.array([w]) for w in (va, vb, ra, rb, tb - ta))))
    tm = ta + s * (tb - ta)
    if not (least < margin and ta < tm < tb):
        return None
    xm, _ = point(*stored, k, tm)
    at = (mode, np.array([tm]), xm[None, :])
    parts = watch.parts(*at)
    value = float(condition(parts)[0])
    if value < 0.0:
        return tm, xm, value
    if splits == 0:
        return None
    middle = (tm, float(parts[0, part]), float(watch.rates(*at)[0, part]))
    found = _confirmed(watch, mode, stored, k, part, start, middle, splits - 1, margin)
    return found if found is not None else _confirmed(watch, mode, stored, k, part, middle, end, splits - 1, margin)
