"""One run's workspace: its parts, counters and the pieces of the execution being built, and
the state of the current mode visit. The HybridSystem itself is never modified (the Pinocchio
model/data split: the system is the immutable model, this is its scratch data)."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

from ..control import Bound
from ..errors import ContractError, LegsimError, SimulationError
from ..execution import Execution, SegmentBuffer, Status
from ..hybrid import HybridSystem, ModeData, not_a_number, real_number
from ..methods import Tableau, make_stepper
from ..methods.stepper import field_value
from .outcomes import Ended
from .simultaneous import OrderWatch
from .zeno import ZenoWatch, strip_hold_warning

ProgressFn = Callable[[float, float, float], None]
Control = Callable[[float, np.ndarray], Any]
#: A mode's guard as the run calls it, ``guard(t, x)``: >= 0 inside the domain.
GuardAt = Callable[[float, np.ndarray], Any]

_EVALUATE = object()  # a guard's control not given: evaluate it


class Guards(tuple):
    """A mode's guards as the run calls them (``GuardAt`` each), and ``values(t, x)``, all of
    them at once: the control there evaluated once for every guard that takes it (a mode with
    friction has one guard per outcome of each event, each on the same control)."""

    values: Callable[[float, np.ndarray], list[float]]


#: Wall-clock seconds between progress reports.
PROGRESS_INTERVAL = 0.2
#: Accepted steps between looks at the clock (a power of 2).
PROGRESS_STEPS = 64


class ModeVisit:
    """The flow in one mode between two transitions: the mode's data, its field and guards as
    the loop calls them, the segment being stored, and the current point (t, x) with
    k0 = f(t, x) and, for dense landing, the guards there (``g_here``)."""

    __slots__ = ("buf", "data", "field", "g_entry", "g_last", "guards", "k0", "name", "single_guard", "t", "x")

    def __init__(self, data: ModeData, guards: Guards, t: float, x: np.ndarray) -> None:
        self.data = data
        self.name = data.name
        self.field = data.mode.field
        self.guards = guards
        self.single_guard = guards[0] if len(guards) == 1 else None
        self.buf = SegmentBuffer(data.name, data.mode.dim)
        self.t = t
        self.x = x
        self.k0: np.ndarray = np.zeros(0)
        self.g_entry: list[float] = []
        self.g_last: Any = None  # the last accepted trial step, whose guards are those here

    @property
    def g_here(self) -> list[float]:
        """The guards at the current point (t, x)."""
        return self.g_entry if self.g_last is None else self.g_last.guard_values()

    def guard_values(self, t: float, x: np.ndarray) -> list[float]:
        """Every guard at (t, x), in the mode's transition order."""
        return self.guards.values(t, x)


