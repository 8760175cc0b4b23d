"""The result of a simulation: segments of flow, strips, transitions and counters.

An execution alternates *segments* (the computed flow in one mode between two transitions)
and *strips* (the relaxation interval of a transition, during which the state is held at the
guard point ``q`` until the reset is applied). Segment arrays are preallocated and grown by
doubling, never appended to one row at a time.

Dense output: each stored point keeps its derivative f(t, x), so ``sample`` interpolates with
cubic Hermite polynomials (error O(h^4) between steps, matching RK4) rather than the linear
interpolation of paper 000 Fig. 12 step 9, which would limit any off-grid comparison to O(h^2).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any, TypeVar

import numpy as np

from .errors import SimulationError

#: A frozen dataclass of the execution's records (``filled``).
_Record = TypeVar("_Record")


class Status(StrEnum):
    """How a run ended: ordinary ends of a simulation are result codes (as in diffrax), not
    exceptions. Each value is the string the JSON summaries carry."""

    FINISHED = "finished"  # reached t_final, or the caller's ``until`` held (``simulate``)
    MAX_TRANSITIONS = "max_transitions"  # the transition budget was used up
    HALVING_EXHAUSTED = "halving_exhausted"  # no halved step lands in the relaxed domain (outward tangent flow)
    NON_FINITE = "non_finite"  # a field, guard or reset produced inf/nan
    RESET_OUTSIDE_DOMAIN = "reset_outside_domain"  # a reset image lies past a guard of its target by more than eps
    MODEL_BREAKDOWN = "model_breakdown"  # the model raised ModelBreakdown (left its range of validity)
    MAX_STEPS = "max_steps"  # the step budget was used up (every step is stored: it bounds memory)
    STALLED = "stalled"  # time stopped advancing (a thousand steps moved it by less than a millionth of h)
    FELL = "fell"  # a fall condition held (legsim.relaxed.Watch; a scene's [fall] section)


#: The statuses' strings, in the order above.
STATUSES = tuple(status.value for status in Status)


def filled(cls: type[_Record], **values: Any) -> _Record:
    """An instance of the frozen dataclass ``cls`` (``Segment``, ``Strip``, ``TransitionRecord``)
    with every field given by name, its attributes set at once: what the generated ``__init__``
    does one field at a time through ``object.__setattr__`` (~0.1 us a field), which the loop's
    drain would pay for every segment, strip and transition of a run. The classes have no
    ``__post_init__``; the instance equals ``cls(**values)``."""
    record = object.__new__(cls)
    record.__dict__.update(values)
    return record


@dataclass(frozen=True)
class Segment:
    """The computed flow in one mode visit.

    Attributes
    ----------
    mode: mode name.
    t: times, shape (N,), strictly increasing (N >= 1).
    x: states, shape (N, n).
    dx: derivatives f(t, x) at the stored points, shape (N, n) (for dense output).
    """

    mode: str
    t: np.ndarray
    x: np.ndarray
    dx: np.ndarray

    @property
    def t_start(self) -> float:
        return float(self.t[0])

    @property
    def t_end(self) -> float:
        return float(self.t[-1])

    def interpolate(self, times: np.ndarray) -> np.ndarray:
        """Cubic Hermite interpolation at ``times`` (inside [t_start, t_end]); shape (len, n)."""
        times = np.asarray(times, dtype=float)
        if len(self.t) == 1:
            return np.repeat(self.x[:1], len(times), axis=0)
        idx = np.clip(np.searchsorted(self.t, times, side="right") - 1, 0, len(self.t) - 2)
        t0 = self.t[idx]
        dt = self.t[idx + 1] - t0
        s = ((times - t0) / dt)[:, None]
        return hermite_values(self.x[idx], self.dx[idx], self.x[idx + 1], self.dx[idx + 1], dt[:, None], s)

    def midpoints(self) -> tuple[np.ndarray, np.ndarray]:
        """The time (N - 1,) and state (N - 1, n) at the middle of each step, on the interpolant."""
        t0, t1 = self.t[:-1], self.t[1:]
        dt = (t1 - t0)[:, None]
        return 0.5 * (t0 + t1), hermite_values(self.x[:-1], self.dx[:-1], self.x[1:], self.dx[1:], dt, 0.5)


def hermite_values(x0: np.ndarray, d0: np.ndarray, x1: np.ndarray, d1: np.ndarray, dt: Any, s: Any) -> np.ndarray:
    """The cubic Hermite interpolant of steps of length dt (s) from (x0, slope d0) to (x1, d1)
    at fractions s of them; arrays broadcast (rows, n) against dt and s of shape (rows, 1)."""
    h00 = 2 * s**3 - 3 * s**2 + 1
    h10 = s**3 - 2 * s**2 + s
    h01 = -2 * s**3 + 3 * s**2
    h11 = s**3 - s**2
    values: np.ndarray = h00 * x0 + h10 * (d0 * dt) + h01 * x1 + h11 * (d1 * dt)
    return values


@dataclass(frozen=True)
class Strip:
    """A relaxation interval: the state is held at ``state`` (the guard point q) in ``mode``
    from ``time`` to ``exit_time`` (the end time of the run if the strip was cut short).

    ``landing_time`` is the end of the step that landed in the strip and ``depth`` its depth
    tau in guard units, so that the strip coordinate at time t in [landing_time, exit_time] is
    tau + (t - landing_time) (paper 000 Fig. 12, step 13), also for a strip cut by t_final.
    """

    mode: str
    name: str
    time: float
    exit_time: float
    state: np.ndarray
    landing_time: float = 0.0
    depth: float = 0.0


@dataclass(frozen=True)
class TransitionRecord:
    """One completed transition.

    Attributes
    ----------
    name: transition name; ``source``/``target``: mode names; ``index``: position of the
        transition among the source mode's outgoing transitions.
    time: strip entry, the time at which the step's interpolant meets the guard (s).
    landing_time: end of the step that landed in the strip (s).
    exit_time: strip exit, ``landing_time + eps - depth`` (``landing_time`` for a guard that jumped
        past its strip), when the reset was applied (s).
    state_before: the guard point q the reset was applied to (source dimension).
    state_after: the reset image R(q) (target dimension).
    depth: tau = -guard at the landing point, in guard units (0 <= tau <= eps; > eps where the
        guard jumped past its strip, ``ModeFunctions.crosses_jumps``).
    """

    name: str
    source: str
    target: str
    index: int
    time: float
    landing_time: float
    exit_time: float
    state_before: np.ndarray
    state_after: np.ndarray
    depth: float

    @property
    def edge(self) -> tuple[str, str]:
        return (self.source, self.target)


@dataclass(frozen=True)
class RunSoFar:
    """The part of a run computed so far, as ``simulate``'s ``until`` sees it.

    Attributes
    ----------
    t0: the run's start time (s).
    segments: the segments so far, the last one possibly still open (its points up to the one
        before the loop's current point, which a crossing may yet move onto its guard point).
    transitions: the transitions taken so far.
    """

    t0: float
    segments: list[Segment]
    transitions: list[TransitionRecord]


@dataclass(frozen=True)
class RunWarning:
    """Something a finished run cannot vouch for (no silent wrong answers).

    Attributes
    ----------
    kind: ``"accumulation"`` (transitions accumulate and the model names no continuation: past
        the accumulation point the relaxed execution holds the state), ``"strip_hold"`` (the
        state was held in strips for more than 1% of the run), ``"non_commuting_resets"``
        (simultaneous transitions whose resets give different states in the two orders),
        ``"unconfirmed_continuation"`` (a transition's continuation taken after a single flight
        as long as the step could resolve: nothing showed an accumulation there).
    message: what happened, where, and the remedy.
    time: when it began (s).
    details: the numbers behind the message (JSON-ready).
    """

    kind: str
    message: str
    time: float
    details: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        """The JSON form: kind, message, time and the details."""
        return {"kind": self.kind, "message": self.message, "time": self.time, **self.details}


@dataclass
class Samples:
    """The execution sampled at given times.

    ``modes[i]`` and ``states[i]`` are the mode and state at ``times[i]``; ``in_strip[i]`` is
    True when that time falls in a relaxation strip (the state is then the held guard point).
    """

    times: np.ndarray
    modes: list[str]
    states: list[np.ndarray]
    in_strip: np.ndarray

    def stack(self) -> np.ndarray:
        """States as one array (len(times), n); raises when the dimension changes between modes."""
        dims = {len(s) for s in self.states}
        if len(dims) > 1:
            raise SimulationError(f"cannot stack samples of different dimensions {sorted(dims)}; use .states")
        return np.array(self.states).reshape(len(self.states), -1)


class SegmentBuffer:
    """Growable preallocated storage for one segment (internal to the integrator)."""

    __slots__ = ("dx", "mode", "size", "t", "x")

    def __init__(self, mode: str, dim: int, capacity: int = 256) -> None:
        self.mode = mode
        self.t = np.empty(capacity)
        self.x = np.empty((capacity, dim))
        self.dx = np.empty((capacity, dim))
        self.size = 0

    def append(self, t: float, x: np.ndarray, dx: np.ndarray) -> None:
        if self.size == len(self.t):
            new = 2 * len(self.t)
            self.t = np.resize(self.t, new)
            self.x = np.resize(self.x, (new, self.x.shape[1]))
            self.dx = np.resize(self.dx, (new, self.dx.shape[1]))
        i = self.size
        self.t[i] = t
        self.x[i] = x
        self.dx[i] = dx
        self.size = i + 1

    def last_time(self) -> float:
        return float(self.t[self.size - 1])

    def freeze(self) -> Segment:
        n = self.size
        return Segment(self.mode, self.t[:n].copy(), self.x[:n].copy(), self.dx[:n].copy())


@dataclass
class Execution:
    """A computed (relaxed, discrete) execution of a hybrid system.

    Attributes
    ----------
    status: one of ``STATUSES``; ``message``: a human explanation when status != finished.
    segments, strips, transitions: the pieces of the execution in time order.
    t0: start time; t_end: time reached (s); t_final: time requested (s).
    counters: steps, halvings, field_evals, guard_evals, reset_evals, strip_time, ...
    settings: h, eps, method and the other arguments of the run.
    state_names: coordinate names per mode visited; ``state_units``: their units (``Mode.units``).
    system_name: name of the simulated system.
    """

    status: str
    message: str
    segments: list[Segment]
    strips: list[Strip]
    transitions: list[TransitionRecord]
    t0: float
    t_end: float
    t_final: float
    counters: dict[str, float]
    settings: dict[str, Any]
    state_names: dict[str, tuple[str, ...]]
    system_name: str = ""
    final_in_strip: bool = False
    _final: tuple[str, np.ndarray] | None = field(default=None, repr=False)
    warnings: list[RunWarning] = field(default_factory=list)
    evaluated: Samples | None = None
    state_units: dict[str, tuple[str, ...]] = field(default_factory=dict)

    # -- the summary a user asks for --------------------------------------------------------
    @property
    def final_mode(self) -> str:
        """Mode at t_end (the source mode if the run ended inside a strip)."""
        return self._final_pair()[0]

    @property
    def final_state(self) -> np.ndarray:
        """State at t_end (the held guard point if the run ended inside a strip)."""
        return self._final_pair()[1].copy()

    def _final_pair(self) -> tuple[str, np.ndarray]:
        if self._final is not None:
            return self._final
        if self.final_in_strip and self.strips:
            last = self.strips[-1]
            return last.mode, last.state
        seg = self.segments[-1]
        return seg.mode, seg.x[-1]

    @property
    def mode_sequence(self) -> list[str]:
        """Modes visited, in order (one entry per segment)."""
        return [s.mode for s in self.segments]

    @property
    def succeeded(self) -> bool:
        """True when the run reached t_final."""
        return self.status == "finished"

    @property
    def steps(self) -> int:
        return int(self.counters.get("steps", 0))

    @property
    def halvings(self) -> int:
        return int(self.counters.get("halvings", 0))

    def strip_intervals(self) -> list[tuple[float, float]]:
        """(entry, exit) times of every strip, the last one possibly cut by t_end."""
        return [(s.time, s.exit_time) for s in self.strips]

    def raise_for_status(self) -> Execution:
        """Raise ``SimulationError`` with the message unless the run finished."""
        if self.status != "finished":
            raise SimulationError(f"simulation stopped with status '{self.status}': {self.message}")
        return self

    # -- sampling --------------------------------------------------------------------------
    def _pieces(self) -> tuple[np.ndarray, list[tuple[str, int]]]:
        # An execution alternates segment, strip, segment, strip, ... by construction (a
        # transition ends a segment and opens a strip; the next segment starts at its exit).
        # Order the pieces that way rather than by start time, so that zero-length strips
        # and segments (simultaneous transitions) keep their place; a time then belongs to the
        # last piece starting at or before it, which makes the execution right-continuous.
        starts: list[float] = []
        kinds: list[tuple[str, int]] = []
        for i, seg in enumerate(self.segments):
            starts.append(seg.t_start)
            kinds.append(("seg", i))
            if i < len(self.strips):
                starts.append(self.strips[i].time)
                kinds.append(("strip", i))
        return np.array(starts), kinds

    def sample(self, times: Iterable[float] | float) -> Samples:
        """Mode and state at each of ``times`` (s), which must lie in [t0, t_end].

        Between steps the state is the cubic Hermite interpolant of the step ends; inside a
        strip it is the held guard point. At a strip exit the state is the reset image.
        """
        arr = np.atleast_1d(np.asarray(times, dtype=float))
        if arr.ndim != 1:
            raise SimulationError(f"sample times must be a 1-d sequence, got shape {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise SimulationError("sample times must be finite")
        tol = 1e-12 * max(1.0, abs(self.t_end))
        if arr.size and (arr.min() < self.t0 - tol or arr.max() > self.t_end + tol):
            raise SimulationError(
                f"sample times must lie in [{self.t0}, {self.t_end}] (the executed interval), "
                f"got [{arr.min()}, {arr.max()}]"
            )
        starts, kinds = self._pieces()
        which = np.clip(np.searchsorted(starts, arr, side="right") - 1, 0, len(kinds) - 1)
        modes: list[str] = [""] * len(arr)
        states: list[np.ndarray] = [np.empty(0)] * len(arr)
        in_strip = np.zeros(len(arr), dtype=bool)
        for piece in np.unique(which):
            sel = np.nonzero(which == piece)[0]
            kind, k = kinds[piece]
            if kind == "seg":
                seg = self.segments[k]
                values = seg.interpolate(np.clip(arr[sel], seg.t_start, seg.t_end))
                for row, i in enumerate(sel):
                    modes[i] = seg.mode
                    states[i] = values[row]
            else:
                strip = self.strips[k]
                for i in sel:
                    modes[i] = strip.mode
                    states[i] = strip.state.copy()
                    in_strip[i] = True
        return Samples(arr, modes, states, in_strip)

    def state_at(self, t: float) -> tuple[str, np.ndarray]:
        """(mode, state) at time t."""
        s = self.sample([t])
        return s.modes[0], s.states[0]

    def step_times(self) -> np.ndarray:
        """All computed time points (segment points), in order."""
        return np.concatenate([s.t for s in self.segments])
