"""Conditions on a run's states checked at every stored point and step's middle (``Watch``): a
fall that ends the run, a state the model cannot vouch for that is reported, an interval that
is measured.

A watch is ``value(mode, t, x) -> v``, a function of each point alone, vectorised over points
of one mode (t of shape (N,), x of shape (N, n), the run's state: the plant's, then the
controller's memory; the points of one visit, or of all the mode's visits at once for the
warnings and times made at the end), and its condition *holds* where v < 0; v may have a
column per part of the condition (N, m), which holds where any part is < 0. The driver checks
the points as the loop hands its buffers back (every ``workspace.POINTS`` points at most, and
at the end), so the loop itself, compiled or not, is unchanged. The points a stop or a warning
is checked at are the stored ones and the middle of every step between them, on the step's interpolant
(``refined``): a condition that holds only inside a step (a foot carried through the ground and
out again by one coarse step) is seen wherever it holds at the step's middle. A watch that gives
its value's rate along the flow (``Watch.rate``) is also checked between those points: where the
cubic through two neighbours' values and rates of one part dips below zero, the interpolant is evaluated at
the cubic's least point (and, if the condition does not hold there, both sides of that point are
searched by the same test, ``DIP_SPLITS`` levels deep), so a dip that misses every checked point
is seen too. A cubic vouches only for a smooth value: a watch whose parts are smooth piecewise
(a foot's depth below a profile, whose slope jumps at each corner) says which piece each part
is on (``Watch.piece``), and between two checked points where a part's piece changes, each
change is located on the step's interpolant (on grids refined in the cell where the piece
changed, ``PIECE_GRID``), the condition checked on both sides of it, and each smooth stretch
between tested by its cubic (``across_pieces``). A piece the part enters and leaves within one
cell of the finest grid (2^-12 of half a step) is not seen. One a part leaves and returns to
between two checked points (a foot whose x turns past a profile's corner and back) shows no
change of piece there; a watch that can tell where the part may be on another piece then
(``Watch.probe``: a foot's farthest x on the cubic of its x) has the piece read at that time,
and where it differs, both stretches, out and back, are searched across their changes as
above.
Where a condition first holds between two checked points, the time is located by bisection on
the points' cubic Hermite interpolant (the one ``Execution.sample`` uses: O(h^4) between steps),
to float64 resolution;
where it holds at a visit's first point (a mode entered), the time is that entry's. A condition
met during a crossing's step, before the guard point q, is found at the visit after the
crossing.

Actions:

* ``"stop"``: the run ends at that time with ``status`` (``fell``, ``model_breakdown``) and the
  watch's message; the execution is cut there (its last point the located one, later strips and
  transitions dropped). The loop may have run on to the next hand-back: the counters count every
  step it took.
* ``"warn"``: a ``RunWarning`` of kind ``name`` naming where the condition first held and where
  v was least (a checked point), with v there in ``details["least_value"]``.
* ``"time"``: the time the condition held along the flow (s, located at both ends), in the
  execution's counters under ``counter``. Strip holds are not flow and are not counted. It is
  measured on the stored points alone: a stretch inside one step is within a counter's
  accuracy (O(h) a stretch), and the steps' middles would double the cost.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from ..errors import SimulationError
from ..execution import Segment, Status, hermite_values
from .single import hermite, hermite_derivative

ACTIONS = ("stop", "warn", "time")
#: Bisection steps locating a time (enough to reach float64's resolution of any step).
BISECTIONS = 64
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


@dataclass(frozen=True)
class Watch:
    """A condition on the run's states (module docstring).

    Attributes
    ----------
    name: the condition's name (a warning's kind).
    value: ``value(mode, t, x) -> v`` (N,), vectorised over one visit's points; < 0: it holds.
        Or (N, m), one column per part of the condition (a foot each, a link's point each): it
        holds where any part is < 0, and each part is checked between points on its own.
    action: ``"stop"``, ``"warn"`` or ``"time"``.
    message: ``message(t, mode, x) -> str`` at a point where it holds (stop, warn).
    status: the status a stop ends the run with (a ``Status`` value).
    counter: the counter a ``"time"`` watch fills (s).
    rate: ``rate(mode, t, x) -> dv/dt`` along the flow at the points (v's unit per s), of v's
        shape, or None; with it a stop or warn watch is also checked between the points (module
        docstring).
    piece: ``piece(mode, t, x) -> labels`` of v's shape, or None (every part smooth): which
        smooth piece of its part's value each point is on (finite numbers, equal on one piece:
        the segment of a profile under a foot). Needs ``rate``.
    clear: ``clear(mode, ta, xa, tb, xb) -> (J, m) bool``, or None: the parts that cannot hold
        anywhere between two checked points (times ta, tb (J,), states xa, xb (J, n)), whatever
        pieces they cross (a point that stays above the highest ground under it); their changes
        of piece are not searched. Needs ``piece``.
    probe: ``probe(mode, t, x) -> (N - 1, m)`` times (s), or None: for each two neighbouring
        points (t (N,), x (N, n)) and each part, a time strictly between them at which the part
        may be on another piece than the one it is on at both (where a point's x turns past a
        profile's corner and back: the time of its farthest x), nan where there is none. The
        piece is read there on the step's interpolant; where it differs, the part's way out
        and back is searched. Needs ``piece``.
    """

    name: str
    value: Callable[[str, np.ndarray, np.ndarray], np.ndarray]
    action: str = "stop"
    message: Callable[[float, str, np.ndarray], str] | None = None
    status: str = Status.FELL.value
    counter: str = ""
    rate: Callable[[str, np.ndarray, np.ndarray], np.ndarray] | None = None
    piece: Callable[[str, np.ndarray, np.ndarray], np.ndarray] | None = None
    clear: Callable[[str, np.ndarray, np.ndarray, np.ndarray, np.ndarray], np.ndarray] | None = None
    probe: Callable[[str, np.ndarray, np.ndarray], np.ndarray] | None = None

    def __post_init__(self) -> None:
        if self.action not in ACTIONS:
            raise SimulationError(f"watch {self.name!r}: action must be one of {list(ACTIONS)}, got {self.action!r}")
        if not callable(self.value):
            raise SimulationError(f"watch {self.name!r}: value must be a function value(mode, t, x)")
        if self.action in ("stop", "warn") and not callable(self.message):
            raise SimulationError(f"watch {self.name!r}: a {self.action} watch needs message(t, mode, x)")
        if self.action == "stop" and self.status not in {s.value for s in Status}:
            raise SimulationError(f"watch {self.name!r}: status {self.status!r} is not a run status")
        if self.action == "time" and not self.counter:
            raise SimulationError(f"watch {self.name!r}: a time watch needs a counter name")
        if self.rate is not None and not callable(self.rate):
            raise SimulationError(f"watch {self.name!r}: rate must be None or a function rate(mode, t, x)")
        if self.piece is not None and not (callable(self.piece) and self.rate is not None):
            raise SimulationError(
                f"watch {self.name!r}: piece must be None or a function piece(mode, t, x), given with a rate"
            )
        if self.clear is not None and not (callable(self.clear) and self.piece is not None):
            raise SimulationError(
                f"watch {self.name!r}: clear must be None or a function clear(mode, ta, xa, tb, xb), given with a piece"
            )
        if self.probe is not None and not (callable(self.probe) and self.piece is not None):
            raise SimulationError(
                f"watch {self.name!r}: probe must be None or a function probe(mode, t, x), given with a piece"
            )

    def values(self, mode: str, t: np.ndarray, x: np.ndarray) -> np.ndarray:
        """The condition's value at the points (N,), float64: the least of its parts (+inf
        where it has none); SimulationError naming the watch if ``value`` gives no such array."""
        return condition(self.parts(mode, t, x))

    def parts(self, mode: str, t: np.ndarray, x: np.ndarray) -> np.ndarray:
        """v at the points, one column per part (N, m), float64."""
        return self._call(self.value, "value", mode, t, x)

    def rates(self, mode: str, t: np.ndarray, x: np.ndarray) -> np.ndarray:
        """dv/dt at the points, as ``parts`` (``rate``, which must be given)."""
        assert self.rate is not None
        return self._call(self.rate, "rate", mode, t, x)

    def pieces(self, mode: str, t: np.ndarray, x: np.ndarray) -> np.ndarray:
        """The piece of each part at the points, as ``parts`` (``piece``, which must be given)."""
        assert self.piece is not None
        return self._call(self.piece, "piece", mode, t, x)

    def probes(self, mode: str, t: np.ndarray, x: np.ndarray, parts: int) -> np.ndarray:
        """``probe``'s times between the neighbouring points (N - 1, parts), float64 (``probe``,
        which must be given); SimulationError naming the watch if it gives no such array."""
        assert self.probe is not None
        if t.shape[0] < 2:
            return np.empty((0, parts))
        try:
            times = np.asarray(self.probe(mode, t, x), dtype=float)
        except Exception as exc:
            raise SimulationError(
                f"watch {self.name!r}: its probe failed in mode '{mode}': {type(exc).__name__}: {exc}"
            ) from exc
        if times.shape != (t.shape[0] - 1, parts):
            raise SimulationError(
                f"watch {self.name!r}: its probe gave shape {times.shape} for {t.shape[0]} points of {parts} parts"
            )
        return times

    def _call(self, function: Callable[..., Any], what: str, mode: str, t: np.ndarray, x: np.ndarray) -> np.ndarray:
        try:
            v = np.asarray(function(mode, t, x), dtype=float)
            raw_shape = v.shape
        except Exception as exc:
            raise SimulationError(
                f"watch {self.name!r}: its {what} failed in mode '{mode}': {type(exc).__name__}: {exc}"
            ) from exc
        if v.ndim == 1:
            v = v[:, None]
        if v.ndim != 2 or v.shape[0] != t.shape[0]:
            raise SimulationError(
                f"watch {self.name!r} gave {what}s of shape {raw_shape} for {t.shape[0]} points: (N,) or (N, parts)"
            )
        return v


def condition(parts: np.ndarray) -> np.ndarray:
    """A condition's value (N,) from its parts' (N, m): the least, +inf where it has none. A nan
    part (a value its watch could not give) hides no other: nan only where every part is."""
    return np.fmin.reduce(parts, axis=1) if parts.shape[1] else np.full(parts.shape[0], np.inf)


def check(watches: Any) -> tuple[Watch, ...]:
    """The watches as a tuple, each a ``Watch`` (SimulationError otherwise)."""
    out = tuple(watches or ())
    for w in out:
        if not isinstance(w, Watch):
            raise SimulationError(f"watches must be legsim.relaxed.Watch objects, got {type(w).__name__}")
    return out


def point(t: np.ndarray, x: np.ndarray, dx: np.ndarray, k: int, tau: float) -> tuple[np.ndarray, np.ndarray]:
    """The interpolated state and its slope at time tau in the step from point k - 1 to k."""
    dt = float(t[k] - t[k - 1])
    s = (tau - float(t[k - 1])) / dt
    return hermite(x[k - 1], dx[k - 1], x[k], dx[k], dt, s), hermite_derivative(x[k - 1], dx[k - 1], x[k], dx[k], dt, s)


def refined(t: np.ndarray, x: np.ndarray, dx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The points a watch is checked at: one visit's stored points (t (N,), x and dx (N, n)) with
    the middle of each step between them on its interpolant, interleaved: times (2N - 1,) and
    states (2N - 1, n). Point k of these is stored point ``stored_index(k)``, or the middle of
    the step ending there; a time between two of them is located on that stored step."""
    if t.shape[0] < 2:
        return t, x
    mid_t, mid_x = Segment("", t, x, dx).midpoints()
    out_t = np.empty(2 * t.shape[0] - 1)
    out_x = np.empty((out_t.shape[0], x.shape[1]))
    out_t[0::2], out_t[1::2] = t, mid_t
    out_x[0::2], out_x[1::2] = x, mid_x
    return out_t, out_x


