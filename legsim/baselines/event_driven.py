"""The simulator users would otherwise write: scipy's ``solve_ivp`` with event functions.

Each mode runs in ``solve_ivp`` with one terminal event per outgoing guard (direction -1: the
guard decreasing through zero). At an event the reset is applied to the located event state
and the integration restarts in the target mode. This is the standard event-driven approach,
made as good as it reasonably gets so that comparisons against it mean something:

* tolerance-controlled (any ``solve_ivp`` method, rtol/atol),
* simultaneous events: after each reset the target's guards are checked at the new state;
  a guard that is already at or past zero and decreasing along the flow fires at once (the
  restart would otherwise miss it, because ``solve_ivp`` only sees sign changes *during* a step),
* a transition cap, and an honest stop when events accumulate (Zeno): the run ends with status
  ``max_transitions`` rather than looping forever; a self-transition whose reset leaves the state
  unchanged (a graze at zero speed) is not fired again on that same state,
* a trial step that leaves the model's range (``ModelBreakdown`` from a field or guard) ends the
  run with status ``model_breakdown``,
* a ``legsim.control.Controller`` (or a ``ControlLaw``, run as one: ``LawController``) runs as
  in the relaxed integrator (``legsim.control.bind``): told the mode, reset at the start and at
  every mode entry (each transition of a chain), evaluated wherever the field or a guard is,
  and at each event, whose reset (written as model functions) takes its input there. A
  held controller (``hold=True``) is refused: its value is sampled at the start of each step,
  and solve_ivp's steps are not the integrator's to sample.

It returns a ``legsim.Execution`` so that the same metric and error code apply to it.
"""

from __future__ import annotations

import math
import time as _time
from collections.abc import Callable
from typing import Any, Literal, cast

import numpy as np
from scipy.integrate import solve_ivp

from ..control import Bound, ControlLaw, Controller, LawController, bind
from ..errors import ModelBreakdown, SimulationError
from ..execution import Execution, Segment, Strip, TransitionRecord
from ..hybrid import HybridSystem, Transition

#: solve_ivp's explicit methods that make sense for these non-stiff models.
METHODS = ("RK23", "RK45", "DOP853", "LSODA", "Radau", "BDF")
IvpMethod = Literal["RK23", "RK45", "DOP853", "LSODA", "Radau", "BDF"]


class _GuardEvent:
    """A transition's guard as a terminal solve_ivp event, crossed downwards (scipy reads the
    ``terminal`` and ``direction`` attributes). Its evaluations are counted like the relaxed
    integrator's guard evaluations (every step end, every root-finding iterate), so that the
    bench compares like with like."""

    terminal = True
    direction = -1

    def __init__(self, transition: Transition, control: Any, counts: dict[str, int]) -> None:
        self.transition, self.control, self.counts = transition, control, counts

    def __call__(self, tt: float, y: np.ndarray) -> float:
        self.counts["guard_evals"] += 1
        tr = self.transition
        if tr.guard_args == "x":
            return tr.guard_fn()(y)
        return tr.guard_value(y, tt, None if self.control is None else self.control(tt, y))


