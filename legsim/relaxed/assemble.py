"""The execution from the loop's buffers: segments from its visits and points, strips and
transitions from its crossing records, the run's end as a status and a message naming mode,
time and state, and the warnings a run owes its reader (accumulations, order-dependent
simultaneous crossings, time held in strips)."""

from __future__ import annotations

import functools
import gc
import math
from collections.abc import Callable
from typing import Any, TypeVar

import numpy as np

from ..errors import LegsimError, SimulationError
from ..execution import Execution, RunSoFar, RunWarning, Segment, Status, Strip, TransitionRecord, filled
from . import between, messages, watches
from .layout import (
    COUNTERS,
    END_BROKE_DOWN,
    END_FIELD_AT_ENTRY,
    END_FINISHED,
    END_GUARD_AT_ENTRY,
    END_GUARD_NAN,
    END_HALVING_EXHAUSTED,
    END_MAX_STEPS,
    END_MAX_TRANSITIONS,
    END_NON_FINITE_STEP,
    END_RESET_BROKE_DOWN,
    END_RESET_NON_FINITE,
    END_RESET_OUTSIDE,
    END_STALLED,
    F_H_TRIED,
    F_STRIP_TIME,
    F_T,
    I_END,
    I_END_COUNT,
    I_END_INDEX,
    I_MODE,
    I_PHASE,
    I_POINTS,
    I_RECORDS,
    I_TRANSITIONS,
    I_VISITS,
    KIND_CONTINUED,
    KIND_CUT,
    KIND_JOINT,
    KIND_JOINT_CONTINUED,
    M_DIM,
    M_J0,
    M_T0,
    PHASE_STEP,
    R_ACCUMULATES,
    R_DEPTH,
    R_DIM_AFTER,
    R_DIM_BEFORE,
    R_EXIT,
    R_HAS_CONTINUATION,
    R_INDEX,
    R_JOINT,
    R_KIND,
    R_LANDING,
    R_ORDER_A,
    R_ORDER_B,
    R_SOURCE,
    R_TARGET,
    R_TIME,
    V_FIRST,
    V_MODE,
)
from .loop import STALL_FRACTION, STALL_WINDOW
from .simultaneous import OrderWatch
from .zeno import ZenoWatch, strip_hold_warning, unconfirmed_continuation

#: A stall within this many strip widths of a guard is reported next to it.
STALL_NEAR_STRIPS = 100.0


_Method = TypeVar("_Method", bound=Callable[..., Any])


def cycle_collector_paused(method: _Method) -> _Method:
    """Run ``method`` with Python's cyclic garbage collector paused (restored after, if it was
    on). The records of a run become thousands of small objects, none of them in a cycle; each
    allocation counts towards the collector's thresholds, and with numba's and Pinocchio's
    objects in the heap the full collections they set off cost more than the objects (on
    oscillator Ex.2 without continuation, 7,448 transitions: 60 ms a run with the collector
    paused, 60 to 150 ms with it on). Reference counting still frees them as usual."""

    @functools.wraps(method)
    def paused(*args: Any, **kwargs: Any) -> Any:
        was_on = gc.isenabled()
        gc.disable()
        try:
            return method(*args, **kwargs)
        finally:
            if was_on:
                gc.enable()

    return paused  # type: ignore[return-value]


#: The ends a non-finite input of the controller can cause: through the field, in a step or at a
#: mode's entry.
INPUT_ENDINGS = (END_NON_FINITE_STEP, END_BROKE_DOWN, END_FIELD_AT_ENTRY)


