"""A walk: run a gait's scene from one initial state, step after step, until it falls, settles
on a gait, or runs out of steps; the basin of attraction is a grid of walks.

A *step* is a return to the scene's Poincare section (its ``[orbit]`` section: just after a
transition, or a level crossing). The walk runs the relaxed integrator from transition to
transition (``simulate(..., max_transitions=0)`` stops at the guard point q of the next one);
it takes that transition itself as the integrator would (the state held at q until the strip's
exit time ``t_land + eps - tau``, then the reset applied to q) and goes on from the reset
state, so each step costs its own flow and nothing more, and a walk that has converged stops
there. Its runs use the orbit problem's settings (h, eps, method, tolerances, as
``legsim.orbits.ReturnMap`` does), so that the reference gait found by ``find_orbit`` is a
fixed point of exactly these steps.

A scene with a controller is walked through its return map instead (``ReturnMap``): a transition
of the closed loop also resets the controller and updates its memory, which only a run of
``simulate`` with the controller carries. Each step is then one return, run from the last one's
state with the controller restored to the memory it had there (each return restarts the clock,
so an epoch less the time walked), which is how a continuous run of the scene goes on (checked
to 1e-10 s and 1e-8 against one, ``tests/sweep``). Its runs end soon after the return (at the
loop's first hand-back past it, ``simulate``'s ``until``), and its counters count them whole;
its warnings are those up to each return, their
times measured from the return's start. Its returns are compared by the plant's state (the
controller's memory, in the returns' frames, follows it); each return may take the problem's
``max_transitions``, past which the walk ``stops``.

Outcomes (``OUTCOMES``):

* ``converges``: a return within ``tol`` of the reference gait's fixed point (Euclidean norm
  over the coordinates that the orbit equations ask to be periodic, i.e. without the cyclic
  and section coordinates; mixed units, as the orbit's own tolerance);
* ``other_gait``: returns repeating with a period p <= ``MAX_PERIOD`` away from the reference
  gait (within ``tol`` and ``REPEAT_SHARE`` of their distance to it, so that a slow approach to
  the gait is not taken for a gait of its own): e.g. a period-two gait past a period doubling;
* ``falls``: the model broke down (a compass gait's hip below the slope: status
  ``model_breakdown``), or a condition of the scene's ``[fall]`` held (status ``fell``);
* ``stops``: no return within the section's ``t_max`` of the last one, more than
  ``MAX_TRANSITIONS_WITHOUT_RETURN`` transitions without one (a rimless wheel rocking to rest),
  or ``CHATTER_RETURNS`` returns in a row less than ``MIN_RETURN_STEPS`` steps apart (a compass
  gait whose legs scissor together, heel strikes accumulating: it chatters in place);
* ``undecided``: ``max_steps`` steps without any of the above;
* ``failed``: the run ended otherwise (``non_finite``, ``halving_exhausted``,
  ``reset_outside_domain``): the integrator's status says why.
"""

from __future__ import annotations

import copy
import math
from collections import defaultdict
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..crossings import first_crossing
from ..errors import ModelBreakdown, ModelError, SimulationError
from ..execution import Execution, Status, Strip
from ..orbits import OrbitError, OrbitProblem
from ..orbits.returns import ReturnMap, shift_frames
from ..relaxed import simulate
from ..relaxed.rules import strip_exit_time

OUTCOMES = ("converges", "other_gait", "falls", "stops", "undecided", "failed")

#: Longest period (in returns) that counts as another gait.
MAX_PERIOD = 4

#: Returns repeat (another gait) when they differ by less than tol and than this share of their
#: distance to the reference gait.
REPEAT_SHARE = 0.01

#: Returns closer than this many steps h are not a gait's: ``CHATTER_RETURNS`` of them in a row
#: are a walk chattering in place (a compass gait whose legs scissor together, its heel
#: strikes accumulating as in a Zeno execution).
MIN_RETURN_STEPS = 10
CHATTER_RETURNS = 3

