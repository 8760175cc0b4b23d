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
is seen too.
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
from ..execution import Segment, Status
from .single import hermite, hermite_derivative

ACTIONS = ("stop", "warn", "time")
#: Bisection steps locating a time (enough to reach float64's resolution of any step).
BISECTIONS = 64
#: Levels of search in a part of a step where the cubic through its ends' values and rates dips
#: below zero but the interpolant at the cubic's least point does not: each level splits at that
#: point and searches both sides, so 4 levels make at most 31 probes.
DIP_SPLITS = 4


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
    """

    name: str
    value: Callable[[str, np.ndarray, np.ndarray], np.ndarray]
    action: str = "stop"
    message: Callable[[float, str, np.ndarray], str] | None = None
    status: str = Status.FELL.value
    counter: str = ""
    rate: Callable[[str, np.ndarray, np.ndarray], np.ndarray] | None = None

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


def first_hold(
    watch: Watch,
    mode: str,
    checked: tuple[np.ndarray, np.ndarray],
    stored: tuple[np.ndarray, np.ndarray, np.ndarray],
    values: Any = None,
    slopes: tuple[np.ndarray, np.ndarray] | None = None,
) -> Hold | None:
    """Where the condition first holds among a visit's ``checked`` points (``refined`` of its
    ``stored`` points t, x, dx), or between two of them by the watch's rate, or None; ``values``
    (the condition's, (N,)) and ``slopes`` (its parts and their rates, (N, m) each) at the
    checked points when known."""
    t, x = checked
    if t.shape[0] == 0:
        return None
    slopes = _slopes(watch, mode, t, x, slopes)
    if values is None:
        values = watch.values(mode, t, x) if slopes is None else condition(slopes[0])
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
    if slopes is not None:
        # up to the first checked point that holds: a part may dip before it within its step
        parts, rates = slopes
        dip = first_dip(watch, mode, (t[: k + 1], parts[: k + 1], rates[: k + 1]), stored)
        if dip is not None and (held is None or dip.time < held.time):
            return dip
    return held


def _slopes(
    watch: Watch, mode: str, t: np.ndarray, x: np.ndarray, given: tuple[np.ndarray, np.ndarray] | None
) -> tuple[np.ndarray, np.ndarray] | None:
    """The parts and their rates at the points (``given``, or the watch's), None without a rate."""
    if watch.rate is None:
        return None
    # on the whole arrays, which a watch may keep what it computed on for the rates
    parts, rates = (watch.parts(mode, t, x), watch.rates(mode, t, x)) if given is None else given
    if parts.shape != rates.shape:
        raise SimulationError(f"watch {watch.name!r}: its rates' shape {rates.shape} is not its values' {parts.shape}")
    return parts, rates


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
    watch: Watch, mode: str, checked: tuple[np.ndarray, np.ndarray, np.ndarray], stored: Stored
) -> Hold | None:
    """The first hold between two neighbours of the ``checked`` points (t (N,), the parts and
    their rates (N, m)) where the cubic through a part's values and rates dips below zero and the
    interpolant confirms it (module docstring): in the earliest such interval, the earliest of
    its parts' holds."""
    t, v, r = checked
    _, least = cubic_least(v[:-1], v[1:], r[:-1], r[1:], np.diff(t)[:, None])
    for j in np.flatnonzero((least < 0.0).any(axis=1)):
        k = stored_index(int(j) + 1)
        holds = []
        for part in np.flatnonzero(least[j] < 0.0):
            ends = [(float(t[i]), float(v[i, part]), float(r[i, part])) for i in (j, j + 1)]
            inside = _confirmed(watch, mode, stored, k, int(part), ends[0], ends[1], DIP_SPLITS)
            if inside is not None:
                holds.append(Hold(int(j) + 1, locate(watch, mode, *stored, k, True, (ends[0][0], inside[0])), inside))
        if holds:
            return min(holds, key=lambda hold: hold.time)
    return None


def _confirmed(
    watch: Watch, mode: str, stored: Stored, k: int, part: int,
    start: tuple[float, float, float], end: tuple[float, float, float], splits: int,
) -> tuple[float, np.ndarray, float] | None:  # fmt: skip
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
        the watch per mode; with ``kind`` "parts" or "rates" its parts or their rates (the
        watch's methods of those names)."""
        function = getattr(watch, kind)
        out: list[np.ndarray] = [np.empty(0)] * self.count
        for mode, members, t, x, ends in self.groups:
            for i, v in zip(members, np.split(function(mode, t, x), ends), strict=True):
                out[i] = v
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