def stored_index(k: int) -> int:
    """The stored point at or after point k of ``refined``'s (k itself or the step's end)."""
    return (k + 1) // 2


def locate(
    watch: Watch, mode: str, t: np.ndarray, x: np.ndarray, dx: np.ndarray, k: int, holds: bool,
    within: tuple[float, float] | None = None,
) -> float:  # fmt: skip
    """The time in (t[k-1], t[k]] (or in ``within``, a part of that step) where the condition
    starts (``holds``) or stops holding: the bisection's end on the side where the new state is
    reached, on the step's interpolant."""
    lo, hi = (float(t[k - 1]), float(t[k])) if within is None else within
    for _ in range(BISECTIONS):
        mid = 0.5 * (lo + hi)
        if not lo < mid < hi:
            break
        xm, _ = point(t, x, dx, k, mid)
        v = float(watch.values(mode, np.array([mid]), xm[None, :])[0])
        if (v < 0.0) == holds:
            hi = mid
        else:
            lo = mid
    return hi


#: A visit's stored points: times (N,), states and their slopes (N, n).
Stored = tuple[np.ndarray, np.ndarray, np.ndarray]


class Hold(NamedTuple):
    """Where a watch's condition first holds in a visit."""

    k: int  #: the checked point at or after it (``refined``'s index)
    time: float  #: when it starts to hold (s)
    #: (t, x, v): a point between two checked ones where it holds, found by the value's rate; None
    #: where a checked point holds first.
    inside: tuple[float, np.ndarray, float] | None = None