#: Transitions without a return after which a walk has stopped walking (rocking, chattering).
MAX_TRANSITIONS_WITHOUT_RETURN = 50

#: A controlled walk's outcome where a return's run ended before returning, by its status.
RUN_OUTCOMES = {Status.MODEL_BREAKDOWN: "falls", Status.FELL: "falls", Status.MAX_TRANSITIONS: "stops"}

#: Counters of the integrator's runs that a walk adds up.
COUNTERS = ("steps", "halvings", "field_evals", "guard_evals", "reset_evals", "error_rejections")


@dataclass
class WalkResult:
    """How a walk ended.

    outcome: one of ``OUTCOMES``; status, message: the last run's status and message (or why the
    walk ended); steps: returns taken; steps_to_gait: the return that came within tol of the
    gait (converges only); distance: the last return's distance to the gait (None without a
    return or a gait); period: the gait's period in returns (1 when it converges, p for another
    gait); mode, state, t_end: where the walk ended (s); transitions: transitions taken;
    counters: the runs' counters added up (``COUNTERS``); warnings: the runs' warnings, each
    "kind: message" once.
    """

    outcome: str
    status: str
    message: str
    steps: int
    mode: str
    state: np.ndarray
    t_end: float
    transitions: int
    steps_to_gait: int | None = None
    distance: float | None = None
    period: int | None = None
    counters: dict[str, float] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)