class Assembly:
    """The pieces of an execution, gathered from the loop's buffers as they fill."""

    def __init__(self, system: Any, tables: Any, options: Any) -> None:
        self.system, self.tables, self.options = system, tables, options
        self.segments: list[Segment] = []
        self.strips: list[Strip] = []
        self.transitions: list[TransitionRecord] = []
        self.crossings: list[tuple[Any, ...]] = []
        self.in_strip = False
        self._open: OpenVisit | None = None
        #: The stop watches' scan: visits scanned whole, points of the next one scanned, and where
        #: one first held (visit index, stored point at or after it, time, watch).
        self._scanned = (0, 0)
        self._checked: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self.stopped: tuple[int, int, float, Any] | None = None
        #: Whether the caller's ``until`` held at a hand-back, the run ending there.
        self.until_held = False

    # -- draining ---------------------------------------------------------------------------
    @cycle_collector_paused
    def drain(self, ws: Any, final: bool) -> None:
        """Turn the buffers' contents into pieces and empty them; an open visit's last point
        stays (a crossing may yet move it onto q)."""
        n_points, n_visits = int(ws.iv[I_POINTS]), int(ws.iv[I_VISITS])
        open_visit = not final and ws.iv[I_PHASE] == PHASE_STEP and n_visits > 0
        self._records(ws)
        # The visits' rows as Python numbers at once (as the records'), the last one's end n_points.
        modes = ws.visits[:n_visits, V_MODE].tolist()
        ends = [*ws.visits[1:n_visits, V_FIRST].tolist(), n_points]
        first = int(ws.visits[0, V_FIRST]) if n_visits else 0
        # One copy of the stored points, whose rows the visits stored whole take as their own.
        stored = (ws.T[:n_points].copy(), ws.X[:n_points].copy(), ws.DX[:n_points].copy())
        widths = self._widths()
        for v in range(n_visits):
            mode, last = modes[v], ends[v]
            if v + 1 == n_visits and open_visit:
                self._extend(ws, mode, first, last - 1)
                break
            if self._open is None:  # a visit stored whole: its segment at once
                self._whole(stored, mode, widths[mode], first, last)
            else:
                self._extend(ws, mode, first, last)
                self._close()
            first = last
        if open_visit:
            mode = int(ws.visits[n_visits - 1, V_MODE])
            n = self._width(mode)
            ws.T[0] = ws.T[n_points - 1]
            ws.X[0, :n] = ws.X[n_points - 1, :n]
            ws.DX[0, :n] = ws.DX[n_points - 1, :n]
            ws.visits[0, V_MODE], ws.visits[0, V_FIRST] = mode, 0
            ws.iv[I_POINTS], ws.iv[I_VISITS] = 1, 1
        else:
            ws.iv[I_POINTS], ws.iv[I_VISITS] = 0, 0
        ws.iv[I_RECORDS] = 0

    def _width(self, mode: int) -> int:
        return int(self.tables.modes[mode, M_DIM]) + self.tables.memory

    def _widths(self) -> list[int]:
        """The state width of each registered mode, by row (``_width``)."""
        tables = self.tables
        return (tables.modes[: len(tables.names), M_DIM] + tables.memory).tolist()

    def _extend(self, ws: Any, mode: int, first: int, last: int) -> None:
        if self._open is None or self._open.mode != mode:
            self._close()
            self._open = OpenVisit(mode, self._width(mode))
        self._open.append(ws.T[first:last], ws.X[first:last], ws.DX[first:last])

    def _whole(self, stored: tuple[np.ndarray, ...], mode: int, n: int, first: int, last: int) -> None:
        """The segment of a visit whose points are all in the buffers (``_extend`` then ``_close``
        without the pieces' lists): rows of the drain's copy of the points (``stored``: t, x, dx),
        contiguous when the mode's state width n fills the buffers' width, else copied."""
        t, x, dx = stored
        if n == x.shape[1]:
            x, dx = x[first:last], dx[first:last]
        else:
            x, dx = x[first:last, :n].copy(), dx[first:last, :n].copy()
        self.segments.append(filled(Segment, mode=self.tables.names[mode], t=t[first:last], x=x, dx=dx))

    def _close(self) -> None:
        if self._open is None:
            return
        visit, self._open = self._open, None
        t, x, dx = visit.points(copy=True)
        self.segments.append(filled(Segment, mode=self.tables.names[visit.mode], t=t, x=x, dx=dx))

    def _records(self, ws: Any) -> None:
        # As Python numbers at once: indexing numpy rows field by field costs more than the records.
        count = int(ws.iv[I_RECORDS])
        if count == 0:
            return
        floats, ints = ws.rec_f[:count].tolist(), ws.rec_i[:count].tolist()
        modes = self.tables.modes[: len(self.tables.names)]
        rows = (modes[:, M_T0].tolist(), modes[:, M_J0].tolist())
        # One copy of the records' guard points and images, each record's state a row of it.
        states = (ws.rec_q[:count].copy(), ws.rec_x[:count].copy())
        for r in range(count):
            self._record(states, r, floats[r], ints[r], rows)

    def _record(self, states: tuple[np.ndarray, np.ndarray], r: int, f: list[float], i: list[int],
                rows: tuple[list[int], list[int]]) -> None:  # fmt: skip
        """Record r; ``states`` the records' guard points and images, ``rows`` the first
        transition and the first joint row of each mode (``M_T0``, ``M_J0``)."""
        tables = self.tables
        source, e, kind = i[R_SOURCE], i[R_INDEX], i[R_KIND]
        row = rows[0][source] + e
        if kind in (KIND_JOINT, KIND_JOINT_CONTINUED):
            name = tables.joint_names[rows[1][source] + i[R_JOINT]]
        elif kind == KIND_CONTINUED:
            name = tables.continuation_names[row]
        else:
            name = tables.transition_names[row]
        source_name = tables.names[source]
        q = states[0][r, : i[R_DIM_BEFORE]]
        tc, t_land, exit_time, tau = f[R_TIME], f[R_LANDING], f[R_EXIT], f[R_DEPTH]
        self.strips.append(filled(Strip, mode=source_name, name=name, time=tc, exit_time=exit_time, state=q,
                                  landing_time=t_land, depth=tau))  # fmt: skip
        if kind == KIND_CUT:
            self.in_strip = True
            self.cut_name = name
            return
        target = tables.names[i[R_TARGET]]
        image = states[1][r, : i[R_DIM_AFTER]]
        self.transitions.append(
            filled(TransitionRecord, name=name, source=source_name, target=target, index=e, time=tc,
                   landing_time=t_land, exit_time=exit_time, state_before=q, state_after=image, depth=tau)
        )  # fmt: skip
        order = (i[R_ORDER_A], i[R_ORDER_B])
        # A continuation's crossing is named by the continuation; its transition's name is kept
        # for the accumulation it continues.
        transition = tables.transition_names[row] if kind == KIND_CONTINUED else name
        self.crossings.append(
            (source_name, name, tc, exit_time, bool(i[R_ACCUMULATES]),
             kind in (KIND_CONTINUED, KIND_JOINT_CONTINUED),
             bool(i[R_HAS_CONTINUATION]), order, q, transition)
        )  # fmt: skip

    # -- the execution ------------------------------------------------------------------------
    @cycle_collector_paused
    def execution(self, ws: Any, steps: list[int], wall: float, python_reason: str) -> Execution:
        """The execution, with its status, message, counters, settings and warnings; ``steps``
        the steps taken by the compiled kernel and by the Python loop."""
        self._close()
        self.check_stops()
        if self.stopped is not None:
            status, message, t_end = self._cut()
        elif self.until_held:
            t_end = float(ws.fs[F_T])
            status, message = Status.FINISHED, f"ended at t={t_end:.17g}, where the caller's until held"
        else:
            status, message = self.ending(ws)
            t_end = float(ws.fs[F_T])
        counters: dict[str, float] = {name: int(ws.iv[slot]) for name, slot in COUNTERS}
        counters.update(
            transitions=int(ws.iv[I_TRANSITIONS]),
            strip_time=float(ws.fs[F_STRIP_TIME]),
            compiled_steps=steps[0],
            python_steps=steps[1],
            wall_time_s=wall,
        )
        jumps = len(self._jumps())
        if jumps:  # only where a model crosses its guards' jumps (ModeFunctions.crosses_jumps)
            counters["guard_jumps"] = jumps
        # A run that took no step at all (t_final = t0) is on the path its tables chose.
        compiled = steps[1] == 0 and (steps[0] > 0 or not python_reason)
        options = self.options
        run_settings = {
            "h": options.h,
            "eps": options.eps,
            "method": options.tableau.name,
            "rtol": options.rtol,
            "atol": options.atol,
            "landing": options.landing,
            "max_transitions": options.max_transitions,
            "control": self.tables.control is not None or self.tables.law is not None,
            "continuation": options.continuation,
            "zeno_window": options.zeno_window,
            "path": "compiled" if compiled else "python",
        }
        if not compiled:
            run_settings["python_reason"] = python_reason or "the run asked for the Python loop"
        warnings = [w for w in self.warnings(t_end) if w.time <= t_end]
        self._watch_results(warnings, counters)
        names, units = self.state_names()
        return Execution(
            status=status,
            message=message,
            segments=self.segments,
            strips=self.strips,
            transitions=self.transitions,
            t0=options.t0,
            t_end=t_end,
            t_final=options.t_final,
            counters=counters,
            settings=run_settings,
            state_names=names,
            system_name=self.system.name,
            final_in_strip=self.in_strip,
            warnings=warnings,
            state_units=units,
        )

    # -- watches (``watches``) -------------------------------------------------------------------
    def _visits(self, first: int) -> list[tuple[int, str, np.ndarray, np.ndarray, np.ndarray]]:
        """(index, mode, t, x, dx) of the visits from ``first`` on, the open one included."""
        out = [(i, s.mode, s.t, s.x, s.dx) for i, s in enumerate(self.segments) if i >= first]
        if self._open is not None and self._open.size:
            out.append((len(self.segments), self.tables.names[self._open.mode], *self._open.points()))
        return out

    def _checked_points(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """Segment i's stored points and its steps' middles (``watches.refined``), made once: a
        closed segment does not change until a stop cuts it."""
        points = self._checked.get(i)
        if points is None:
            seg = self.segments[i]
            points = self._checked[i] = watches.refined(seg.t, seg.x, seg.dx)
        return points

    def check_stops(self) -> bool:
        """Scan the points stored since the last scan, and the middles of their steps
        (``watches.refined``), for the stop watches; True once one held (``stopped``: the
        earliest, by its visit and its stored point at or after it)."""
        stops = [w for w in self.options.watches if w.action == "stop"]
        if self.stopped is not None or not stops:
            return self.stopped is not None
        done, points = self._scanned
        for i, mode, t, x, dx in self._visits(done):
            start = max(points - 1, 0) if i == done else 0
            stored = t[start:], x[start:], dx[start:]
            if i < len(self.segments):  # a closed visit: its checked points are kept for the warnings
                ct, cx = self._checked_points(i)
                checked = ct[2 * start :], cx[2 * start :]
            else:
                checked = watches.refined(*stored)
            found = [(hit.time, hit.k, w) for w in stops if (hit := between.first_hold(w, mode, checked, stored))]
            if found:
                when, k, watch = min(found, key=lambda item: item[0])
                self.stopped = (i, start + watches.stored_index(k), when, watch)
                return True
            self._scanned = (i, t.shape[0])
        return False

    def check_until(self) -> bool:
        """True once the caller's ``until`` holds on the run so far (``RunSoFar``: the closed
        visits and the open one's drained points)."""
        until = self.options.until
        if until is None or self.until_held:
            return self.until_held
        segments = list(self.segments)
        if self._open is not None and self._open.size:
            _, mode, t, x, dx = self._visits(len(self.segments))[-1]
            segments.append(Segment(mode, *_read_only(t, x, dx)))  # the run's own storage
        try:
            held = until(RunSoFar(self.options.t0, segments, list(self.transitions)))
        except LegsimError:
            raise
        except Exception as exc:
            raise SimulationError(f"until failed at t={segments[-1].t[-1] if segments else self.options.t0:.17g}: "
                                  f"{type(exc).__name__}: {exc}") from exc  # fmt: skip
        if not isinstance(held, (bool, np.bool_)):
            raise SimulationError(f"until must return True or False, got {type(held).__name__} {held!r:.80}")
        self.until_held = bool(held)
        return self.until_held

    def _cut(self) -> tuple[Status, str, float]:
        """Cut the execution where a stop watch first held: its status, message and time."""
        assert self.stopped is not None
        i, k, when, watch = self.stopped
        seg = self.segments[i]
        if k == 0:
            t, x, dx = seg.t[:1], seg.x[:1], seg.dx[:1]
        else:
            xk, dxk = watches.point(seg.t, seg.x, seg.dx, k, when)
            t = np.append(seg.t[:k], when)
            x, dx = np.vstack([seg.x[:k], xk]), np.vstack([seg.dx[:k], dxk])
        self.segments[i + 1 :] = []
        self.segments[i] = Segment(seg.mode, t, x, dx)
        self._checked.clear()
        self.strips = [s for s in self.strips if s.exit_time <= when]
        self.transitions = [tr for tr in self.transitions if tr.exit_time <= when]
        self.crossings = [c for c in self.crossings if c[3] <= when]
        self.in_strip = False
        return Status(watch.status), watch.says(when, seg.mode, x[-1].copy()), when

    def _watch_results(self, warnings: list[Any], counters: dict[str, float]) -> None:
        """The warn watches' warnings added to ``warnings``, the time watches' times to ``counters``."""
        if any(w.action == "warn" for w in self.options.watches):
            # Every visit is closed by now: each one's stored points and its steps' middles.
            visits = [(s.mode, *self._checked_points(i), s) for i, s in enumerate(self.segments)]
            warnings += self._watch_warnings(visits, watches.PointsByMode([(m, t, x) for m, t, x, _ in visits]))
        if any(w.action == "time" for w in self.options.watches):
            # Measured on the stored points' interpolant: a stretch inside one step is within a
            # counter's accuracy (O(h) a stretch), and the middles would double its cost.
            stored = [(i, s.mode, s.t, s.x, s.dx) for i, s in enumerate(self.segments)]
            counters.update(self._watch_times(stored, watches.PointsByMode([(m, t, x) for _, m, t, x, _ in stored])))

    def _watch_warnings(self, visits: list[Any], points: watches.PointsByMode) -> list[RunWarning]:
        """A warning for each warn watch that held: where it first did, and its least value;
        ``visits`` (mode, checked times, checked states, segment) and ``points``, the same by mode."""
        out = []
        for w in self.options.watches:
            if w.action != "warn":
                continue
            first = least = None
            parts_at: list[Any] = [None] * len(visits)
            if w.rate is None:
                values = points.values(w)
            else:  # the parts once: the condition's values are their least
                parts = points.values(w, "parts")
                values = [watches.condition(p) for p in parts]
                none = [None] * len(visits)
                pieces = points.values(w, "pieces") if w.piece is not None else none
                probes = points.probes(w) if w.probe is not None else none
                rates = points.values(w, "rates")
                parts_at = [watches.PartsAt(*at) for at in zip(parts, rates, pieces, probes, strict=True)]
            for (mode, t, x, seg), v, at in zip(visits, values, parts_at, strict=True):
                stored = seg.t, seg.x, seg.dx
                if first is None and (hit := between.first_hold(w, mode, (t, x), stored, v, at)) is not None:
                    k, when, inside = hit
                    state = x[0] if k == 0 else watches.point(*stored, watches.stored_index(k), when)[0]
                    first = (when, mode, state)
                    if inside is not None and (least is None or inside[2] < least[0]):
                        least = (inside[2], inside[0], mode, inside[1])
                k, low = watches.least_of(v)
                if least is None or low < least[0]:
                    least = (low, float(t[k]), mode, x[k].copy())
            if first is None or least is None:
                continue
            message = w.says(*first)
            if w.graded and least[1] != first[0]:
                message += f"; the most at t={least[1]:.17g}: {w.says(least[1], least[2], least[3])}"
            out.append(RunWarning(w.name, message, first[0], {"least_value": least[0], "least_time": least[1]}))
        return out

    def _watch_times(self, visits: list[Any], points: watches.PointsByMode) -> dict[str, float]:
        """The time each time watch's condition held along the flow (s); ``visits`` and
        ``points`` as ``_watch_warnings``'s."""
        times = {}
        for w in self.options.watches:
            if w.action == "time":
                values = points.values(w)
                times[w.counter] = sum(
                    watches.time_held(w, mode, t, x, dx, v)
                    for (_, mode, t, x, dx), v in zip(visits, values, strict=True)
                )
        return times

    def state_names(self) -> tuple[dict[str, tuple[str, ...]], dict[str, tuple[str, ...]]]:
        """The coordinate names and units of every mode visited (the memory's last)."""
        law = self.tables.law
        extra_names = () if law is None else tuple(law.memory_names)
        extra_units = () if law is None else tuple(law.memory_units)
        names: dict[str, tuple[str, ...]] = {}
        units: dict[str, tuple[str, ...]] = {}
        for seg in self.segments:
            if seg.mode not in names:
                mode = self.system.mode(seg.mode)
                names[seg.mode] = mode.names + extra_names
                units[seg.mode] = mode.units + extra_units
        return names, units

    def warnings(self, t_end: float) -> list[Any]:
        """Accumulations without continuation, order-dependent simultaneous crossings, and time
        held in strips (replayed from the crossings in order)."""
        strip_time = sum(s.exit_time - s.time for s in self.strips)
        # The Zeno watch opens an episode only at an accumulating crossing: without one it has
        # nothing to say, and most runs skip its replay.
        replays_zeno = any(crossing[4] for crossing in self.crossings)
        out = self._zeno_warnings(t_end, strip_time) if replays_zeno else []
        out += self._order_warnings()
        held = strip_hold_warning(strip_time, self.options.t0, t_end, out)
        return out + ([held] if held is not None else [])

    def _zeno_warnings(self, t_end: float, strip_time: float) -> list[Any]:
        """The Zeno watch's warnings, the crossings replayed in order, and those of continuations
        taken where the crossings' history did not confirm an accumulation."""
        zeno = ZenoWatch(self.options.zeno_window, self.options.continuation)
        replay = _Replay()
        unconfirmed = []
        for source, name, tc, exit_time, accumulates, continued, has_cont, _, _, transition in self.crossings:
            if continued and transition != name:
                history = zeno.history(source, transition)
                said = unconfirmed_continuation(history, source, transition, name, tc, zeno.window)
                unconfirmed += [said] if said is not None else []
            replay.transitions.append(None)
            replay.strip_time += exit_time - tc
            zeno.crossed(replay, source, name, tc, exit_time, accumulates, continued, has_cont)
        replay.strip_time = strip_time
        return zeno.warnings(replay, t_end) + unconfirmed

    def _order_warnings(self) -> list[Any]:
        """The warnings of simultaneous crossings whose order changes the state (``OrderWatch``)."""
        pairs = [crossing for crossing in self.crossings if crossing[7][0] >= 0 and crossing[7][1] >= 0]
        if not pairs:
            return []
        order = OrderWatch()
        for source, _, tc, _, _, _, _, pair, q, _ in pairs:
            order.check(self.system.mode_data(source), list(pair), q[: self.system.mode(source).dim], tc)
        return order.warnings()

    def _jumps(self) -> list[TransitionRecord]:
        """The transitions crossed where their guard jumped past its strip (depth beyond eps)."""
        return [tr for tr in self.transitions if tr.depth > self.options.eps]

    # -- the end --------------------------------------------------------------------------------
    def ending(self, ws: Any) -> tuple[Status, str]:
        """How the run ended, and the message naming mode, time and state."""
        reason, index = int(ws.iv[I_END]), int(ws.iv[I_END_INDEX])
        if reason == END_FINISHED:
            return Status.FINISHED, ""
        tables = self.tables
        mode = int(ws.iv[I_MODE])
        name = tables.names[mode]
        n = self._width(mode)
        t, x = float(ws.fs[F_T]), ws.x[:n].copy()
        transition = self._transition_name(mode, index)
        breakdown = tables.breakdowns.last
        if reason == END_MAX_TRANSITIONS:
            return Status.MAX_TRANSITIONS, (
                f"transition budget max_transitions={self.options.max_transitions} used up at t={t:.17g} "
                f"(next transition {transition} from mode '{name}')"
            )
        if reason == END_MAX_STEPS:
            return Status.MAX_STEPS, (
                f"step budget max_steps={self.options.max_steps} used up at t={t:.17g} in mode '{name}' "
                f"(x={x.tolist()})"
            )
        if reason == END_STALLED:
            return Status.STALLED, self._stalled(ws, name, t, x)
        if reason == END_HALVING_EXHAUSTED:
            known = 0 <= index < ws.g_here.shape[0]
            guards = (float(ws.g_here[index]), float(ws.g1[index])) if known else (math.nan, math.nan)
            return Status.HALVING_EXHAUSTED, messages.halving_exhausted(
                name, t, x, int(ws.iv[I_END_COUNT]), float(ws.fs[F_H_TRIED]), transition, self.options.eps, guards
            )
        # A non-finite input is to blame before whatever a nan of the model would mean.
        unfed = self._input_not_finite(ws, name, t) if reason in INPUT_ENDINGS else None
        if unfed is not None:
            return Status.NON_FINITE, unfed
        if reason == END_NON_FINITE_STEP:
            return Status.NON_FINITE, messages.non_finite_step(name, t, x, float(ws.fs[F_H_TRIED]))
        if reason == END_BROKE_DOWN:
            why = breakdown if breakdown is not None else self.model_range(name, x)
            return Status.MODEL_BREAKDOWN, messages.model_breakdown(why, name, t, float(ws.fs[F_H_TRIED]))
        if reason == END_GUARD_NAN:
            x1 = ws.x1[:n].copy()
            return Status.NON_FINITE, messages.nan_guard(name, t + float(ws.fs[F_H_TRIED]), x1, transition)
        return self._entry_ending(ws, reason, name, transition, t, x, breakdown)

    def _entry_ending(self, ws: Any, reason: int, name: str, transition: str, t: float, x: np.ndarray,
                      breakdown: Any) -> tuple[Status, str]:  # fmt: skip
        if breakdown is not None and reason in (END_FIELD_AT_ENTRY, END_GUARD_AT_ENTRY):
            return Status.MODEL_BREAKDOWN, f"{breakdown} (mode '{name}', t={t:.17g})"
        if self._nan_breaks_at_entry(ws, reason, name, x):
            # As inside a step: a model that declares ``nan_breaks`` writes nan past its range.
            return Status.MODEL_BREAKDOWN, f"{self.model_range(name, x)} (entering mode '{name}', t={t:.17g})"
        if reason == END_FIELD_AT_ENTRY:
            return Status.NON_FINITE, messages.non_finite_field(name, t, x, ws.K[0, : x.shape[0]].copy())
        if reason == END_GUARD_AT_ENTRY:
            value = float(ws.g_here[int(ws.iv[I_END_INDEX])])
            return Status.NON_FINITE, messages.non_finite_guard(name, t, x, transition, value)
        if reason == END_RESET_OUTSIDE:
            g = float(ws.g_here[int(ws.iv[I_END_INDEX])])
            return Status.RESET_OUTSIDE_DOMAIN, (
                f"state entering mode '{name}' at t={t:.17g} lies past the guard of transition {transition} by "
                f"{-g:.3g} > eps={self.options.eps:g}: x={x.tolist()}"
            )
        last = self.transitions[-1] if self.transitions else None
        if reason == END_RESET_NON_FINITE and last is not None:
            return Status.NON_FINITE, (
                f"reset of transition {last.name} at t={last.exit_time:.17g} gives a non-finite state "
                f"{last.state_after.tolist()} from q={last.state_before.tolist()}"
            )
        assert reason == END_RESET_BROKE_DOWN, f"every END_* is handled ({reason})"
        why = breakdown if breakdown is not None else self.model_range(name, x)
        return Status.MODEL_BREAKDOWN, f"{why} (reset of transition {transition} from mode '{name}', t={t:.17g})"

    def _stalled(self, ws: Any, name: str, t: float, x: np.ndarray) -> str:
        data = self.tables.datas[int(ws.iv[I_MODE])]
        nearest = ""
        eps, h, tried = self.options.eps, self.options.h, float(ws.fs[F_H_TRIED])
        if data is not None and data.transitions:
            e = int(np.argmin(ws.g_here[: len(data.transitions)]))
            if ws.g_here[e] <= STALL_NEAR_STRIPS * eps:
                nearest = f" next to the guard of transition {data.transitions[e].name} ({ws.g_here[e]:.3g})"
        head = (
            f"the run stopped advancing in mode '{name}'{nearest}: its last {STALL_WINDOW} steps and crossings "
            f"moved time by less than {STALL_FRACTION:g} of h = {h:g} s, to t={t:.17g} (x={x.tolist()})"
        )
        if self.options.rtol is not None and not nearest and tried < STALL_FRACTION * h:
            # No guard near: the error control, not a strip, holds the run.
            return (
                f"{head}; error control took the step down to {tried:.3g} s with no guard near: the field "
                f"jumps or switches at this state (a controller switching on the state can hold the flow on "
                f"its switching surface, a sliding mode), which no step resolves; a switch on time, a field "
                f"without the jump, or fixed steps run past it"
            )
        return f"{head}; a thicker strip (eps) or a shorter h lets steps land"

    def _transition_name(self, mode: int, index: int) -> str:
        tables = self.tables
        if index < 0 or tables.datas[mode] is None or index >= len(tables.datas[mode].transitions):
            return "?"
        return tables.datas[mode].transitions[index].name

    def _input_not_finite(self, ws: Any, mode: str, t: float) -> str | None:
        """Why the run ended, when the controller's last input to ``mode``'s functions is not
        finite (an entry it left unwritten is nan): the input, not the model, is then to blame,
        whatever a nan of the model means."""
        functions = self.system.mode(mode).functions
        u = ws.u[: functions.inputs] if functions is not None else ws.u[:0]
        if np.isfinite(u).all():
            return None
        return (
            f"the controller's input u={u.tolist()} in mode '{mode}' near t={t:.17g} is not finite "
            f"(an entry a ControlLaw's control leaves unwritten is nan)"
        )

    def _nan_breaks_at_entry(self, ws: Any, reason: int, mode: str, x: np.ndarray) -> bool:
        """Whether a run ended at a mode's entry by a nan of its field or of a guard, in a mode
        whose functions declare ``nan_breaks`` (a nan there means the state is past the model's
        range, as it does inside a step; an infinity stays non-finite)."""
        functions = self.system.mode(mode).functions
        if functions is None or not functions.nan_breaks:
            return False
        if reason == END_FIELD_AT_ENTRY:
            return bool(np.isnan(ws.K[0, : x.shape[0]]).any())
        if reason == END_GUARD_AT_ENTRY:
            return bool(np.isnan(ws.g_here[int(ws.iv[I_END_INDEX])]))
        return False

    def model_range(self, mode: str, x: np.ndarray) -> str:
        """Why a model function's nan ends the run, in words: the mode's ``range_note`` where its
        functions give one, a function's at x, the last state before the nan."""
        head = f"{self.system.name}: the state leaves the model's range of validity in mode '{mode}'"
        functions = self.system.mode(mode).functions
        note = functions.range_note if functions is not None else ""
        if callable(note):
            try:
                note = note(x)
            except Exception as exc:  # the run's status stands; only its explanation is lost
                note = f"(its range_note failed: {type(exc).__name__}: {exc})"
        return f"{head}: {note}" if note else head


class _Replay:
    """What ``ZenoWatch`` reads of a run while the crossings are replayed."""

    def __init__(self) -> None:
        self.transitions: list[None] = []
        self.strip_time = 0.0


def _read_only(*arrays: np.ndarray) -> list[np.ndarray]:
    """Read-only views of ``arrays``."""
    views = [a.view() for a in arrays]
    for view in views:
        view.flags.writeable = False
    return views


class OpenVisit:
    """The points of a visit still open at a hand-back, in arrays that double as they fill: a
    hand-back's checks read the visit so far as views, so a long visit costs its points once,
    not once per hand-back."""

    def __init__(self, mode: int, width: int, capacity: int = 256) -> None:
        self.mode, self.size = mode, 0
        self.t, self.x, self.dx = np.empty(capacity), np.empty((capacity, width)), np.empty((capacity, width))

    def append(self, t: np.ndarray, x: np.ndarray, dx: np.ndarray) -> None:
        """Add rows t (k,), and x, dx (k, >= width), their first width columns."""
        end = self.size + t.shape[0]
        if end > self.t.shape[0]:
            capacity = max(end, 2 * self.t.shape[0])
            self.t = np.resize(self.t, capacity)
            self.x, self.dx = (np.vstack([a, np.empty((capacity - a.shape[0], a.shape[1]))]) for a in (self.x, self.dx))
        width = self.x.shape[1]
        self.t[self.size : end], self.x[self.size : end], self.dx[self.size : end] = t, x[:, :width], dx[:, :width]
        self.size = end

    def points(self, copy: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(t, x, dx) of the rows so far: views, or arrays of their own with ``copy``."""
        rows = slice(0, self.size)
        views = self.t[rows], self.x[rows], self.dx[rows]
        return (views[0].copy(), views[1].copy(), views[2].copy()) if copy else views