class PartsAt(NamedTuple):
    """A watch's parts at checked points, their rates along the flow and, where it gives them,
    their pieces, (N, m) each, and its probes' times between the points, (N - 1, m)."""

    parts: np.ndarray
    rates: np.ndarray
    pieces: np.ndarray | None = None
    probes: np.ndarray | None = None


def first_hold(
    watch: Watch,
    mode: str,
    checked: tuple[np.ndarray, np.ndarray],
    stored: tuple[np.ndarray, np.ndarray, np.ndarray],
    values: Any = None,
    parts_at: PartsAt | None = None,
) -> Hold | None:
    """Where the condition first holds among a visit's ``checked`` points (``refined`` of its
    ``stored`` points t, x, dx), or between two of them by the watch's rate, or None; ``values``
    (the condition's, (N,)) and its parts, their rates and pieces (``PartsAt``) at the checked
    points when known."""
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
        # up to the first checked point that holds: a part may dip before it within its step
        parts, rates, pieces, probes = parts_at
        upto = PartsAt(
            parts[: k + 1],
            rates[: k + 1],
            None if pieces is None else pieces[: k + 1],
            None if probes is None else probes[:k],
        )
        dip = first_dip(watch, mode, (t[: k + 1], x[: k + 1]), upto, stored)
        if dip is not None and (held is None or dip.time < held.time):
            return dip
    return held