class _Walker:
    """One walk's state: where it is, the returns so far, the counters."""

    def __init__(
        self,
        problem: OrbitProblem,
        fixed_point: np.ndarray | None,
        max_steps: int,
        tol: float,
        progress: Callable[[float, float, float], None] | None,
    ) -> None:
        self.problem = problem
        self.system, self.control = problem.instantiate()
        self.fixed_point = fixed_point
        self.max_steps, self.tol, self.progress = max_steps, tol, progress
        self.watches: tuple[Any, ...] = ()
        self.periodic = np.array(problem.periodic_idx, dtype=int)
        self.returns: list[np.ndarray] = []
        self.return_times: list[float] = []
        self.distance: float | None = None
        self.period: int | None = None
        self.events = 0  # section events: a return every problem.returns of them
        self.transitions = 0
        self.since_event = 0  # transitions since the last section event
        self.counters: defaultdict[str, float] = defaultdict(int)
        self.warnings: dict[str, None] = {}  # insertion-ordered set

    def run(self, mode: str, x: np.ndarray, t: float) -> WalkResult:
        p = self.problem
        last_return = t
        while True:
            if self.progress is not None:  # a deadline: checked between runs too
                self.progress(t, t, t)
            ex = self.flow(mode, x, t, last_return + p.t_max)
            for t_hit, x_hit in self.crossings(ex, last_return):
                last_return = t_hit
                verdict = self.returned(x_hit, t_hit)
                if verdict is not None:
                    return self.end(verdict, ex, p.bound.mode, x_hit, t_hit)
            if ex.status == Status.MAX_TRANSITIONS:
                crossed = self.cross(ex.strips[-1])
                if isinstance(crossed, WalkResult):
                    return crossed
                name, mode, x, t = crossed
                verdict = None
                if p.section.kind == "transition" and name == p.section.transition and self.event():
                    last_return = t
                    verdict = self.returned(x, t)
                elif self.since_event > MAX_TRANSITIONS_WITHOUT_RETURN:
                    verdict = (
                        "stops",
                        f"{self.since_event} transitions without a return to the section {p.section.label}",
                    )
                if verdict is not None:
                    return self.end(verdict, ex, mode, x, t)
            elif ex.status == Status.FINISHED and ex.t_end < last_return + p.t_max:
                mode, x, t = ex.final_mode, ex.final_state.copy(), ex.t_end  # returned in this run: go on
            elif ex.status == Status.FINISHED:
                return self.end(
                    ("stops", f"no return to the section {p.section.label} within t_max = {p.t_max:g} s"),
                    ex,
                    ex.final_mode,
                    ex.final_state,
                    ex.t_end,
                )
            else:
                outcome = "falls" if ex.status in (Status.MODEL_BREAKDOWN, Status.FELL) else "failed"
                return self.end((outcome, ex.message), ex, ex.final_mode, ex.final_state, ex.t_end)

    def flow(self, mode: str, x: np.ndarray, t: float, t_final: float) -> Execution:
        """The relaxed run from (mode, x) at t up to the guard point of the next transition."""
        p = self.problem
        # The problem's landing rule and halving budget, as its return map runs: the gait's
        # fixed point is then one of these steps'.
        ex = simulate(
            self.system,
            x,
            mode,
            max(t_final, t + p.h),
            p.h,
            p.eps,
            p.tableau,
            self.control,
            t0=t,
            max_transitions=0,
            rtol=p.rtol,
            atol=p.atol,
            progress=self.progress,
            landing=p.landing,
            max_halvings=p.max_halvings,
            watches=self.watches,
        )
        self.add_run(ex)
        return ex

    def add_run(self, ex: Execution, until: float = math.inf) -> None:
        """Add a run's counters, and its warnings up to time ``until`` (s), to the walk's."""
        for key in COUNTERS:
            self.counters[key] += ex.counters.get(key, 0)
        self.warnings.update(dict.fromkeys(f"{w.kind}: {w.message}" for w in ex.warnings if w.time <= until))

    def crossings(self, ex: Execution, last_return: float) -> list[tuple[float, np.ndarray]]:
        """Returns to a level-crossing section in this run's flow, in time order."""
        p = self.problem
        if p.section.kind != "crossing" or not ex.segments or ex.segments[0].mode != p.bound.mode:
            return []
        seg, hits, after = ex.segments[0], [], last_return + p.min_time
        while self.since_event >= p.min_transitions:
            hit = first_crossing(seg, p.bound.s, p.section.direction, after)
            if hit is None:
                break
            after = hit[0] + p.min_time
            if self.event():
                hits.append(hit)
        return hits

    def event(self) -> bool:
        """Count a section event; True when it completes a return (every ``returns`` events)."""
        self.events += 1
        self.since_event = 0
        return self.events % self.problem.returns == 0

    def cross(self, strip: Strip) -> tuple[str, str, np.ndarray, float] | WalkResult:
        """Take the transition whose strip the run stopped in: hold q to the exit time, reset q.
        Returns (transition name, target mode, state, time), or how the walk ended."""
        tr = next(tr for tr in self.system.outgoing(strip.mode) if tr.name == strip.name)
        t_exit = strip_exit_time(strip.landing_time, self.problem.eps, strip.depth)
        self.counters["reset_evals"] += 1
        try:
            # No reset is the identity (hybrid.Transition).
            q = strip.state.copy()
            x_after = np.asarray(q if tr.reset is None else tr.reset(q), dtype=float)
        except ModelBreakdown as exc:
            return self.finish(
                "falls", "model_breakdown", f"{exc} (reset of {tr.name})", strip.mode, strip.state, strip.time
            )
        except Exception as exc:
            raise ModelError(
                f"{self.system.name}: reset of transition {tr.name} failed at t={strip.time:.17g}: "
                f"{type(exc).__name__}: {exc}"
            ) from exc
        if not np.all(np.isfinite(x_after)):
            return self.finish(
                "failed",
                "non_finite",
                f"reset of {tr.name} gives a non-finite state {x_after.tolist()}",
                tr.target,
                x_after,
                t_exit,
            )
        self.transitions += 1
        self.since_event += 1
        return tr.name, tr.target, x_after, t_exit

    def returned(self, x: np.ndarray, t: float) -> tuple[str, str] | None:
        """Record a return at time t (s); the walk's verdict (outcome, why) when it has one."""
        self.returns.append(np.asarray(x, dtype=float).copy())
        self.return_times.append(t)
        k = len(self.returns)
        quick = MIN_RETURN_STEPS * self.problem.h
        intervals = np.diff(self.return_times[-CHATTER_RETURNS - 1 :])
        if len(intervals) == CHATTER_RETURNS and np.all(intervals < quick):
            return "stops", (
                f"the last {CHATTER_RETURNS} returns came less than {MIN_RETURN_STEPS} steps h apart: "
                f"it chatters in place (a Zeno-like collapse), it does not walk"
            )
        if self.fixed_point is not None:
            self.distance = float(np.linalg.norm((x - self.fixed_point)[self.periodic]))
            if self.distance < self.tol:
                self.period = 1
                return "converges", f"within {self.tol:g} of the gait after {k} step(s)"
        # Returns converging to the gait also come closer to each other (by |1 - mu| of their
        # distance to it, mu a multiplier): repeating counts only when it is much tighter.
        repeat_tol = self.tol if self.distance is None else min(self.tol, REPEAT_SHARE * self.distance)
        for period in range(1, MAX_PERIOD + 1):
            if (
                k > period
                and t - self.return_times[k - 1 - period] >= period * quick
                and np.linalg.norm((x - self.returns[k - 1 - period])[self.periodic]) < repeat_tol
            ):
                self.period = period
                return "other_gait", f"returns repeat every {period} step(s) away from the gait"
        if k >= self.max_steps:
            return "undecided", f"{k} steps without converging, falling or repeating"
        return None

    def end(self, verdict: tuple[str, str], ex: Execution, mode: str, x: np.ndarray, t: float) -> WalkResult:
        outcome, why = verdict
        status = ex.status if outcome in ("falls", "failed") else "finished"
        return self.finish(outcome, str(status), why, mode, x, t)

    def finish(self, outcome: str, status: str, message: str, mode: str, x: np.ndarray, t: float) -> WalkResult:
        k = len(self.returns)
        return WalkResult(
            outcome=outcome,
            status=status,
            message=message,
            steps=k,
            mode=mode,
            state=np.asarray(x, dtype=float).copy(),
            t_end=float(t),
            transitions=self.transitions,
            steps_to_gait=k if outcome == "converges" else None,
            distance=self.distance,
            period=self.period,
            counters=dict(self.counters),
            warnings=list(self.warnings),
        )