def simulate_events(
    system: HybridSystem,
    x0: Any,
    mode: str,
    t_final: float,
    *,
    method: str = "RK45",
    rtol: float = 1e-6,
    atol: float = 1e-9,
    control: Controller | Callable[[float, np.ndarray], Any] | None = None,
    t0: float = 0.0,
    max_transitions: int = 10_000,
    max_step: float = math.inf,
    event_tol: float = 1e-10,
    dense_output: bool = False,
) -> Execution:
    """Event-driven simulation of ``system`` from ``(mode, x0)`` on [t0, t_final] with solve_ivp.

    Parameters
    ----------
    method, rtol, atol, max_step: passed to ``scipy.integrate.solve_ivp``.
    control: optional ``control(t, x) -> u`` passed to fields as their third argument, or a
        ``legsim.control.Controller`` (told the mode, ``reset`` at the start and at every mode
        entry); a Controller with ``hold=True`` raises SimulationError.
    max_transitions: transition cap; reaching it ends the run with status ``max_transitions``.
    event_tol: a guard within this of zero at a reset image, and decreasing along the flow,
        fires immediately (simultaneous events).
    dense_output: keep solve_ivp's own interpolant of each segment, so that ``sample`` between
        steps has the method's accuracy (the cubic Hermite interpolation of a plain
        ``Execution`` is only O(step^4), poor for the long steps of DOP853 at tight
        tolerances). Costs a little time inside solve_ivp: leave it off when timing.

    Returns
    -------
    Execution
        transitions have ``time == landing_time == exit_time`` (no strip) and depth 0;
        ``counters["wall_time_s"]`` covers the integration only, not the assembly of the
        returned arrays.
    """
    _check_arguments(method, rtol, atol, t0, t_final)
    control = _bound_control(control)
    x = system.check_state(mode, x0, t=t0, u=_initial_control(control, mode, t0, x0), label="x0")
    solver = {"method": cast(IvpMethod, method), "rtol": rtol, "atol": atol, "max_step": max_step}
    run = _EventRun(system, control, solver, dense_output, event_tol, max_transitions)
    wall0 = _time.perf_counter()
    run.start(mode, x, float(t0))
    while run.status == "finished" and run.flow(t_final):
        run.chain()
    wall = _time.perf_counter() - wall0 - run.pieces.seconds
    return _assemble(
        system,
        run.pieces.segments,
        run.transitions,
        run.status,
        run.message,
        t0,
        run.t,
        t_final,
        run.counts,
        wall,
        {"method": f"solve_ivp-{method}", "rtol": rtol, "atol": atol},
        run.dense if dense_output else None,
    )


def _check_arguments(method: str, rtol: float, atol: float, t0: float, t_final: float) -> None:
    """SimulationError naming the first bad argument of ``simulate_events``."""
    if method not in METHODS:
        raise SimulationError(f"unknown solve_ivp method {method!r}; choose one of {list(METHODS)}")
    for label, value in (("rtol", rtol), ("atol", atol)):
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise SimulationError(f"{label} must be finite and > 0, got {value!r}")
    if not (isinstance(t_final, (int, float)) and math.isfinite(t_final) and t_final > t0):
        raise SimulationError(f"t_final must be finite and > t0 = {t0}, got {t_final!r}")


