"""The loop's driver: builds a run's tables and workspace, runs the loop (compiled when the
kernel can take the run, else interpreted), serves what it hands back (a mode to make ready,
full buffers, progress) and assembles the execution.

The compiled kernel registers itself here (``KERNEL``) when ``legsim.compiled`` is imported:
the core never imports the compiled path.
"""

from __future__ import annotations

import math
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ContractError, LegsimError, ModelError, SimulationError
from ..execution import Execution
from ..hybrid import HybridSystem
from ..interrupts import raise_if_stopped
from ..methods import Tableau
from . import loop
from .assemble import Assembly
from .evaluate import enter_controller, visit_of
from .layout import (
    F_H_PROP,
    F_STALL_T,
    F_T,
    I_MODE,
    I_PHASE,
    I_POINTS,
    I_RECORDS,
    I_STEPS,
    I_TRANSITIONS,
    I_VISITS,
    LAND_AIM,
    LAND_DENSE,
    LAND_HALVE,
    M_READY,
    PHASE_ENTER,
    RETURN_ENDED,
    RETURN_FULL,
    RETURN_NEED_MODE,
    RETURN_PROGRESS,
    S_ADAPTIVE,
    S_ATOL,
    S_CONTINUES,
    S_EPS,
    S_EXPONENT,
    S_H_MAX,
    S_HOLD,
    S_LANDING,
    S_MAX_HALVINGS,
    S_MAX_STEPS,
    S_MAX_TRANSITIONS,
    S_MEMORY,
    S_PROGRESS_STEPS,
    S_RTOL,
    S_T0,
    S_T_FINAL,
    S_WINDOW,
)
from .stages import INFO_EXTRA, INFO_STAGES, method_arrays
from .tables import RunTables, kept_tables
from .workspace import Workspace, allocate, resized, with_longer_buffers

#: The compiled kernel, set by ``legsim.compiled``: ``KERNEL.run(tables, ws, method)`` and
#: ``KERNEL.addresses(functions)``; None runs every run interpreted.
KERNEL: Any = None
#: Steps (or transitions) between looks at the clock: at first, and at least; the loop then hands
#: back about every ``LOOK_INTERVAL`` of wall time, by the rate measured so far.
PROGRESS_STEPS_FIRST, PROGRESS_STEPS_MOST = 64, 1 << 20
LOOK_INTERVAL = 0.02
#: Wall-clock seconds between progress reports.
PROGRESS_INTERVAL = 0.2
#: With stop watches, the most steps (or transitions) before the loop hands back and the driver
#: scans the new points: a run that fell goes on for at most this many steps.
STOP_CHECK_STEPS = 256
LANDINGS = {"halve": LAND_HALVE, "aim": LAND_AIM, "dense": LAND_DENSE}


@dataclass(frozen=True)
class Options:
    """A run's settings, checked by ``simulate``."""

    tableau: Tableau
    h: float
    eps: float
    landing: str
    rtol: float | None
    atol: float | None
    t0: float
    t_final: float
    max_transitions: int
    max_halvings: int
    max_steps: int
    continuation: bool
    zeno_window: float
    hold: bool
    progress: Callable[[float, float, float], None] | None
    python: bool = False
    #: Conditions on the run's points (``watches.Watch``): stops, warnings, measured times.
    watches: tuple[Any, ...] = ()
    #: The caller's end: ``until(so_far) -> bool`` on the run so far (``RunSoFar``), or None.
    until: Callable[[Any], bool] | None = None