def _parts_at(watch: Watch, mode: str, t: np.ndarray, x: np.ndarray, given: PartsAt | None) -> PartsAt | None:
    """The parts, their rates and pieces at the points (``given``, or the watch's), None without
    a rate."""
    if watch.rate is None:
        return None
    if given is None:
        # on the whole arrays, which a watch may keep what it computed on for the rates
        parts = watch.parts(mode, t, x)
        pieces = None if watch.piece is None else watch.pieces(mode, t, x)
        probes = None if watch.probe is None else watch.probes(mode, t, x, parts.shape[1])
        given = PartsAt(parts, watch.rates(mode, t, x), pieces, probes)
    for what, a in (("rates", given.rates), ("pieces", given.pieces)):
        if a is not None and a.shape != given.parts.shape:
            raise SimulationError(
                f"watch {watch.name!r}: its {what}' shape {a.shape} is not its values' {given.parts.shape}"
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


def first_dip(
    watch: Watch, mode: str, checked: tuple[np.ndarray, np.ndarray], parts_at: PartsAt, stored: Stored
) -> Hold | None:
    """The first hold between two neighbours of the ``checked`` points (t (N,), x (N, n)), with
    the watch's parts, their rates, pieces and probes there (``parts_at``): where the cubic
    through a part's values and rates dips below zero and the interpolant confirms it, or where
    parts' pieces change (at the checked points, or at a probe between them) and the search
    across the changes finds it (module docstring); in the earliest such interval, the earliest
    of its parts' holds."""
    t, x = checked
    v, r, pieces, probes = parts_at
    _, least = cubic_least(v[:-1], v[1:], r[:-1], r[1:], np.diff(t)[:, None])
    unsmooth = np.zeros(least.shape, dtype=bool) if pieces is None else pieces[:-1] != pieces[1:]
    dips = (least < 0.0) & ~unsmooth
    probe_times, probe_pieces = _detours(watch, mode, t, pieces, probes, unsmooth, stored)
    detours = probe_times == probe_times
    cleared = _cleared(watch, mode, t, x, unsmooth | detours)
    changes, detours = unsmooth & ~cleared, detours & ~cleared
    for j in np.flatnonzero((dips | changes | detours).any(axis=1)):
        k = stored_index(int(j) + 1)
        times = np.broadcast_to(t[j : j + 2, None], v[j : j + 2].shape)
        ends = np.stack([times, v[j : j + 2], r[j : j + 2]], axis=-1)  # (2, parts, 3): t, value, rate
        found = [
            _confirmed(watch, mode, stored, k, int(p), _end(ends[0, p]), _end(ends[1, p]), DIP_SPLITS)
            for p in np.flatnonzero(dips[j])
        ]
        if changes[j].any():
            assert pieces is not None
            which = np.flatnonzero(changes[j])
            found.append(across_pieces(watch, mode, stored, k, which, ends[0, which], ends[1, which],
                                       pieces[j : j + 2, which].T, PIECE_CHANGES))  # fmt: skip
        for p in np.flatnonzero(detours[j]):
            assert pieces is not None
            probe = (float(probe_times[j, p]), float(probe_pieces[j, p]))
            found.append(_detour(watch, mode, stored, k, int(p), ends[:, p], float(pieces[j, p]), probe))
        holds = [
            Hold(int(j) + 1, locate(watch, mode, *stored, k, True, (float(t[j]), inside[0])), inside)
            for inside in found
            if inside is not None
        ]
        if holds:
            return min(holds, key=lambda hold: hold.time)
    return None


def _cleared(watch: Watch, mode: str, t: np.ndarray, x: np.ndarray, unsmooth: np.ndarray) -> np.ndarray:
    """Which parts the watch's ``clear`` rules out between each two checked points where some
    part's piece changes (``unsmooth``, (N - 1, m)), of its shape; none without ``clear``."""
    out = np.zeros(unsmooth.shape, dtype=bool)
    rows = np.flatnonzero(unsmooth.any(axis=1))
    if watch.clear is None or rows.size == 0:
        return out
    try:
        cleared = np.asarray(watch.clear(mode, t[rows], x[rows], t[rows + 1], x[rows + 1]), dtype=bool)
    except Exception as exc:
        raise SimulationError(
            f"watch {watch.name!r}: its clear failed in mode '{mode}': {type(exc).__name__}: {exc}"
        ) from exc
    if cleared.shape != (rows.size, unsmooth.shape[1]):
        raise SimulationError(
            f"watch {watch.name!r}: its clear gave shape {cleared.shape} for {rows.size} stretches of "
            f"{unsmooth.shape[1]} parts"
        )
    out[rows] = cleared
    return out


def _detours(
    watch: Watch, mode: str, t: np.ndarray, pieces: np.ndarray | None, probes: np.ndarray | None,
    unsmooth: np.ndarray, stored: Stored,
) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Where the watch's probes (``probes``, (N - 1, m) times between the checked points at
    times t (N,)) find a part on another piece between two checked points at which it is on
    one (``unsmooth`` false): the probe's time and the piece there, (N - 1, m) each, nan
    elsewhere (everywhere without probes)."""
    times, labels = np.full(unsmooth.shape, np.nan), np.full(unsmooth.shape, np.nan)
    if probes is None or pieces is None or t.shape[0] < 2:
        return times, labels
    if probes.shape != unsmooth.shape:
        raise SimulationError(
            f"watch {watch.name!r}: its probe gave shape {probes.shape} for {t.shape[0]} points of "
            f"{unsmooth.shape[1]} parts"
        )
    with np.errstate(invalid="ignore"):
        inside = ~unsmooth & (probes > t[:-1, None]) & (probes < t[1:, None])
    j, p = np.nonzero(inside)
    if j.size == 0:
        return times, labels
    at = probes[j, p]
    states = _interpolated(stored, (j + 2) // 2, at)  # the stored step of checked interval j
    read = watch.pieces(mode, at, states)[np.arange(j.size), p]
    other = read != pieces[j, p]
    times[j[other], p[other]], labels[j[other], p[other]] = at[other], read[other]
    return times, labels


def _interpolated(stored: Stored, k: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Each stored step k[i]'s interpolant at times[i] inside it, (len(times), n)."""
    t, x, dx = stored
    dt = (t[k] - t[k - 1])[:, None]
    return hermite_values(x[k - 1], dx[k - 1], x[k], dx[k], dt, (times - t[k - 1])[:, None] / dt)