class Run:
    """The parts of one run (method, step-size rule, landing rule), its settings, counters and
    the segments, strips and transitions of the execution so far."""

    def __init__(
        self,
        system: HybridSystem,
        tableau: Tableau,
        step_size: Any,
        landing: Any,
        eps: float,
        control: Control | None,
        *,
        max_transitions: int,
        max_halvings: int,
        max_steps: int,
        progress: ProgressFn | None,
        t0: float,
        t_final: float,
        zeno: ZenoWatch,
    ) -> None:
        self.system = system
        self.tableau = tableau
        self.stepper = make_stepper(tableau)
        #: Field evaluations of a step beyond k0 = f(t, x).
        self.evals_per_step = tableau.stages - 1
        self.step_size = step_size
        self.landing = landing
        self.eps = eps
        self.control = control
        #: A controller held over each step (zero-order hold), sampled at each step's start.
        self.held_control = control if isinstance(control, Bound) and control.hold else None
        self.max_transitions = max_transitions
        self.max_halvings = max_halvings
        self.max_steps = max_steps
        self.zeno = zeno
        self.order = OrderWatch()
        self.t0, self.t_final = t0, t_final
        self.steps = self.halvings = self.error_rejections = 0
        self.field_evals = self.guard_evals = self.reset_evals = 0
        self.strip_time = 0.0
        self.segments: list = []
        self.strips: list = []
        self.transitions: list = []
        self.state_names: dict[str, tuple[str, ...]] = {}
        self.state_units: dict[str, tuple[str, ...]] = {}
        self.checked_modes: set[str] = set()
        self._guard_cache: dict[str, Guards] = {}
        #: Per-run caches of parts that keep state per mode (the compiled path's workspaces).
        self.scratch: dict[str, Any] = {}
        self._progress = progress
        self._wall0 = self._last_report = time.perf_counter()

    def note_mode(self, data: ModeData) -> None:
        """The run enters ``data``'s mode: its coordinates' names and units join the execution's."""
        self.state_names.setdefault(data.name, data.mode.names)
        self.state_units.setdefault(data.name, data.mode.units)

    # -- evaluations ---------------------------------------------------------------------------
    def f(self, field: Callable[..., np.ndarray], t: float, x: np.ndarray) -> np.ndarray:
        """The field at (t, x) with the control there, counted and checked to have x's shape."""
        self.field_evals += 1
        control = self.control
        return field_value(field(t, x, None if control is None else control(t, x)), x)

    def guard_fns(self, data: ModeData) -> Guards:
        """The mode's guards as g(t, x), with the control evaluated for ``t,x,u`` guards; built
        once per mode and run."""
        fns = self._guard_cache.get(data.name)
        if fns is None:
            fns = self._guard_cache[data.name] = Guards(self._guard_fn(tr) for tr in data.transitions)
            control = self.control
            if control is None or all(tr.guard_args == "x" for tr in data.transitions):
                fns.values = lambda t, x: [float(g(t, x)) for g in fns]
            else:

                def values(t: float, x: np.ndarray) -> list[float]:
                    u = control(t, x)
                    return [float(g(t, x, u)) for g in fns]

                fns.values = values
        return fns

    def _guard_fn(self, transition) -> Callable[..., float]:
        """g(t, x) of ``transition``, its value checked to be a real number at every call (the
        check costs an isinstance on the common path of a float); g(t, x, u) takes the control
        u at (t, x) already evaluated (``Guards.values``)."""
        g, control, name = transition.guard, self.control, transition.name

        def number(value: Any) -> float:
            out = real_number(value)
            if out is None:
                raise ContractError(f"guard of transition {name} {not_a_number(value)}")
            return out

        if transition.guard_args == "x":
            return lambda t, x, u=None: v if isinstance(v := g(x), float) else number(v)
        if control is None:
            return lambda t, x, u=None: v if isinstance(v := g(t, x, None), float) else number(v)

        def guard(t: float, x: np.ndarray, u: Any = _EVALUATE) -> float:
            v = g(t, x, control(t, x) if u is _EVALUATE else u)
            return v if isinstance(v, float) else number(v)

        return guard

    # -- bookkeeping ---------------------------------------------------------------------------
    def end_visit(self, visit: ModeVisit, ended: Ended) -> Ended:
        """Store the visit's segment and end the run there."""
        self.segments.append(visit.buf.freeze())
        return ended

    @property
    def has_progress(self) -> bool:
        """True when a progress callback wants reports."""
        return self._progress is not None

    def tick(self, t: float) -> None:
        """Report progress when PROGRESS_INTERVAL has passed since the last report."""
        if self._progress is None:
            return
        now = time.perf_counter()
        if now - self._last_report > PROGRESS_INTERVAL:
            self._last_report = now
            try:
                self._progress(t, self.t0, self.t_final)
            except LegsimError:  # the caller stopping the run with its own error (a deadline)
                raise
            except Exception as exc:  # a bug in the caller's callback, not the model
                raise SimulationError(
                    f"the progress callback failed at t={t:.17g}: {type(exc).__name__}: {exc}"
                ) from exc

    def execution(self, ended: Ended) -> Execution:
        """The execution computed, ending as ``ended`` says."""
        counters = {
            "steps": self.steps,
            "halvings": self.halvings,
            "error_rejections": self.error_rejections,
            "field_evals": self.field_evals,
            "guard_evals": self.guard_evals,
            "reset_evals": self.reset_evals,
            "transitions": len(self.transitions),
            "strip_time": self.strip_time,
            "wall_time_s": time.perf_counter() - self._wall0,
        }
        settings = {
            "h": self.step_size.h_max,
            "eps": self.eps,
            "method": self.tableau.name,
            **self.step_size.settings(),
            "landing": self.landing.name,
            "max_transitions": self.max_transitions,
            "control": self.control is not None,
            "continuation": self.zeno.continues,
            "zeno_window": self.zeno.window,
        }
        warnings = self.zeno.warnings(self, ended.t) + self.order.warnings()
        held = strip_hold_warning(self.strip_time, self.t0, ended.t, warnings)
        warnings += [held] if held is not None else []
        return Execution(
            status=Status(ended.status),
            message=ended.message,
            segments=self.segments,
            strips=self.strips,
            transitions=self.transitions,
            t0=self.t0,
            t_end=ended.t,
            t_final=self.t_final,
            counters=counters,
            settings=settings,
            state_names=self.state_names,
            system_name=self.system.name,
            final_in_strip=ended.in_strip,
            warnings=warnings,
            state_units=self.state_units,
        )
