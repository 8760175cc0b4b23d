"""A run's tables: the modes it may enter, their transitions, functions and parameters, as the
step loop reads them (``layout.M_*``, ``T_*``, ``J_*``).

Modes get rows as the run reaches them: a mode's row is *registered* (its dimension and its
controller, enough to reset into it) when some ready mode may lead to it, and *ready* (its
functions and parameters, its transitions' targets registered in turn) when the loop first
enters it (``RETURN_NEED_MODE``), which is also when a lazily built system expands it. A mode
written as model functions (``Mode.functions``) brings its own functions; a mode of Python
callables gets adapters (``legsim.relaxed.adapt``). The controller adds its control and entry
functions and, per mode, its parameters.

The arrays keep spare rows (``SPARE``) so that a Python joint function met inside a loop call can
register a new outcome; the driver grows them between calls.
"""

from __future__ import annotations

import contextlib
import functools
from collections.abc import Iterator
from typing import Any

import numpy as np

from ..control import Bound
from ..errors import ModelError
from ..hybrid import HybridSystem, ModeData
from ..model import GuardOf, ModeFunctions, ResetOf
from . import adapt
from .evaluate import Tables
from .layout import (
    J_TARGET,
    JOINT_FIELDS,
    M_C0,
    M_C1,
    M_CONTROL,
    M_CROSSES_JUMPS,
    M_DIM,
    M_ENTER,
    M_FIELD,
    M_GUARD_FN,
    M_GUARDS,
    M_J0,
    M_JOINT,
    M_JOINT_HISTORY,
    M_NAN_BREAKS,
    M_NJ,
    M_P0,
    M_P1,
    M_PREVIEWED,
    M_READY,
    M_RESET,
    M_T0,
    MODE_FIELDS,
    NO_CONTINUATION,
    T_CONTINUATION,
    T_TARGET,
    TRANSITION_FIELDS,
)
from .probe import probe_controller, probe_indices
from .workspace import Workspace, allocate, cleared

#: Rows kept free in each table for registrations inside a loop call.
SPARE = 64
#: Joint outcomes a mode with a Python joint function may register.
PYTHON_JOINT_OUTCOMES = 64


@contextlib.contextmanager
def kept_tables(system: HybridSystem, control: Any, law: Any) -> Iterator[RunTables]:
    """The tables for a run of ``system`` under ``law`` (a ``ControlLaw``, or None): those the
    system's last finished run left when it ran under the same law, its modes already ready, so
    that a system's modes are built once however many runs it makes (an orbit search, a
    benchmark, a scene run again). The system keeps one set, its last run's, whatever law that
    was. A Python ``control`` gets new tables (its adapters belong to its run), and so does a run
    started inside another (from its callback), and a run after one that reached a Python mode.
    Tables are kept only when the run ends without an exception: a mode half-prepared by a
    failing model is not reused. The caller holds the system's turn (``HybridSystem.turn``)."""
    if control is not None:
        yield RunTables(system, control, law)
        return
    tables = system.run_scratch.pop("tables", None)
    if tables is None or tables.law is not law:
        tables = RunTables(system, None, law)
    tables.breakdowns.last = None
    yield tables
    # Tables that took the run to the Python loop are not kept: the next run is compiled until it
    # reaches a Python mode itself, and names only what it reached.
    if tables.compiled:
        system.run_scratch["tables"] = tables