class _EventRun:
    """One event-driven run: where it is (mode, x, t), what it has recorded, and how it ended
    (``status`` stays "finished" while it goes on)."""

    def __init__(
        self,
        system: HybridSystem,
        control: Any,
        solver: dict[str, Any],
        dense_output: bool,
        event_tol: float,
        max_transitions: int,
    ) -> None:
        self.system, self.control, self.solver, self.dense_output = system, control, solver, dense_output
        self.event_tol, self.max_transitions = event_tol, max_transitions
        self.counts = {"field_evals": 0, "guard_evals": 0, "reset_evals": 0, "steps": 0}
        self.pieces = _Segments(system, control)
        self.dense: list[Any] = []
        self.transitions: list[TransitionRecord] = []
        self.status, self.message = "finished", ""
        self.mode, self.x, self.t = "", np.empty(0), 0.0
        self.event: tuple[float, int, np.ndarray] | None = None

    def start(self, mode: str, x: np.ndarray, t: float) -> None:
        """Enter ``mode`` at (t, x): a Controller is reset and told the mode."""
        self.mode, self.x, self.t = mode, x, t
        _enter(self.control, mode, t, x)

    def flow(self, t_final: float) -> bool:
        """Integrate the current mode until its first guard event or t_final; True when an event
        ended it (``event``: its time, transition index and located state)."""
        mode, field, control = self.mode, self.system.mode(self.mode).field, self.control

        def fun(tt: float, y: np.ndarray) -> np.ndarray:
            return field(tt, y, None if control is None else control(tt, y))

        events = [_GuardEvent(tr, control, self.counts) for tr in self.system.outgoing(mode)]
        try:
            sol = solve_ivp(
                fun, (self.t, t_final), self.x, events=events or None, dense_output=self.dense_output, **self.solver
            )
        except ModelBreakdown as exc:
            # A trial step of solve_ivp left the model's range (e.g. a runner's body through the
            # ground): the solver cannot shorten a step on such grounds, so the run ends here.
            self.status, self.message = "model_breakdown", f"{exc} (solve_ivp in mode '{mode}' after t={self.t:.17g})"
            self.add_point()
            return False
        self.counts["field_evals"] += sol.nfev
        self.counts["steps"] += max(len(sol.t) - 1, 0)
        self.pieces.add(mode, sol.t.copy(), sol.y.T.copy())
        self.dense.append(sol.sol)
        if sol.status == -1:
            self.status = "non_finite"
            self.message = f"solve_ivp failed in mode '{mode}' at t={sol.t[-1]:.17g}: {sol.message}"
            return False
        if sol.status == 0:
            self.t = float(sol.t[-1])
            return False
        assert sol.t_events is not None and sol.y_events is not None  # status 1: a terminal event fired
        t_event, e = min((float(te[0]), i) for i, te in enumerate(sol.t_events) if len(te))
        self.event = (t_event, e, np.asarray(sol.y_events[e][0], dtype=np.float64))
        return True

    def chain(self) -> None:
        """Take the event's transition, and the further ones whose guards the reset images sit
        on at the same instant."""
        assert self.event is not None
        t_event, e, q = self.event
        while True:
            if len(self.transitions) >= self.max_transitions:
                self.status = "max_transitions"
                self.message = (
                    f"transition cap max_transitions={self.max_transitions} reached at t={t_event:.17g} "
                    f"(events accumulate: Zeno)"
                )
                return
            tr = self.system.outgoing(self.mode)[e]
            self.counts["reset_evals"] += 1
            after = tr.image(q, t_event, None if self.control is None else self.control(t_event, q))
            self.transitions.append(
                TransitionRecord(
                    tr.name, self.mode, tr.target, e, t_event, t_event, t_event, q.copy(), after.copy(), 0.0
                )
            )
            fixed_point = tr.target == self.mode and np.array_equal(after, q)
            self.start(tr.target, after, t_event)
            if not np.all(np.isfinite(after)):
                self.status, self.message = (
                    "non_finite",
                    f"reset gave a non-finite state at t={t_event:.17g}: {after.tolist()}",
                )
                return
            nxt = _firing_at_entry(self.system, self.mode, after, t_event, self.control, self.event_tol, self.counts)
            if nxt is None or (fixed_point and self.system.outgoing(self.mode)[nxt] is tr):
                # A self-transition whose reset left the state unchanged would fire again on the
                # same state forever (a graze at zero speed): firing it once is all it can do.
                return
            e, q = nxt, after.copy()
            # A zero-length segment keeps the execution's segment/strip alternation.
            self.add_point()

    def add_point(self) -> None:
        """A zero-length segment at the current state (no interpolant)."""
        self.pieces.add(self.mode, np.array([self.t]), np.asarray(self.x, dtype=float).reshape(1, -1).copy())
        self.dense.append(None)


def _bound_control(control: Any) -> Any:
    """What the loop calls as ``u(t, x)``: the control itself, or a Controller bound to the mode;
    SimulationError for anything else and for a held Controller. A ``ControlLaw`` runs as a
    ``LawController``."""
    if isinstance(control, ControlLaw):
        control = LawController(control)
    if control is not None and not callable(control):
        raise SimulationError(
            f"control must be callable control(t, x) -> u or None, got {type(control).__name__}; "
            f"a legsim.control.Controller also does"
        )
    bound = bind(control)
    if isinstance(bound, Bound) and bound.hold:
        raise SimulationError(
            f"controller {type(control).__name__} has hold=True (a zero-order hold sampled at each "
            f"step's start), which solve_ivp cannot run: its steps are its own and a held value "
            f"would change the field inside them; run it with legsim.relaxed.simulate, or set hold=False"
        )
    return bound


def _initial_control(control: Any, mode: str, t0: float, x0: Any) -> Any:
    """The control at the start, for checking x0: a Controller is not entered yet (the run
    enters the mode when it starts), so it is asked directly."""
    x = np.asarray(x0, dtype=float)
    if isinstance(control, Bound):
        return control.controller(mode, t0, x)
    return None if control is None else control(t0, x)


