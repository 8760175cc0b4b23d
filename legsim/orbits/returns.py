"""The return map: from a state on the section, simulate until the trajectory comes back to it.

How the return is found
-----------------------
The return map simulates a bounded horizon with ``legsim.simulate`` and locates the crossing
on the execution's dense output (the cubic Hermite interpolant of the step containing the sign
change, solved with Brent's method), then again on the run's own step from the stored point
before it (``section_points``: the interpolant's error would be noise in the map); for a
transition section it reads the reset image from the execution's transition record. We prefer
this to adding the section as a guard of a wrapped system: an extra guard would change the
computation being analysed (steps would be halved to land in the section's strip and the state
held there), and starting on the section would fire that guard at once. The horizon grows: 1.5
times the last return time (plus 20 steps), or t_max / 8 at first, doubled until a return is
found or t_max is reached. The run itself ends soon after the return (``simulate``'s ``until``,
asked as the loop hands its points back, every 256 steps at most), so a return costs about its
own time, and a model failure long after it (a runner that falls a few strides later) cannot
hide it.

A crossing of a function section counts only after at least ``min_transitions`` transitions
(default 1) since the start, so that a start just off the section (as finite differences and
Newton trials make) does not "return" to the section it has just left. Crossings are looked for
inside continuous flow of the section's mode; a reset that jumps across s = 0 is not a crossing.

Controllers
-----------
A problem with a ``controller`` starts each return with a fresh one restored to the memory
guess, and reads the memory back at the return: the controller changes its memory only at mode
entries (``legsim.control``), so the memory at the return is the one after the last mode entry
before it, recorded as the run enters each mode. A ``ControlLaw``'s memory is part of the run's
state: the return starts from (x, memory) and reads both off the execution. Memory that is an
epoch on the run's clock or a position along a cyclic coordinate (``ControlLaw.memory_frames``:
a runner's last touchdown time and place) is read back in the return's own frame, shifted by
the return time and the coordinate's increment, since every return restarts both.

Period
------
The relaxed integrator holds the state at the guard point q for ``eps - tau`` plus the rest of
the landing step (``legsim.relaxed``), so the relaxed return time exceeds the hybrid system's
period by eps + O(h) per transition. ``Return.flow_time`` is the return time less the time spent
in strips, which converges at the method's order; ``Return.time`` is the relaxed one.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..control import ControlLaw, Controller
from ..crossings import returns
from ..errors import LegsimError
from ..execution import Execution, RunSoFar, TransitionRecord
from ..hybrid import HybridSystem
from ..relaxed import simulate
from .errors import OrbitError
from .problem import OrbitProblem, Return
from .section_points import crossing_on_step, evaluator, steps_reproducible

#: Relative change of a memory value over a return below which it is unchanged (rounding).
MEMORY_ROUNDING = 1e-12


class MemoryLog(Controller):
    """A controller run as it is, its memory recorded after every mode entry (``entries[k]``:
    after the k-th entry, entry 0 the start of the run)."""

    def __init__(self, controller: Controller) -> None:
        self.controller = controller
        self.hold = controller.hold
        self.entries: list[np.ndarray] = []

    def reset(self, mode: str, t: float, x: np.ndarray) -> None:
        self.controller.reset(mode, t, x)
        self.entries.append(np.asarray(self.controller.memory(), dtype=float).reshape(-1).copy())

    def __call__(self, mode: str, t: float, x: np.ndarray) -> Any:
        return self.controller(mode, t, x)

    @property
    def input_source(self) -> Controller:
        """The wrapped controller's: this one only records its memory."""
        return self.controller.input_source