class RunTables:
    """The tables of one run of ``system`` under ``control`` (module docstring).

    Attributes
    ----------
    names: mode names by row; ``rows``: rows by name.
    transition_names, continuation_names: by transition row; ``joint_names``: by joint row.
    memory: the controller's memory size; ``inputs``: the entries of the input array u.
    compiled: whether every function of every registered mode and of the controller is compiled.
    """

    def __init__(self, system: HybridSystem, control: Any, law: Any = None) -> None:
        self.system = system
        self.control = control
        self.law = law
        self.cell = adapt.InputCell()
        self.breakdowns = adapt.Breakdowns()
        self.functions: list[Any] = []
        #: The call shape of each function (``compiled.native.SIGNATURES``).
        self.kinds: list[str] = []
        #: The compiled kernel's addresses of the functions (``driver.Runner.addresses``): the
        #: first ones of ``functions``, the table growing only at its end.
        self.addresses = np.zeros(0, dtype=np.int64)
        self._function_ids: dict[int, int] = {}
        self.names: list[str] = []
        self.rows: dict[str, int] = {}
        self.datas: list[ModeData] = []
        self.transition_names: list[str] = []
        self.continuation_names: list[str] = []
        self.joint_names: list[str] = []
        self.modes = np.zeros((SPARE, MODE_FIELDS), dtype=np.int64)
        self.transitions = np.zeros((SPARE, TRANSITION_FIELDS), dtype=np.int64)
        self.joints = np.zeros((SPARE, JOINT_FIELDS), dtype=np.int64)
        self.P = np.zeros(SPARE)
        self.n_transitions = self.n_joints = self.n_params = 0
        self.history_rows = 0
        #: The workspace of the tables' last run and its sizes (``allocate``'s arguments), which the
        #: next run of the same sizes takes (``workspace``): a short run spends about as long
        #: allocating three dozen arrays as stepping.
        self.spare_workspace: tuple[tuple[int, ...], Workspace] | None = None
        self.memory = self._memory()
        self.inputs = 0 if law is None else int(law.inputs)
        self.compiled, self.python_reason = True, ""
        if law is not None and not law.compiled:
            self._python(f"controller {law.name} has Python functions (compile them with legsim.model_function)")
        elif law is None and control is not None:
            self._python("the control is a Python callable")

    # -- registration -------------------------------------------------------------------------
    def register(self, name: str) -> int:
        """The row of mode ``name``, registered on first use: its dimension and controller, enough
        to reset into it. Its own functions come when it is prepared (``describe``), so that the
        many modes a transition may reach are not built until the run enters one."""
        row = self.rows.get(name)
        if row is not None:
            return row
        dim = self.system.dim(name)
        row = len(self.names)
        self._grow_modes(row + 1)
        self.names.append(name)
        self.rows[name] = row
        self.datas.append(None)  # type: ignore[arg-type]  # the ModeData comes when it is ready
        out = self.modes[row]
        out[M_DIM] = dim
        out[M_READY] = 0
        out[M_T0] = out[M_GUARDS] = out[M_NJ] = out[M_J0] = 0
        out[M_FIELD] = out[M_GUARD_FN] = out[M_RESET] = out[M_JOINT] = -1
        out[M_P0] = out[M_P1] = out[M_NAN_BREAKS] = out[M_PREVIEWED] = out[M_CROSSES_JUMPS] = 0
        self._register_control(row, name)
        return row

    def describe(self, row: int) -> None:
        """Mode ``row``'s field, parameters and flags in the table."""
        name = self.names[row]
        mode = self.system.mode(name)
        out = self.modes[row]
        functions = mode.functions
        if functions is not None:
            out[M_FIELD] = self.function(functions.field)
            out[M_P0], out[M_P1] = self.params(functions.params)
            out[M_NAN_BREAKS] = int(functions.nan_breaks)
            out[M_PREVIEWED] = int(functions.previewed)
            out[M_CROSSES_JUMPS] = int(functions.crosses_jumps)
            self.inputs = max(self.inputs, functions.inputs)
            if self.law is not None and functions.inputs and self.law.inputs != functions.inputs:
                raise ModelError(
                    f"{self.system.name}: controller {self.law.name} gives {self.law.inputs} input entries, "
                    f"mode '{name}' takes {functions.inputs}"
                )
            if not functions.compiled:
                self._python(f"mode '{name}' has Python model functions")
        else:
            out[M_FIELD] = self.function(adapt.field_adapter(mode, self.cell, self.breakdowns))
            self._python(f"mode '{name}' is written as Python callables")

    def make_ready(self, row: int) -> None:
        """Prepare mode ``row`` unless an earlier run of these tables has."""
        if self.modes[row, M_READY] == 0:
            self.prepare(row)

    def prepare(self, row: int) -> None:
        """Make mode ``row`` ready: its transitions' and continuations' targets registered, its
        guards, resets and joint function in the table."""
        name = self.names[row]
        self.describe(row)
        data = self.system.mode_data(name)
        self.datas[row] = data
        count = len(data.transitions)
        first = self.n_transitions
        self._grow_transitions(first + count)
        self.n_transitions += count
        self.modes[row, M_T0], self.modes[row, M_GUARDS] = first, count
        self.modes[row, M_JOINT_HISTORY] = first + count
        self.history_rows = max(self.history_rows, first + count + 1)
        self.n_transitions += 1  # the joint history's row
        functions = data.mode.functions
        for e, tr in enumerate(data.transitions):
            self.transition_names.append(tr.name)
            self.continuation_names.append(tr.continuation.name if tr.continuation is not None else "")
            self.transitions[first + e, T_TARGET] = self.register(tr.target)
            cont = tr.continuation
            self.transitions[first + e, T_CONTINUATION] = (
                NO_CONTINUATION if cont is None else self.register(cont.target)
            )
        self.transition_names.append("")
        self.continuation_names.append("")
        if functions is not None:
            probe_indices(name, data.mode.dim, functions, count, self._reset_dims(data))
        if self.law is not None:
            control_params = self.P[self.modes[row, M_C0] : self.modes[row, M_C1]]
            probe_controller(name, data.mode.dim, self.law, control_params)
        self._prepare_functions(row, data, functions)
        self.modes[row, M_READY] = 1
        # A continuation's image is checked against its target's guards before it is entered.
        for tr in data.transitions:
            if tr.continuation is not None:
                target = self.rows[tr.continuation.target]
                if self.modes[target, M_READY] == 0:
                    self.prepare(target)

    def _reset_dims(self, data: ModeData) -> dict[int, int]:
        """reset index e -> the dimension its image has (``legsim.model``): each transition's
        target, and for e = count + j the target of transition j's continuation."""
        count = len(data.transitions)
        dims = {e: self.system.dim(tr.target) for e, tr in enumerate(data.transitions)}
        for j, tr in enumerate(data.transitions):
            if tr.continuation is not None:
                dims[count + j] = self.system.dim(tr.continuation.target)
        return dims

    def _prepare_functions(self, row: int, data: ModeData, functions: ModeFunctions | None) -> None:
        """The guards, resets and joint function of a ready mode: its own model functions where
        every transition takes them, adapters of its Python callables otherwise."""
        system = self.system
        if not data.transitions:
            return
        if functions is not None and _own_guards(data, functions):
            self.modes[row, M_GUARD_FN] = self.function(functions.guards)
        else:
            if functions is not None:
                self._python(f"mode '{data.name}' has transitions with Python guards")
            self.modes[row, M_GUARD_FN] = self.function(adapt.guards_adapter(data, self.cell, self.breakdowns))
        if functions is not None and _own_resets(data, functions):
            self.modes[row, M_RESET] = -1 if functions.reset is None else self.function(functions.reset, "indexed")
        else:
            if functions is not None:
                self._python(f"mode '{data.name}' has transitions with Python resets")
            self.modes[row, M_RESET] = self.function(adapt.reset_adapter(system, data, self.breakdowns), "indexed")
        if functions is not None and functions.joint is not None:
            self.modes[row, M_JOINT] = self.function(functions.joint, "joint")
            first, count = self._outcomes(list(functions.joint_outcomes))
            self.modes[row, M_J0], self.modes[row, M_NJ] = first, count
        elif system.joint is not None:
            self.modes[row, M_J0] = self._reserve_joints(PYTHON_JOINT_OUTCOMES)
            self.modes[row, M_NJ] = 0
            self.modes[row, M_JOINT] = self.function(
                adapt.joint_adapter(system, data, functools.partial(self._joint, row)), "joint"
            )
            self._python(f"the system's joint function is Python (mode '{data.name}')")

    def _register_control(self, row: int, name: str) -> None:
        self.modes[row, M_CONTROL] = -1
        self.modes[row, M_ENTER] = -1
        self.modes[row, M_C0] = 0
        self.modes[row, M_C1] = 0
        if self.law is not None:
            self.modes[row, M_CONTROL] = self.function(self.law.control)
            if self.law.enter is not None:
                self.modes[row, M_ENTER] = self.function(self.law.enter)
            start, end = self.params(self.law.params_for(name, self.system))
            self.modes[row, M_C0], self.modes[row, M_C1] = start, end
        elif self.control is not None:
            functions = self.system.mode(name).functions
            reads = 0 if functions is None else functions.inputs
            self.modes[row, M_CONTROL] = self.function(adapt.control_adapter(self.control, name, self.cell, reads))
            if isinstance(self.control, Bound):
                self.modes[row, M_ENTER] = self.function(adapt.enter_adapter(self.control, name))

    def _memory(self) -> int:
        """The memory entries of the state: a ``ControlLaw``'s (a Python ``Controller`` keeps its
        state in itself, and the orbit search reads it through ``memory()``)."""
        return 0 if self.law is None else len(self.law.memory_names)

    def _python(self, reason: str) -> None:
        if self.compiled:
            self.compiled = False
            self.python_reason = reason

    # -- joint outcomes ---------------------------------------------------------------------
    def _outcomes(self, outcomes: list[tuple[str, str]]) -> tuple[int, int]:
        first = self._reserve_joints(len(outcomes))
        for k, (name, target) in enumerate(outcomes):
            self.joint_names[first + k] = name
            self.joints[first + k, J_TARGET] = self.register(target)
        return first, len(outcomes)

    def _reserve_joints(self, count: int) -> int:
        first = self.n_joints
        self._grow_joints(first + count)
        self.n_joints += count
        self.joint_names.extend([""] * count)
        return first

    def _joint(self, row: int, name: str, target: str) -> int:
        """The index of outcome (name, target) among mode ``row``'s, registered on first use."""
        first, count = int(self.modes[row, M_J0]), int(self.modes[row, M_NJ])
        target_row = self.register(target)
        for k in range(count):
            if self.joint_names[first + k] == name and self.joints[first + k, J_TARGET] == target_row:
                return k
        if count >= PYTHON_JOINT_OUTCOMES:
            raise ModelError(
                f"{self.system.name}: mode '{self.names[row]}' has more than {PYTHON_JOINT_OUTCOMES} joint outcomes"
            )
        self.joint_names[first + count] = name
        self.joints[first + count, J_TARGET] = target_row
        self.modes[row, M_NJ] = count + 1
        return count

    # -- storage ------------------------------------------------------------------------------
    def function(self, fn: Any, kind: str = "state") -> int:
        """The index of ``fn`` in the function table (added on first use), called with the
        shape ``kind``: ``"state"``, ``"indexed"`` (resets) or ``"joint"``."""
        key = id(fn)
        found = self._function_ids.get(key)
        if found is not None and self.functions[found] is fn:
            return found
        self.functions.append(fn)
        self.kinds.append(kind)
        self._function_ids[key] = len(self.functions) - 1
        return len(self.functions) - 1

    def plain_functions(self) -> list[Any]:
        """The function table with each compiled function as its plain Python source
        (``py_func``): the whole run in Python, to read or debug."""
        return [getattr(fn, "py_func", fn) for fn in self.functions]

    def params(self, values: Any) -> tuple[int, int]:
        """Store a parameter array in P: its span (start, end)."""
        arr = np.ascontiguousarray(values, dtype=np.float64).reshape(-1)
        start = self.n_params
        self._grow_params(start + arr.shape[0])
        self.P[start : start + arr.shape[0]] = arr
        self.n_params += arr.shape[0]
        return start, start + arr.shape[0]

    def _grow_modes(self, rows: int) -> None:
        if rows + SPARE // 2 > self.modes.shape[0]:
            self.modes = _grown(self.modes, rows + SPARE)

    def _grow_transitions(self, rows: int) -> None:
        if rows + SPARE > self.transitions.shape[0]:
            self.transitions = _grown(self.transitions, rows + 2 * SPARE)

    def _grow_joints(self, rows: int) -> None:
        if rows > self.joints.shape[0]:
            self.joints = _grown(self.joints, rows + SPARE)

    def _grow_params(self, size: int) -> None:
        if size > self.P.shape[0]:
            self.P = _grown(self.P, size + SPARE)

    def workspace(self, sizes: tuple[int, int, int, int, int, int]) -> Workspace:
        """A workspace of ``sizes`` (``allocate``'s arguments) for a run: the spare one, cleared,
        when it has these sizes, else a new one."""
        spare, self.spare_workspace = self.spare_workspace, None
        if spare is not None and spare[0] == sizes:
            return cleared(spare[1])
        return allocate(*sizes)

    def tables(self, functions: Any) -> Tables:
        """The loop's ``Tables`` with ``functions`` as the function table (the list of callables
        interpreted, their addresses compiled)."""
        return Tables(functions, self.modes, self.transitions, self.joints, self.P)

    @property
    def widest(self) -> int:
        """The longest state of the registered modes, memory included."""
        return int(self.modes[: len(self.names), M_DIM].max()) + self.memory

    @property
    def most_guards(self) -> int:
        """The most guards of a ready mode (at least 1)."""
        return max(1, int(self.modes[: len(self.names), M_GUARDS].max()))

    def name_of(self, row: int) -> str:
        return self.names[row]


def _own_guards(data: ModeData, functions: ModeFunctions) -> bool:
    """Whether every transition of the mode takes its guard from the mode's functions."""
    return all(isinstance(tr.guard, GuardOf) and tr.guard.functions is functions for tr in data.transitions)


def _own_resets(data: ModeData, functions: ModeFunctions) -> bool:
    """Whether every transition and continuation of the mode takes its reset from the mode's
    functions (or, when they have none, keeps the state)."""

    def own(reset: Any) -> bool:
        if functions.reset is None:
            return reset is None
        return isinstance(reset, ResetOf) and reset.functions is functions

    return all(own(tr.reset) and (tr.continuation is None or own(tr.continuation.reset)) for tr in data.transitions)


def _grown(arr: np.ndarray, rows: int) -> np.ndarray:
    """``arr`` with at least ``rows`` rows (new ones zero), at least doubled: registering many
    modes (a robot's friction outcomes) copies each table a few times, not once a mode."""
    out = np.zeros((max(rows, 2 * arr.shape[0]), *arr.shape[1:]), dtype=arr.dtype)
    out[: arr.shape[0]] = arr
    return out