class _ReturnWalker(_Walker):
    """A walk of a controlled scene: each step one return of the problem's ``ReturnMap``, the
    controller restored to its memory at the last return."""

    def run(self, mode: str, x: np.ndarray, t: float) -> WalkResult:
        p = copy.copy(self.problem)
        p.progress = self.progress  # a deadline is checked inside each return's runs too
        rmap = ReturnMap(p, self.watches)
        memory = p.memory_guess.copy()
        noted = np.zeros(memory.shape, dtype=bool)  # entries some return has noted
        while True:
            if self.progress is not None:
                self.progress(t, t, t)
            try:
                ret = rmap(x, memory=memory)
            except OrbitError as exc:
                return self.ended(exc, x, t)
            self.count(ret.execution, len(ret.transitions), ret.t_return)
            memory = self.walk_frame(ret, noted)
            noted |= ret.memory_noted
            # The walk goes on from where the robot is: its cyclic coordinates are not restarted.
            t, x = t + ret.time, ret.x_end.copy()
            verdict = self.returned(x, t)
            if verdict is not None:
                outcome, why = verdict
                return self.finish(outcome, "finished", why, p.bound.mode, x, t)

    def walk_frame(self, ret: Any, noted: np.ndarray) -> np.ndarray:
        """The memory at return ``ret`` as the next return of the walk sees it. ``ReturnMap``
        gives it in the frame of a return that restarts the clock and the cyclic coordinates; a
        walk restarts the clock only. So an epoch noted in an earlier return (``noted``) and not
        in this one is moved by this return's time too, and a place noted in this one is put
        back where it was noted. An entry never noted holds its fresh marker, which has no frame."""
        p = self.problem
        memory = ret.memory_end.copy()
        shift_frames(p, memory, ret.memory_noted, 0.0, ret.x_start - ret.x_end)
        shift_frames(p, memory, noted & ~ret.memory_noted, ret.time, np.zeros(p.dim))
        return memory

    def count(self, ex: Execution, transitions: int, until: float = math.inf) -> None:
        """Add a return's run to the counters, and its warnings up to time ``until`` (s, the
        return: the next return runs on from there); ``transitions`` up to the return."""
        self.add_run(ex, until)
        self.transitions += transitions

    def ended(self, exc: OrbitError, x: np.ndarray, t: float) -> WalkResult:
        """The walk's end where a return started from x at time t (s) did not come: none within
        t_max or the transition budget spent (``stops``), a fall, or a failed run, where its run
        ended."""
        ex = exc.execution
        if ex is None:  # the simulation raised (a deadline, a model's error)
            return self.finish("failed", exc.status, str(exc), self.problem.bound.mode, x, t)
        self.count(ex, len(ex.transitions))
        kind = "stops" if exc.status == "no_return" else RUN_OUTCOMES.get(ex.status, "failed")
        # The plant's state: a ControlLaw's memory follows it in the run's.
        state = ex.final_state[: len(self.system.state_names(ex.final_mode))]
        message = str(exc) if exc.status == "no_return" else ex.message
        if ex.t0 != t:  # a return runs on a clock of its own, restarted at each return
            message += f" (times counted from this return's start, at t={t:.17g} s of the walk)"
        return self.finish(kind, str(ex.status), message, ex.final_mode, state, t + ex.t_end - ex.t0)