def _enter(control: Any, mode: str, t: float, x: np.ndarray) -> None:
    """The run enters ``mode`` at (t, x): a Controller is reset and told the mode."""
    if isinstance(control, Bound):
        control.enter(mode, t, x)


def _firing_at_entry(system, mode, x, t, control, tol, counts) -> int | None:
    """Index of a guard of ``mode`` already at/past zero and decreasing at x, if any."""
    field = system.mode(mode).field
    best = None
    for i, tr in enumerate(system.outgoing(mode)):
        u = None if control is None else control(t, x)
        g = tr.guard_value(x, t, u)
        counts["guard_evals"] += 1
        if g < -tol:
            return i
        if g <= tol:
            f = np.asarray(field(t, x, None if control is None else control(t, x)), dtype=float)
            counts["field_evals"] += 1
            delta = 1e-7 / max(1.0, float(np.linalg.norm(f)))
            rate = (tr.guard_value(x + delta * f, t, u) - g) / delta
            counts["guard_evals"] += 1
            # A difference of two guard values carries their rounding: a rate within it (a graze
            # at zero speed, as at a release) tells no direction, and firing on it would cycle.
            rounding = 4.0 * np.finfo(float).eps * float(np.max(np.abs(x))) / delta
            if rate < -rounding and (best is None or g < best[0]):
                best = (g, i)
    return None if best is None else best[1]


class DenseExecution(Execution):
    """An event-driven execution that samples each segment with solve_ivp's own interpolant."""

    dense: list[Any] | None = None

    def sample(self, times):
        samples = super().sample(times)
        if not self.dense:
            return samples
        starts, kinds = self._pieces()
        which = np.clip(np.searchsorted(starts, samples.times, side="right") - 1, 0, len(kinds) - 1)
        for piece in np.unique(which):
            kind, k = kinds[piece]
            interpolant = self.dense[k] if kind == "seg" else None
            if interpolant is None:
                continue
            seg = self.segments[k]
            sel = np.nonzero(which == piece)[0]
            values = interpolant(np.clip(samples.times[sel], seg.t_start, seg.t_end))
            for row, i in enumerate(sel):
                samples.states[i] = np.array(values[:, row], dtype=float)
        return samples


class _Segments:
    """The run's segments, each with its derivatives evaluated when it is added, while a
    Controller is still in that segment's mode and memory; ``seconds`` is the time spent on
    them, which the run's reported wall time leaves out (it is the Execution's assembly)."""

    def __init__(self, system: HybridSystem, control: Any) -> None:
        self.system, self.control = system, control
        self.segments: list[Segment] = []
        self.seconds = 0.0

    def add(self, mode: str, ts: np.ndarray, xs: np.ndarray) -> None:
        """A segment of ``mode``: times ts (k,), states xs (k, n)."""
        start = _time.perf_counter()
        field, control = self.system.mode(mode).field, self.control
        dx = np.array(
            [field(tt, xx, None if control is None else control(tt, xx)) for tt, xx in zip(ts, xs, strict=True)],
            dtype=float,
        ).reshape(xs.shape)
        self.segments.append(Segment(mode, ts, xs, dx))
        self.seconds += _time.perf_counter() - start


def _assemble(system, segments, transitions, status, message, t0, t_end, t_final, counts, wall, settings, dense=None):
    strips = [Strip(tr.source, tr.name, tr.time, tr.exit_time, tr.state_before, tr.time, 0.0) for tr in transitions]
    counters = dict(counts, transitions=len(transitions), halvings=0, strip_time=0.0, wall_time_s=wall)
    names = {seg.mode: system.state_names(seg.mode) for seg in segments}
    fields = dict(
        status=status,
        message=message,
        segments=segments,
        strips=strips,
        transitions=transitions,
        t0=float(t0),
        t_end=float(t_end),
        t_final=float(t_final),
        counters=counters,
        settings=settings,
        state_names=names,
        system_name=system.name,
    )
    if dense is None:
        return Execution(**fields)
    execution = DenseExecution(**fields)
    execution.dense = dense
    return execution