def drive(
    system: HybridSystem,
    mode: str,
    x0: np.ndarray,
    control: Any,
    law: Any,
    options: Options,
    memory: np.ndarray | None = None,
) -> Execution:
    """Run ``system`` from (mode, x0) at options.t0 under a Python ``control`` or a ``law``
    (``legsim.control.ControlLaw``): x0 the plant's state; the controller's memory starts from
    ``memory``, else ``law.initial_memory`` or the Python controller's ``memory()``."""
    wall0 = time.perf_counter()
    with kept_tables(system, control, law) as tables:
        row = tables.register(mode)
        tables.make_ready(row)
        method = method_arrays(options.tableau)
        stages = method.info[INFO_STAGES] + max(method.info[INFO_EXTRA], 0)
        # As wide as the widest mode built so far: reaching a wider mode later would copy the buffers.
        width = max(tables.widest, max((m.dim for m in system.modes.values()), default=0) + tables.memory)
        sizes = (width, tables.most_guards, stages, tables.inputs, tables.memory, tables.n_transitions)
        ws = tables.workspace(sizes)
        settings(ws, options, tables)
        start(tables, ws, row, x0, memory, options)
        compiled = KERNEL is not None and not options.python
        assembly = Assembly(system, tables, options)
        run = Runner(tables, ws, method, compiled, options, assembly)
        run.go()
        execution = assembly.execution(run.ws, run.steps, time.perf_counter() - wall0, python_reason(tables, options))
        if run.ws is ws:  # as allocated, not grown: the tables' next run of these sizes takes it
            tables.spare_workspace = (sizes, ws)
        return execution


def python_reason(tables: RunTables, options: Options) -> str:
    """Why a run took (or would take) the Python loop, "" for none; read after the run, since a
    mode the run reaches later may be the one written in Python."""
    if options.python:
        return "the run asked for plain Python (simulate(python=True))"
    if KERNEL is None and tables.compiled:
        return "the compiled kernel is not loaded (legsim.compiled was not imported)"
    return tables.python_reason


def settings(ws: Workspace, options: Options, tables: RunTables) -> None:
    """Write the run's settings into ws.cf and ws.ci."""
    adaptive = options.rtol is not None
    cf, ci = ws.cf, ws.ci
    cf[S_T_FINAL], cf[S_T0], cf[S_H_MAX], cf[S_EPS] = options.t_final, options.t0, options.h, options.eps
    cf[S_WINDOW] = options.zeno_window
    if adaptive:
        tableau = options.tableau
        assert options.atol is not None and tableau.error_order is not None
        cf[S_RTOL], cf[S_ATOL] = options.rtol, options.atol
        cf[S_EXPONENT] = -1.0 / (min(tableau.order, tableau.error_order) + 1)
    ci[S_ADAPTIVE] = int(adaptive)
    ci[S_LANDING] = LANDINGS[options.landing]
    ci[S_MAX_HALVINGS], ci[S_MAX_STEPS] = options.max_halvings, options.max_steps
    ci[S_MAX_TRANSITIONS] = options.max_transitions
    ci[S_CONTINUES], ci[S_HOLD], ci[S_MEMORY] = int(options.continuation), int(options.hold), tables.memory


def start(
    tables: RunTables, ws: Workspace, row: int, x0: np.ndarray, memory: np.ndarray | None, options: Options
) -> None:
    """The run's first point: the plant's state, the controller's memory and its entry into the
    first mode."""
    dim = int(tables.modes[row, 0])
    ws.x[:dim] = x0
    if tables.memory:
        ws.x[dim : dim + tables.memory] = tables.law.initial_memory if memory is None else memory
    ws.iv[I_MODE] = row
    ws.iv[I_PHASE] = PHASE_ENTER
    ws.fs[F_T] = ws.fs[F_STALL_T] = options.t0
    ws.fs[F_H_PROP] = options.h
    vis = visit_of(tables.tables(tables.functions), tables.memory, row)
    enter_controller(tables.tables(tables.functions), vis, ws, options.t0, ws.x)