class ReturnMap:
    """The return map of a problem's section, with an adaptive simulation horizon.

    ``rmap(x, parameters=None, memory=None) -> Return``; ``memory``: the controller's memory at
    the start (default the problem's ``memory_guess``). Raises ``OrbitError`` (status
    ``no_return`` or ``simulation_failed``, the run that stopped as its ``execution``) when
    there is no return. ``evaluations`` counts the simulations run. ``watches``: passed to every
    ``simulate`` (a scene's ``[fall]`` conditions and its model's checks, for a walk).
    """

    def __init__(self, problem: OrbitProblem, watches: Sequence[Any] = ()) -> None:
        self.problem = problem
        self.watches = tuple(watches)
        self.evaluations = 0
        self._hint: float | None = None  # the last return time (s): where the next one is looked for

    def __call__(
        self, x: np.ndarray, parameters: Mapping[str, float] | None = None, memory: np.ndarray | None = None
    ) -> Return:
        p = self.problem
        x = np.asarray(x, dtype=float).copy()
        params = dict(p.parameters)
        if parameters:
            params.update({k: float(v) for k, v in parameters.items()})
        system, control = p.instantiate(params)
        memory = p.memory_guess if memory is None else np.asarray(memory, dtype=float).reshape(-1)
        last_error: OrbitError | None = None
        for horizon in self._horizons():
            made = None if p.controller is None else p.restored_controller(params, memory)
            if isinstance(made, ControlLaw):
                ex = self._simulate(system, made, np.concatenate([x, memory]), horizon)
                log = None
            else:
                log = None if made is None else MemoryLog(made)
                ex = self._simulate(system, control if log is None else log, x, horizon)
            # What the run's input came from: the law, the Python controller, or the control.
            found = self._locate(ex, x, params, system, control if made is None else made)
            if found is not None:
                self._hint = found.time
                if log is not None:
                    self._read_memory(found, memory, log)
                elif made is not None:
                    found.memory_start = memory.copy()
                if made is not None:
                    self._to_start_frame(found)
                return found
            if ex.status != "finished":
                raise OrbitError(
                    f"return map: the simulation from {self.show_state(x)} stopped with status "
                    f"'{ex.status}' before returning to the section {p.section.label}: {ex.message}",
                    "simulation_failed",
                    execution=ex,
                )
            seen = [tr.name for tr in ex.transitions]
            last_error = OrbitError(
                f"no return to the section {p.section.label} within t_max = {horizon:g} s from "
                f"{self.show_state(x)} (transitions taken: {_abbreviate(seen)}; final mode '{ex.final_mode}', "
                f"state {np.round(ex.final_state, 6).tolist()})",
                "no_return",
                execution=ex,
            )
        assert last_error is not None
        raise last_error

    def _read_memory(self, found: Return, memory: np.ndarray, log: MemoryLog) -> None:
        """The memory at the start and at the return: after the entry of the return's segment
        (after the returning transition for a section after a transition)."""
        entry = found.segment + (1 if self.problem.section.kind == "transition" else 0)
        if entry >= len(log.entries):
            raise OrbitError(
                f"return map: the controller was reset {len(log.entries)} times but the return lies "
                f"after mode entry {entry}: its memory at the return is unknown",
                "simulation_failed",
            )
        found.memory_start = memory.copy()
        found.memory_end = log.entries[entry]

    def _to_start_frame(self, found: Return) -> None:
        """The memory at the return expressed as the next return will see it: an epoch (frame
        "t") noted during this return less the return time, a position along a cyclic coordinate
        noted during it less that coordinate's increment. The next return restarts the clock and
        the cyclic coordinates, so a gait's touchdown times and places repeat only in these
        frames. An entry the return did not change keeps its value: on a periodic orbit every
        return notes the same entries, and one never noted holds a marker (a law's "no liftoff
        yet" time) that has no frame. Unchanged means within rounding, and is read back exactly:
        the integrator's arithmetic on the run's state moves a memory value by rounding (that
        marker, -1e9 s, by 1e-7 s), which would otherwise stay in the orbit equations."""
        found.memory_end = found.memory_end.copy()
        noted = np.abs(found.memory_end - found.memory_start) > MEMORY_ROUNDING * (1.0 + np.abs(found.memory_start))
        found.memory_end[~noted] = found.memory_start[~noted]
        found.memory_noted = noted
        shift_frames(self.problem, found.memory_end, noted, found.time, found.x_end - found.x_start)

    def _horizons(self) -> list[float]:
        """Growing simulation horizons (s): the last return time and a half (plus 20 steps), or
        t_max / 8, doubled up to t_max (see the module docstring)."""
        p = self.problem
        horizon = 1.5 * self._hint + 20 * p.h if self._hint is not None else p.t_max / 8
        horizons = []
        while horizon < p.t_max:
            horizons.append(horizon)
            horizon *= 2
        horizons.append(p.t_max)
        return horizons

    def _simulate(self, system: HybridSystem, control: Any, x: np.ndarray, horizon: float) -> Execution:
        p = self.problem
        self.evaluations += 1
        try:
            return simulate(
                system,
                x,
                p.bound.mode,
                horizon,
                p.h,
                p.eps,
                p.tableau,
                control,
                max_transitions=p.max_transitions,
                max_halvings=p.max_halvings,
                rtol=p.rtol,
                atol=p.atol,
                landing=p.landing,
                progress=p.progress,
                watches=self.watches,
                until=self._returned,
            )
        except LegsimError as exc:
            raise OrbitError(
                f"return map: the simulation from {self.show_state(x)} over {horizon:g} s failed before "
                f"returning to the section {p.section.label}: {exc}",
                "simulation_failed",
            ) from exc

    def _returned(self, so_far: RunSoFar) -> bool:
        """Whether the run so far holds the return ``_locate`` looks for, so that it ends there
        rather than at the horizon. Past a transition, once a step was taken after it: the
        controller has been reset on that entry, whose memory the return reads."""
        if self.problem.section.kind == "transition":
            k = self._returning_transition(so_far)
            return k is not None and k + 1 < len(so_far.segments) and len(so_far.segments[k + 1].t) >= 2
        return self._returning_crossing(so_far) is not None

    def _returning_transition(self, run: Execution | RunSoFar) -> int | None:
        """The index in ``run.transitions`` of the ``returns``-th taking of the section's
        transition into the section's mode, or None."""
        p = self.problem
        taken = (k for k, rec in enumerate(run.transitions)
                 if rec.name == p.section.transition and rec.target == p.bound.mode)  # fmt: skip
        return next(itertools.islice(taken, p.returns - 1, None), None)

    def _returning_crossing(self, run: Execution | RunSoFar) -> tuple[int, float, np.ndarray] | None:
        """The ``returns``-th crossing of the section in the run's segments, (k, t, x) as
        ``crossings.returns`` gives it, or None."""
        p = self.problem
        found = returns(run, p.bound.mode, p.bound.s, p.section.direction, p.min_transitions, p.min_time)
        return next(itertools.islice(found, p.returns - 1, None), None)

    def show_state(self, x: np.ndarray) -> str:
        """A state of the section's mode as ``{name=value, ...}`` for messages."""
        return "{" + ", ".join(f"{n}={v:.6g}" for n, v in zip(self.problem.names, x, strict=False)) + "}"

    def _locate(
        self, ex: Execution, x0: np.ndarray, params: dict[str, float], system: HybridSystem, control: Any
    ) -> Return | None:
        if self.problem.section.kind == "transition":
            return self._locate_after_transition(ex, x0, params)
        return self._locate_crossing(ex, x0, params, system, control)

    def _locate_after_transition(self, ex: Execution, x0: np.ndarray, params: dict[str, float]) -> Return | None:
        """The ``returns``-th time the section's transition is taken into the section's mode."""
        k = self._returning_transition(ex)
        if k is None:
            return None
        rec = ex.transitions[k]
        return self._make_return(ex, x0, rec.state_after.copy(), rec.exit_time, k, ex.transitions[: k + 1], params)

    def _locate_crossing(
        self, ex: Execution, x0: np.ndarray, params: dict[str, float], system: HybridSystem, control: Any
    ) -> Return | None:
        """The ``returns``-th crossing, scanning the segments of the section's mode in time
        order, located again on the run's own step where that step can be retaken
        (``section_points``). Segment k follows transitions[k-1], so k transitions precede it."""
        p = self.problem
        hit = self._returning_crossing(ex)
        if hit is None:
            return None
        k, t_hit, x_hit = hit
        if steps_reproducible(control, p.tableau, p.rtol is not None):
            run = evaluator(system, control, p.tableau)
            on_step = crossing_on_step(run, ex.segments[k], p.bound.s, p.section.direction, t_hit)
            if on_step is not None:
                t_hit, x_hit = on_step
        return self._make_return(ex, x0, x_hit, t_hit, k, ex.transitions[:k], params)

    def _make_return(
        self,
        ex: Execution,
        x0: np.ndarray,
        x_end: np.ndarray,
        t_ret: float,
        k: int,
        records: Sequence[TransitionRecord],
        params: dict[str, float],
    ) -> Return:
        p = self.problem
        in_strips = sum(s.exit_time - s.time for s in ex.strips if s.exit_time <= t_ret + 1e-12 * max(1.0, t_ret))
        # A ControlLaw's memory follows the plant's state in the execution's.
        x_end = np.asarray(x_end, dtype=float)
        ret = Return(
            x_start=x0.copy(),
            x_end=x_end[: p.dim].copy(),
            memory_end=x_end[p.dim :].copy(),
            mode=p.bound.mode,
            time=t_ret - ex.t0,
            flow_time=t_ret - ex.t0 - in_strips,
            transitions=list(records),
            execution=ex,
            t_return=t_ret,
            segment=k,
            parameters=dict(params),
        )
        if p.step_length is not None:
            ret.step_length = float(p.step_length(ret))
        elif p.cyclic_idx:
            c = p.cyclic_idx[0]
            ret.step_length = float(ret.x_end[c] - ret.x_start[c])
        return ret


