"""Conditions on a run's states checked at every stored point and step's middle (``Watch``): a
fall that ends the run, a state the model cannot vouch for that is reported, an interval that
is measured.

A watch is ``value(mode, t, x) -> v``, a function of each point alone, vectorised over points
of one mode (t of shape (N,), x of shape (N, n), the run's state: the plant's, then the
controller's memory; the points of one visit, or of all the mode's visits at once for the
warnings and times made at the end), and its condition *holds* where v < 0. The driver checks
the points as the loop hands its buffers back (every ``workspace.POINTS`` points at most, and
at the end), so the loop itself, compiled or not, is unchanged. The points a stop or a warning
is checked at are the stored ones and the middle of every step between them, on the step's interpolant
(``refined``): a condition that holds only inside a step (a foot carried through the ground and
out again by one coarse step) is seen wherever it holds at the step's middle. Where a condition
first holds between two checked points, the time is located by bisection on the points' cubic
Hermite interpolant (the one ``Execution.sample`` uses: O(h^4) between steps), to float64
resolution;
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
from typing import Any

import numpy as np

from ..errors import SimulationError
from ..execution import Segment, Status
from .single import hermite, hermite_derivative

ACTIONS = ("stop", "warn", "time")
#: Bisection steps locating a time (enough to reach float64's resolution of any step).
BISECTIONS = 64


@dataclass(frozen=True)
class Watch:
    """A condition on the run's states (module docstring).

    Attributes
    ----------
    name: the condition's name (a warning's kind).
    value: ``value(mode, t, x) -> v`` (N,), vectorised over one visit's points; < 0: it holds.
    action: ``"stop"``, ``"warn"`` or ``"time"``.
    message: ``message(t, mode, x) -> str`` at a point where it holds (stop, warn).
    status: the status a stop ends the run with (a ``Status`` value).
    counter: the counter a ``"time"`` watch fills (s).
    """

    name: str
    value: Callable[[str, np.ndarray, np.ndarray], np.ndarray]
    action: str = "stop"
    message: Callable[[float, str, np.ndarray], str] | None = None
    status: str = Status.FELL.value
    counter: str = ""

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

    def values(self, mode: str, t: np.ndarray, x: np.ndarray) -> np.ndarray:
        """v at the points (N,), float64; SimulationError naming the watch if it is no such array."""
        try:
            v = np.asarray(self.value(mode, t, x), dtype=float).reshape(-1)
        except Exception as exc:
            raise SimulationError(f"watch {self.name!r} failed in mode '{mode}': {type(exc).__name__}: {exc}") from exc
        if v.shape[0] != t.shape[0]:
            raise SimulationError(f"watch {self.name!r} gave {v.shape[0]} values for {t.shape[0]} points")
        return v


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


def first_hold(
    watch: Watch,
    mode: str,
    checked: tuple[np.ndarray, np.ndarray],
    stored: tuple[np.ndarray, np.ndarray, np.ndarray],
    values: Any = None,
) -> tuple[int, float] | None:
    """(k, time) where the condition first holds among a visit's ``checked`` points (``refined``
    of its ``stored`` points t, x, dx; k the checked point at or after it), or None; ``values``:
    v at the checked points when known."""
    t, x = checked
    if t.shape[0] == 0:
        return None
    v = watch.values(mode, t, x) if values is None else values
    below = np.flatnonzero(v < 0.0)
    if below.size == 0:
        return None
    k = int(below[0])
    if k == 0:
        return 0, float(t[0])
    return k, locate(watch, mode, *stored, stored_index(k), True, (float(t[k - 1]), float(t[k])))


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

    def values(self, watch: Watch) -> list[np.ndarray]:
        """v at the points of each visit, in the visits' order: one call of the watch per mode."""
        out: list[np.ndarray] = [np.empty(0)] * self.count
        for mode, members, t, x, ends in self.groups:
            for i, v in zip(members, np.split(watch.values(mode, t, x), ends), strict=True):
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
