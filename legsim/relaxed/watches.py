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
its value's rate along the flow (``Watch.rate``) is also checked between those points, and one
whose value is smooth only piecewise across the changes of its pieces (``Watch.piece``,
``Watch.probe``): ``legsim.relaxed.between``.
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
from typing import Any, NamedTuple, TypeVar

import numpy as np

from ..errors import SimulationError
from ..execution import Segment, Status
from .single import hermite, hermite_derivative

ACTIONS = ("stop", "warn", "time")
#: An index of ``refined``'s points: one, or an array of them.
_Index = TypeVar("_Index", int, np.ndarray)
#: Bisection steps locating a time (enough to reach float64's resolution of any step).
BISECTIONS = 64


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
    probe: ``probe(mode, t, x) -> (N - 1, m, P)`` times (s), or (N - 1, m) for one probe a part, or
        None: for each two neighbouring points (t (N,), x (N, n)) and each part, times strictly
        between them at which the part may be on another piece than the one it is on at both
        (where a point's x turns past a profile's corner and back: the turns of its x), nan where
        there is none. The piece is read there on the step's interpolant; where it differs, the
        part's way out and back is searched. The points given may be several visits' end to end;
        the times between two visits' points are not read. Needs ``piece``.
    graded: whether v measures how far the condition holds (a depth, a force past its limit), so
        that a warning also names where it holds the most; False for a yes-or-no condition (its
        v only -1 or +1), whose warning names where it first holds only.
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
    graded: bool = True

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

    def probes(self, mode: str, t: np.ndarray, x: np.ndarray) -> np.ndarray:
        """``probe``'s times between the neighbouring points, (N - 1, m, P) float64 (``probe``,
        which must be given; (N - 1,) and (N - 1, m) taken as one probe a part);
        SimulationError naming the watch if it gives no such array or fails."""
        assert self.probe is not None
        try:
            times = np.asarray(self.probe(mode, t, x), dtype=float) if t.shape[0] > 1 else np.empty((0, 0, 0))
        except Exception as exc:
            raise SimulationError(
                f"watch {self.name!r}: its probe failed in mode '{mode}': {type(exc).__name__}: {exc}"
            ) from exc
        raw_shape = times.shape
        while times.ndim < 3:
            times = times[..., None]
        if times.ndim != 3 or times.shape[0] != max(t.shape[0] - 1, 0):
            raise SimulationError(
                f"watch {self.name!r}: its probe gave shape {raw_shape} for {t.shape[0]} points: (N - 1,), "
                f"(N - 1, parts) or (N - 1, parts, probes)"
            )
        return times

    def says(self, t: float, mode: str, x: np.ndarray) -> str:
        """``message`` at a point where the watch holds; SimulationError naming the watch if it
        fails or gives no string (the run's message and warnings are strings)."""
        assert self.message is not None
        try:
            text = self.message(t, mode, x)
        except Exception as exc:
            raise SimulationError(
                f"watch {self.name!r}: its message failed at t={t:.17g} in mode '{mode}': {type(exc).__name__}: {exc}"
            ) from exc
        if not isinstance(text, str):
            raise SimulationError(f"watch {self.name!r}: its message must return a str, got {type(text).__name__}")
        return text

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
        # nan < 0 is false: a condition it leaves unknown would never hold, silently (a state that
        # is itself not finite is the run's end, which the run reports)
        if what == "value" and v.shape[1]:
            unknown = np.isnan(v).all(axis=1)
            if unknown.any() and (unknown := unknown & np.isfinite(x).all(axis=1)).any():
                raise SimulationError(
                    f"watch {self.name!r} gave nan for every part at t={float(t[np.argmax(unknown)]):.17g} in mode "
                    f"'{mode}': its condition must be a number at every point"
                )
        return v


def condition(parts: np.ndarray) -> np.ndarray:
    """A condition's value (N,) from its parts' (N, m): the least, +inf where it has none. A nan
    part (a value its watch could not give) hides no other (``Watch.parts`` refuses a point
    where every part is nan)."""
    return np.fmin.reduce(parts, axis=1) if parts.shape[1] else np.full(parts.shape[0], np.inf)


def check(watches: Any) -> tuple[Watch, ...]:
    """The watches as a tuple, each a ``Watch`` (SimulationError otherwise)."""
    if isinstance(watches, Watch):
        watches = (watches,)
    try:
        out = tuple(watches or ())
    except TypeError:
        raise SimulationError(
            f"watches must be a sequence of legsim.relaxed.Watch objects, got {watches!r:.80}"
        ) from None
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


def stored_index(k: _Index) -> _Index:
    """The stored point at or after point k of ``refined``'s (k itself or the step's end); k an
    int or an array of them."""
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
    their pieces, (N, m) each, and its probes' times between the points, (N - 1, m, P)."""

    parts: np.ndarray
    rates: np.ndarray
    pieces: np.ndarray | None = None
    probes: np.ndarray | None = None


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

    def probes(self, watch: Watch) -> list[np.ndarray]:
        """The watch's probes between the points of each visit (``Watch.probes``, (N - 1, m, P)),
        in the visits' order: one call of the watch per mode, the times between two visits'
        points dropped."""
        out: list[np.ndarray] = [np.empty((0, 0, 0))] * self.count
        for mode, members, t, x, ends in self.groups:
            times = watch.probes(mode, t, x)
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