def _detour(
    watch: Watch, mode: str, stored: Stored, k: int, part: int, ends: np.ndarray, piece: float,
    probe: tuple[float, float],
) -> Inside | None:  # fmt: skip
    """The earliest point of stored step k's interpolant found where the condition holds for a
    part that is on ``piece`` at both ``ends`` ((2, 3): t, value, rate) and on another at the
    ``probe`` (its time and that piece): the probed point itself, and the way out and the way
    back each searched across its changes of piece (``across_pieces``)."""
    tp, piece_out = probe
    at = np.array([tp])
    state = _states_at(stored, k, at)
    parts, rates = watch.parts(mode, at, state), watch.rates(mode, at, state)
    held = float(condition(parts)[0])
    middle = np.array([[tp, parts[0, part], rates[0, part]]])
    which = np.array([part])
    found = [
        (tp, state[0], held) if held < 0.0 else None,
        across_pieces(watch, mode, stored, k, which, ends[:1], middle, np.array([[piece, piece_out]]), PIECE_CHANGES),
        across_pieces(watch, mode, stored, k, which, middle, ends[1:], np.array([[piece_out, piece]]), PIECE_CHANGES),
    ]
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


def _states_at(stored: Stored, k: int, times: np.ndarray) -> np.ndarray:
    """Stored step k's interpolant at ``times`` (m,) inside it, (m, n)."""
    t, x, dx = stored
    t0, dt = float(t[k - 1]), float(t[k] - t[k - 1])
    return hermite_values(x[k - 1], dx[k - 1], x[k], dx[k], dt, (times.reshape(-1, 1) - t0) / dt)


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
    start: End, end: End, splits: int,
) -> Inside | None:  # fmt: skip
    """A point (t, x, v) of stored step k's interpolant between ``start`` and ``end`` (t, the
    part's value and rate) where the condition holds, searched at the least point of the part's
    cubic and, where it does not hold there, on each side of it, ``splits`` levels deep."""
    (ta, va, ra), (tb, vb, rb) = start, end
    s, least = (float(u[0]) for u in cubic_least(*(np.array([w]) for w in (va, vb, ra, rb, tb - ta))))
    tm = ta + s * (tb - ta)
    if not (least < 0.0 and ta < tm < tb):
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
    found = _confirmed(watch, mode, stored, k, part, start, middle, splits - 1)
    return found if found is not None else _confirmed(watch, mode, stored, k, part, middle, end, splits - 1)