class Runner:
    """Runs the loop until the run ends, serving what it hands back."""

    def __init__(self, tables: RunTables, ws: Workspace, method: Any, compiled: bool, options: Options,
                 assembly: Any) -> None:  # fmt: skip
        self.tables, self.ws, self.method, self.compiled = tables, ws, method, compiled
        self.options, self.assembly = options, assembly
        #: Steps taken by each path: (compiled, python).
        self.steps = [0, 0]
        # A stop watch or the caller's until may end the run at a hand-back: the loop then hands back
        # every STOP_CHECK_STEPS exactly, never at a pace the clock sets, so that where such a run
        # ends (until) and its counters (steps taken before the stop was seen) do not depend on
        # the machine's speed or load.
        self.ends_early = any(w.action == "stop" for w in options.watches) or options.until is not None
        self.ws.ci[S_PROGRESS_STEPS] = 0 if options.progress is None else PROGRESS_STEPS_FIRST
        if self.ends_early:
            self.ws.ci[S_PROGRESS_STEPS] = STOP_CHECK_STEPS
        self.last_report = self.last_look = time.perf_counter()
        self.work_at_look = 0
        tables.breakdowns.ws = ws

    def go(self) -> None:
        while True:
            code = self.call()
            if code == RETURN_ENDED:
                self.assembly.drain(self.ws, final=True)
                return
            if code == RETURN_NEED_MODE:
                self.tables.prepare(int(self.ws.iv[I_MODE]))
                self.fit()
            elif code == RETURN_FULL or (code == RETURN_PROGRESS and self.ends_early):
                self.assembly.drain(self.ws, final=False)
                if code == RETURN_FULL:
                    self.ws = with_longer_buffers(self.ws)
                    self.tables.breakdowns.ws = self.ws
                if self.assembly.check_stops() or self.assembly.check_until():  # the run ends there
                    self.assembly.drain(self.ws, final=True)
                    return
                self.tick()
            elif code == RETURN_PROGRESS:
                self.tick()

    def call(self) -> int:
        tables, ws = self.tables, self.ws
        compiled = self.compiled and tables.compiled
        before = int(ws.iv[I_STEPS])
        try:
            if compiled:
                return int(KERNEL.run(tables.tables(self.addresses()), ws, self.method))
            functions = tables.plain_functions() if self.options.python else tables.functions
            # The loop checks every value it computes for finiteness itself; numpy's warnings on
            # an overflow in its scalar arithmetic would only repeat that (the kernel has none).
            with np.errstate(all="ignore"):
                return int(loop.run(tables.tables(functions), ws, self.method))
        except ContractError as exc:
            raise ModelError(f"{tables.system.name}: {exc} {self.where()}") from exc
        except LegsimError:
            raise
        except Exception as exc:
            raise ModelError(
                f"{tables.system.name}: evaluating mode '{self.mode_name()}' failed {self.where()}: "
                f"{type(exc).__name__}: {exc}{self.raised_in(exc)}"
            ) from exc
        finally:
            self.steps[0 if compiled else 1] += int(self.ws.iv[I_STEPS]) - before

    def addresses(self) -> np.ndarray:
        """The function table's addresses, kept with the tables for their next run (those of
        functions added since, computed now)."""
        tables = self.tables
        known = tables.addresses.shape[0]
        if known < len(tables.functions):
            more = KERNEL.addresses(tables.functions[known:], tables.kinds[known:])
            tables.addresses = np.concatenate([tables.addresses, more])
        return tables.addresses

    def raised_in(self, exc: BaseException) -> str:
        """Which of the run's model functions raised ``exc``, when its traceback shows it: the
        innermost frame running one of them (the Python loop over their Python source)."""
        codes = {}
        for fn in self.tables.functions:
            code = getattr(getattr(fn, "py_func", fn), "__code__", None)
            if code is not None:
                codes[code] = getattr(fn, "__name__", repr(fn))
        names = [codes[frame.f_code] for frame, _ in traceback.walk_tb(exc.__traceback__) if frame.f_code in codes]
        if names:
            return f" (raised in model function '{names[-1]}')"
        # Compiled code leaves no frames of the model's functions in the traceback.
        return " (python=True runs the model's Python source and names the function that raised)"

    def mode_name(self) -> str:
        return self.tables.names[int(self.ws.iv[I_MODE])]

    def where(self) -> str:
        ws = self.ws
        n = int(self.tables.modes[int(ws.iv[I_MODE]), 0]) + self.tables.memory
        return f"in the step from t={ws.fs[F_T]:.17g} in mode '{self.mode_name()}' (x={ws.x[:n].tolist()})"

    def pace(self, now: float) -> None:
        """Set how many steps the loop takes before it looks at the clock again: about
        ``LOOK_INTERVAL`` at the rate of the last stretch."""
        if self.ends_early:  # hands back every STOP_CHECK_STEPS, whatever the clock (__init__)
            return
        work = _work(self.ws)
        elapsed = now - self.last_look
        if elapsed > 0.0 and work > self.work_at_look:
            rate = (work - self.work_at_look) / elapsed
            steps = min(max(int(rate * LOOK_INTERVAL), PROGRESS_STEPS_FIRST), PROGRESS_STEPS_MOST)
            self.ws.ci[S_PROGRESS_STEPS] = steps
        self.last_look, self.work_at_look = now, work

    def fit(self) -> None:
        """Widen the workspace for the modes registered so far."""
        tables = self.tables
        self.ws = resized(self.ws, tables.widest, tables.most_guards, tables.inputs, tables.n_transitions)
        tables.breakdowns.ws = self.ws

    def tick(self) -> None:
        progress = self.options.progress
        if progress is None:
            return
        # The loop hands back here a few times a second on a long run: a stop signal swallowed
        # by a finalizer meanwhile ends the run now rather than at its end.
        raise_if_stopped()
        now = time.perf_counter()
        self.pace(now)
        if now - self.last_report <= PROGRESS_INTERVAL:
            return
        self.last_report = now
        try:
            progress(float(self.ws.fs[F_T]), self.options.t0, self.options.t_final)
        except LegsimError:
            raise
        except Exception as exc:
            raise SimulationError(
                f"the progress callback failed at t={self.ws.fs[F_T]:.17g}: {type(exc).__name__}: {exc}"
            ) from exc