def memory_at_crossing(problem: OrbitProblem, t: float, memory: np.ndarray, t_start: float) -> np.ndarray:
    """A run's controller memory at a crossing of the section at time t (s), as a return started
    there, at the run's state, sees it (``ReturnMap._to_start_frame``'s frames): an epoch (frame
    "t") less t, as each return restarts the clock; a position along a cyclic coordinate as it
    is, as a return measures places in the frame of its start's coordinates, which are the run's
    own. An epoch before the run's start ``t_start`` (s) was never noted (a law's "no liftoff
    yet" marker) and is kept as it is. Shape (m,), a copy."""
    out = np.asarray(memory, dtype=float).copy()
    noted = np.array(
        [frame != "t" or value >= t_start for frame, value in zip(problem.memory_frames, out, strict=True)]
    )
    shift_frames(problem, out, noted, t, np.zeros(problem.dim))
    return out


def shift_frames(problem: OrbitProblem, memory: np.ndarray, noted: np.ndarray, time: float, shift: np.ndarray) -> None:
    """In place: each noted memory value measured from a frame, less the frame's shift: an epoch
    (frame "t") less ``time`` (s), a position along a cyclic coordinate less that coordinate's
    entry of ``shift`` (shape (n,))."""
    for i, frame in enumerate(problem.memory_frames):
        if not noted[i] or not frame:
            continue
        if frame == "t":
            memory[i] -= time
        elif problem.names.index(frame) in problem.cyclic_idx:
            memory[i] -= shift[problem.names.index(frame)]


def _abbreviate(names: list[str], limit: int = 8) -> str:
    if not names:
        return "none"
    if len(names) <= limit:
        return ", ".join(names)
    return ", ".join(names[:limit]) + f", ... ({len(names)} in all)"


def return_map(
    problem: OrbitProblem,
    x: Sequence[float] | np.ndarray,
    parameters: Mapping[str, float] | None = None,
    memory: Sequence[float] | np.ndarray | None = None,
) -> Return:
    """One evaluation of ``problem``'s return map from the state ``x`` (section's mode) and, with
    a controller, its memory (default ``problem.memory_guess``)."""
    return ReturnMap(problem)(problem.state_vector(x), parameters, None if memory is None else np.asarray(memory))