class PointsByMode:
    """The checked points of a list of visits (mode, t, x), gathered by mode once for every watch
    asked about them: a watch is vectorised, and a run visits few modes many times. Every watch
    then sees the very same arrays of a mode (a watch may keep what it computed on them)."""

    def __init__(self, visits: Sequence[tuple[str, np.ndarray, np.ndarray]]) -> None:
        by_mode: dict[str, list[int]] = {}
        for i, (mode, _, _) in enumerate(visits):
            by_mode.setdefault(mode, []).append(i)
        self.count = len(visits)
        self.groups = []
        for mode, members in by_mode.items():
            t = np.concatenate([visits[i][1] for i in members])
            x = np.concatenate([visits[i][2] for i in members])
            ends = np.cumsum([visits[i][1].shape[0] for i in members])[:-1]
            self.groups.append((mode, members, t, x, ends))

    def values(self, watch: Watch, kind: str = "values") -> list[np.ndarray]:
        """The condition's value at the points of each visit, in the visits' order: one call of
        the watch per mode; with ``kind`` "parts", "rates" or "pieces" its parts, their rates
        or their pieces (the watch's methods of those names)."""
        function = getattr(watch, kind)
        out: list[np.ndarray] = [np.empty(0)] * self.count
        for mode, members, t, x, ends in self.groups:
            for i, v in zip(members, np.split(function(mode, t, x), ends), strict=True):
                out[i] = v
        return out

    def probes(self, watch: Watch, parts: Sequence[np.ndarray]) -> list[np.ndarray]:
        """The watch's probes between the points of each visit (``Watch.probes``, (N - 1, m)),
        in the visits' order, ``parts`` each visit's parts (their widths): one call of the watch
        per mode, the times between two visits' points dropped."""
        out: list[np.ndarray] = [np.empty((0, 0))] * self.count
        for mode, members, t, x, ends in self.groups:
            times = watch.probes(mode, t, x, parts[members[0]].shape[1])
            starts, stops = [0, *ends], [*ends, t.shape[0]]
            for i, start, stop in zip(members, starts, stops, strict=True):
                out[i] = times[start : max(stop - 1, start)]
        return out


def time_held(
    watch: Watch, mode: str, t: np.ndarray, x: np.ndarray, dx: np.ndarray, values: np.ndarray | None = None
) -> float:
    """The time (s) the condition holds along one visit's flow, the ends of each interval
    located; ``values``: v at the visit's points when known."""
    if t.shape[0] < 2:
        return 0.0
    neg = (watch.values(mode, t, x) if values is None else values) < 0.0
    if not neg.any():  # the common case, an actuator never at its limit: nothing to add up
        return 0.0
    total = float(np.sum(np.diff(t)[neg[:-1] & neg[1:]]))
    for crossing in np.flatnonzero(neg[:-1] != neg[1:]) + 1:
        k = int(crossing)
        if neg[k]:  # starts holding inside the step
            total += float(t[k]) - locate(watch, mode, t, x, dx, k, True)
        else:  # stops holding inside it
            total += locate(watch, mode, t, x, dx, k, False) - float(t[k - 1])
    return total


def least_of(v: np.ndarray) -> tuple[int, float]:
    """The index of the least of the values v and that value (nan values left out)."""
    v = np.where(np.isnan(v), np.inf, v)
    k = int(np.argmin(v))
    return k, float(v[k])