class Evaluator:
    """A system's modes as the loop evaluates them, for tools that step the same fields outside a
    run (the variational equations of ``legsim.orbits``): ``call(fn, mode, *args)`` calls
    ``fn(tables, visit, ws, method, *args)``, a function written like the loop's, compiled by the
    kernel when the mode's functions and the controller's are (``KERNEL.tool``), else
    interpreted."""

    def __init__(self, system: HybridSystem, tableau: Tableau, control: Any = None, law: Any = None) -> None:
        self.tables = RunTables(system, control, law)
        self.method = method_arrays(tableau)
        self.ws: Workspace | None = None

    def call(self, fn: Callable[..., Any], mode: str, *args: Any) -> Any:
        tables = self.tables
        row = tables.register(mode)
        if tables.modes[row, M_READY] == 0:
            tables.prepare(row)
        stages = self.method.info[INFO_STAGES] + max(self.method.info[INFO_EXTRA], 0)
        if self.ws is None:
            self.ws = allocate(tables.widest, tables.most_guards, stages, tables.inputs, tables.memory, 1)
        else:
            self.ws = resized(self.ws, tables.widest, tables.most_guards, tables.inputs, 1)
        ws = self.ws
        ws.ci[S_MEMORY] = tables.memory
        ws.ci[S_HOLD] = 0
        tables.breakdowns.ws = ws
        if KERNEL is not None and tables.compiled:
            addresses = KERNEL.addresses(tables.functions, tables.kinds)
            tab = tables.tables(addresses)
            return KERNEL.tool(fn)(tab, visit_of(tab, tables.memory, row), ws, self.method, *args)
        tab = tables.tables(tables.functions)
        return fn(tab, visit_of(tab, tables.memory, row), ws, self.method, *args)


def _work(ws: Workspace) -> int:
    return int(ws.iv[I_STEPS]) + int(ws.iv[I_TRANSITIONS])


def buffer_counts(ws: Workspace) -> tuple[int, int, int]:
    """(points, records, visits) stored in the output buffers."""
    return int(ws.iv[I_POINTS]), int(ws.iv[I_RECORDS]), int(ws.iv[I_VISITS])


def finite(value: float) -> bool:
    return math.isfinite(value)