def walk(
    problem: OrbitProblem,
    x0: np.ndarray,
    t0: float,
    fixed_point: np.ndarray | None,
    *,
    max_steps: int = 20,
    tol: float = 1e-3,
    progress: Callable[[float, float, float], None] | None = None,
    watches: tuple[Any, ...] = (),
) -> WalkResult:
    """Walk from ``x0`` (a state of the section's mode at time ``t0``, s) until the walk has an
    outcome (``OUTCOMES``), at most ``max_steps`` returns.

    ``fixed_point``: the reference gait's state on the section, shape (n,), or None (then no
    walk ``converges``; one that settles is ``other_gait`` with period 1). ``tol``: in state
    units. ``progress``: passed to every ``simulate`` (a deadline raises from it). ``watches``:
    passed to every ``simulate`` too (a scene's ``[fall]`` conditions: a run that ends ``fell``
    is a walk that ``falls``). A problem with a controller starts from its ``memory_guess`` (a
    fresh controller's memory) and takes its steps through its return map (module docstring).
    """
    x0 = np.asarray(x0, dtype=float)
    if x0.shape != (problem.dim,):
        raise SimulationError(
            f"walk: the initial state has shape {x0.shape}, expected ({problem.dim},) in the "
            f"section's mode '{problem.bound.mode}'"
        )
    if not (math.isfinite(tol) and tol > 0):
        raise SimulationError(f"walk: tol must be > 0, got {tol!r}")
    kind = _Walker if problem.controller is None else _ReturnWalker
    walker = kind(
        problem, None if fixed_point is None else np.asarray(fixed_point, dtype=float), max_steps, tol, progress
    )
    walker.watches = tuple(watches)
    return walker.run(problem.bound.mode, x0.copy(), float(t0))


def walk_columns(result: WalkResult) -> dict[str, Any]:
    """A walk's columns of the sweep table."""
    return {
        "outcome": result.outcome,
        "walk_steps": result.steps,
        "steps_to_gait": result.steps_to_gait,
        "distance_to_gait": result.distance,
        "gait_period": result.period,
    }
