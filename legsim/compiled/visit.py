"""The compiled path's Python side: hand a mode visit's step loop to the kernel with the table
of the system's modes it may enter (``Table``), turn the transitions it crossed into Execution
pieces in batches, and its return code into the same outcome the Python loop reaches
(``relaxed.integrate.run_visit``), with the same messages.

The table of a mode lists the modes the kernel can run that its transitions and continuations
reach. The kernel enters a mode itself once the mode is *ready*: its field's output and its twin
checked against the Python callables at its first entry in the process, which Python makes
before it hands that entry to the kernel (``enter_compiled``). Every entry of a ready mode is
thus the kernel's arithmetic, so a run gives the same result whether it is the first of its
system in the process or not. The kernel keeps the points of every mode in one buffer as wide
as the table's widest state."""

from __future__ import annotations

import gc
import weakref
from typing import Any

import numpy as np

from ..errors import LegsimError, ModelBreakdown
from ..execution import Segment, SegmentBuffer, Status, Strip, TransitionRecord
from ..hybrid import ModeData, check_field_output
from ..relaxed import messages
from ..relaxed.integrate import control_source, control_writer, out_of_steps, runs_compiled
from ..relaxed.outcomes import Ended, Entered, Outcome
from ..relaxed.run import ModeVisit, Run
from ..relaxed.strip import cross
from . import kernel as k
from . import transit as kt
from .generate import get_kernel, no_resets, plan_for
from .twin import CompiledMode, check_twin

#: Transitions the kernel records per call before Python turns them into Execution pieces.
RECORD_CHUNK = 4096
#: Steps per kernel call when a progress callback wants reports (about 1 ms of work).
PROGRESS_CHUNK = 8192
_NO_LIMIT = 1 << 62
#: The ready modes (a system's ModeData, by id): their field's output and twin were checked
#: against the Python callables at their first entry in this process. The check costs as much
#: as a short run, and its answer does not change from one run to the next.
_READY: weakref.WeakValueDictionary[int, ModeData] = weakref.WeakValueDictionary()
#: The modes checked under control, by (id, the class of the controller the twin computes): a
#: twin computes each controller's input by its own code, which a check without control (or
#: under another controller) does not try.
_READY_CONTROLLED: weakref.WeakValueDictionary[tuple[int, type], ModeData] = weakref.WeakValueDictionary()


#: system -> ((a mode, whether the run is controlled) -> the table of the modes it reaches),
#: kept while the system lives.
_TABLES: weakref.WeakKeyDictionary[Any, dict[tuple[str, bool], Table]] = weakref.WeakKeyDictionary()


def is_ready(data: ModeData) -> bool:
    """Whether the mode's field and twin were checked in this process (``_READY``)."""
    return _READY.get(id(data)) is data


class Table:
    """The modes the kernel may run and enter (``reachable``), the first one's visit first
    (indices 0 .. len(mi) - 1), then the other modes their transitions lead to (indices past
    the table: the kernel hands their entry to Python). With ``hand_back`` every target is
    numbered past the table, the mode itself too, so that Python takes every entry (a
    controlled run: each entry resets the controller). Arrays as ``transit`` describes them;
    ``keys`` the (mode, transition) of each history row."""

    def __init__(self, system: Any, modes: list[str], hand_back: bool = False) -> None:
        self.names = list(modes)
        self.datas = [system.mode_data(name) for name in modes]
        index = {} if hand_back else {name: i for i, name in enumerate(self.names)}

        def number(name: str) -> int:
            if name not in index:
                index[name] = len(self.names)
                self.names.append(name)
            return index[name]

        sets: list[tuple[Any, ...]] = []
        params: list[np.ndarray] = []
        # Rows of ``mi`` and ``ti`` (``transit`` describes their columns).
        mi: list[tuple[int | bool, ...]] = []
        ti: list[tuple[int | bool, ...]] = []
        self.keys: list[tuple[str, str]] = []
        self.twins: list[tuple[CompiledMode, int]] = []
        offset = 0
        for name, data in zip(modes, self.datas, strict=True):
            twin = data.mode.compiled
            functions = (twin.field, twin.guards, no_resets if twin.resets is None else twin.resets)
            if functions not in sets:
                sets.append(functions)
            mi.append(
                (
                    sets.index(functions),
                    data.mode.dim,
                    twin.n_guards,
                    offset,
                    offset + twin.params.size,
                    len(ti),
                    twin.resets is not None,
                    False,
                )
            )
            params.append(twin.params)
            self.twins.append((twin, offset))
            offset += twin.params.size
            for e, (tr, target) in enumerate(zip(data.transitions, data.targets, strict=True)):
                cont = tr.continuation
                ti.append(
                    (
                        number(target),
                        kt.NO_MODE if cont is None else number(cont.target),
                        cont is not None and twin.continued,
                        kt.UNKNOWN_GROUP if twin.joint_groups is None else twin.joint_groups[e],
                        target == name,
                        len(self.keys),
                    )
                )
                self.keys.append((name, tr.name))
        self.sets = tuple(sets)
        self.P = np.concatenate(params) if params else np.zeros(0)
        self.mi = np.array(mi, dtype=np.int64).reshape(-1, 8)
        self.ti = np.array(ti, dtype=np.int64).reshape(-1, 6)
        self.hist = np.zeros((max(1, len(self.keys)), 3))
        #: The widest state of the table's modes: the kernel's buffers hold any of them.
        self.width = int(self.mi[:, 1].max()) if len(mi) else 0

    def write_control(self, run: Run) -> None:
        """The run's control into every twin's parameters, which may hold another run's
        controller (once per kernel run: the control changes only at entries, in Python)."""
        for data in self.datas:
            _write_control(run, data)

    def load(self, run: Run) -> None:
        """The twins' parameters into P, which modes are ready, and the Zeno histories of the
        table's transitions from the run's ZenoWatch."""
        for twin, offset in self.twins:
            self.P[offset : offset + twin.params.size] = twin.params
        for i, data in enumerate(self.datas):
            self.mi[i, kt.MI_READY] = is_ready(data)
        for row, (mode, name) in enumerate(self.keys):
            history = run.zeno.history(mode, name)
            self.hist[row] = (0.0, 0.0, 0.0) if history is None else (1.0, history[0], history[1])

    def store(self) -> None:
        """P back into the twins' parameters: a twin may count its evaluations there (a robot's
        model counters, ``robots.bridge.twins.add_counts``)."""
        for twin, offset in self.twins:
            twin.params[:] = self.P[offset : offset + twin.params.size]


class Workspace:
    """Per-run scratch arrays of the kernel, as wide as the widest state (``width``)."""

    def __init__(self, width: int, stages: int, n_guards: int) -> None:
        self.K = np.zeros(stages * width)
        self.x, self.XS, self.x_new, self.k1, self.work = (np.zeros(width) for _ in range(5))
        self.q, self.dq, self.raw = np.zeros(width), np.zeros(width), np.zeros(width)
        self.gv = np.zeros(max(1, n_guards))
        self.fs = np.zeros(8)
        self.iv = np.zeros(13, dtype=np.int64)
        self.cf = np.zeros(7)
        self.ci = np.zeros(8, dtype=np.int64)
        self.cnt = np.zeros(3, dtype=np.int64)
        self.r_i = np.zeros((RECORD_CHUNK, 6), dtype=np.int64)
        self.r_f = np.zeros((RECORD_CHUNK, 4))
        self.r_q = np.zeros((RECORD_CHUNK, width))
        self.r_after = np.zeros((RECORD_CHUNK, width))


def run_visit_compiled(run: Run, visit: ModeVisit) -> Outcome:
    """The step loop from a mode visit Python entered, compiled: through the transitions the
    kernel takes (``transit``), possibly into other modes of the table, until the run ends or
    Python must take a crossing or an entry. A twin that computes the run's control first gets
    the controller's values as its reset at this entry left them."""
    if run.control is None:
        if not is_ready(visit.data) and _check_visit(run, visit):
            _READY[id(visit.data)] = visit.data
    elif _READY_CONTROLLED.get(key := _control_key(run, visit.data)) is not visit.data and _check_visit(run, visit):
        _READY_CONTROLLED[key] = visit.data
    return _drive(run, visit, kt.CROSS)


def _check_visit(run: Run, visit: ModeVisit) -> bool:
    """The twin of the visit's mode against the Python callables at its start, under the run's
    control; whether every guard was compared (``check_twin``)."""
    _write_control(run, visit.data)
    guards = visit.guard_values(visit.t, visit.x)
    return check_twin(run.system.name, visit.data, visit.t, visit.x, visit.k0, guards)


def _write_control(run: Run, data: ModeData) -> None:
    """The run's control into the parameters of ``data``'s twin, which may hold another run's."""
    twin = data.mode.compiled
    write = control_writer(run.control, twin)
    if write is None:  # pragma: no cover -- runs_compiled said the twin computes this control
        raise RuntimeError(f"mode '{data.name}': its twin cannot compute the run's control")
    write(twin.params)


def _control_key(run: Run, data: ModeData) -> tuple[int, type]:
    """The key of ``data``'s mode under the run's control in ``_READY_CONTROLLED``."""
    return id(data), type(control_source(run.control))


def enter_compiled(run: Run, mode: str, x: np.ndarray, t: float) -> Outcome:
    """The entry of ``mode`` at (t, x) taken by the kernel (``relaxed.entry.enter_mode``'s
    decisions, on the twin), and the step loop from there; Python first checks the mode at its
    first entry in the process. An entry Python must take (a field or guard that is not finite
    there) comes back as ``Entered(..., python_entry=True)``."""
    data = run.system.mode_data(mode)
    run.note_mode(data)
    if not is_ready(data) and not _check_first_entry(run, data, t, x):
        return Entered(mode, x, t, python_entry=True)
    visit = ModeVisit(data, run.guard_fns(data), t, x)
    # As relaxed.entry.enter_mode: a new flow restarts the step size, not a self-transition.
    new_flow = run.step_size.adaptive and bool(run.transitions) and run.transitions[-1].source != mode
    return _drive(run, visit, kt.ENTER_NEW_FLOW if new_flow else kt.ENTER)


def _check_first_entry(run: Run, data: ModeData, t: float, x: np.ndarray) -> bool:
    """Check the mode's field output and twin at its first entry in the process, where the
    Python callables are finite (else False: Python's entry says what is not, or takes an
    entry where the twin's guards are nan)."""
    k0 = check_field_output(run.system.name, data.name, data.mode, t, x, None)
    try:
        guards = [float(guard(t, x)) for guard in run.guard_fns(data)]
    except ModelBreakdown:
        return False
    if not (np.all(np.isfinite(k0)) and all(map(np.isfinite, guards))):
        return False
    _write_control(run, data)
    if not check_twin(run.system.name, data, t, x, k0, guards):
        return False  # nan guards compared nothing: Python takes this entry, a later one checks
    _READY[id(data)] = data
    return True


def _drive(run: Run, visit: ModeVisit, start: int) -> Outcome:
    """Run the kernel from the visit: its steps from (visit.t, visit.x, visit.k0) with ``start``
    CROSS, or first the entry of its mode from (visit.t, visit.x) (ENTER, ENTER_NEW_FLOW)."""
    table = _table(run, visit.name)
    kernel = get_kernel(table.sets)
    plan = plan_for(run.tableau)
    ws = _workspace(run, table)
    visit.buf = _with_width(visit.buf, table.width)
    n = visit.data.mode.dim
    ws.x[:n] = visit.x
    if start == kt.CROSS:
        ws.K[:n] = visit.k0
    _settings(run, ws, plan)
    ws.fs[k.F_T], ws.fs[k.F_HPROP] = visit.t, run.step_size.h_prop
    ws.iv[kt.I_MODE], ws.iv[kt.I_ENTER], ws.iv[kt.I_XLEN] = 0, start, n
    table.write_control(run)
    while True:
        ws.ci[kt.CI_MAX_STEPS] = min(PROGRESS_CHUNK if run.has_progress else _NO_LIMIT, run.max_steps - run.steps)
        ws.ci[kt.CI_BUDGET] = max(0, run.max_transitions - len(run.transitions))
        ws.iv[k.I_SIZE] = visit.buf.size
        table.load(run)
        buf = visit.buf
        code = kernel(
            table.P,
            table.mi,
            table.ti,
            table.hist,
            plan.c,
            plan.n_groups,
            plan.weights,
            plan.n_members,
            plan.members,
            plan.b_err,
            plan.fsal,
            ws.x,
            ws.K,
            ws.XS,
            ws.x_new,
            ws.k1,
            ws.gv,
            ws.work,
            ws.q,
            ws.dq,
            ws.raw,
            buf.t,
            buf.x,
            buf.dx,
            ws.fs,
            ws.iv,
            ws.cf,
            ws.ci,
            ws.cnt,
            ws.r_i,
            ws.r_f,
            ws.r_q,
            ws.r_after,
        )
        table.store()
        buf.size = int(ws.iv[k.I_SIZE])
        _count(run, ws)
        if ws.iv[k.I_RECORDS]:
            visit = _commit_records(run, visit, table, ws, int(ws.iv[k.I_RECORDS]))
        visit.t = float(ws.fs[k.F_T])
        if code == k.BUFFER_FULL:
            _grow(visit.buf)
        elif code == k.CHUNK:
            run.tick(visit.t)
            if run.steps >= run.max_steps:
                visit.x = ws.x[: visit.data.mode.dim].copy()
                visit.buf = _with_width(visit.buf, visit.data.mode.dim)
                return run.end_visit(visit, out_of_steps(run, visit))
        elif code == k.RECORDS_FULL:
            run.tick(visit.t)
        else:
            break
    if code == kt.NEXT:
        # The kernel reached a mode it does not enter (outside the table, or not ready yet), or
        # a state for the entry's special cases, which Python's entry takes: the segments before
        # it are committed with their transitions, nothing of the next one is stored yet.
        m = int(ws.iv[kt.I_MODE])
        special = m < len(table.datas) and is_ready(table.datas[m])
        return Entered(table.names[m], ws.x[: int(ws.iv[kt.I_XLEN])].copy(), visit.t, python_entry=special)
    visit.x = ws.x[: visit.data.mode.dim].copy()
    visit.buf = _with_width(visit.buf, visit.data.mode.dim)
    if code == k.GUARD_NAN and visit.data.mode.compiled.fallback:
        return _python_rest(run, visit, ws)
    return _outcome(run, visit, ws, code)


def _python_rest(run: Run, visit: ModeVisit, ws: Workspace) -> Outcome:
    """The rest of the visit on the Python loop, from the kernel's last accepted point: a twin
    with ``fallback`` returns nan guards past its model's range, where the Python callables
    raise the ModelBreakdown the loop shortens the step for (or ends the run with)."""
    from ..relaxed.integrate import run_visit

    visit.k0 = ws.K[: visit.data.mode.dim].copy()
    return run_visit(run, visit, python=True)


def _table(run: Run, mode: str) -> Table:
    """The table of the modes ``mode`` reaches (made once per system, mode and whether the run
    is controlled, used by every run)."""
    tables = _TABLES.setdefault(run.system, {})
    controlled = run.control is not None
    table = tables.get((mode, controlled))
    if table is None:
        table = tables[(mode, controlled)] = Table(run.system, reachable(run, mode), hand_back=controlled)
    return table


def reachable(run: Run, mode: str) -> list[str]:
    """The modes the kernel can run (``runs_compiled``) that ``mode``'s transitions and their
    continuations reach through such modes, ``mode`` first; ``mode`` alone in a controlled run,
    whose entries Python takes. A lazily built system builds them here; a mode whose building
    fails is left to Python, which says so if a run reaches it."""
    system = run.system
    if run.control is not None:
        return [mode]
    order, seen = [mode], {mode}
    for name in order:
        data = system.mode_data(name)
        nexts = [*data.targets, *(tr.continuation.target for tr in data.transitions if tr.continuation)]
        for target in nexts:
            if target in seen:
                continue
            seen.add(target)
            try:
                if runs_compiled(run, system.mode_data(target)):
                    order.append(target)
            except LegsimError:
                continue
    return order


def _workspace(run: Run, table: Table) -> Workspace:
    """The run's workspace, made wider when the table's states or guards need it."""
    ws = run.scratch.get("compiled_workspace")
    dim, guards = table.width, int(table.mi[:, 2].max())
    if ws is None or ws.x.size < dim or ws.gv.size < guards:
        if ws is not None:
            dim, guards = max(dim, ws.x.size), max(guards, ws.gv.size)
        ws = run.scratch["compiled_workspace"] = Workspace(dim, run.tableau.stages, guards)
    return ws


def _settings(run: Run, ws: Workspace, plan) -> None:
    step_size = run.step_size
    ws.cf[:] = (
        run.t_final,
        step_size.h_max,
        run.eps,
        getattr(step_size, "rtol", 0.0),
        getattr(step_size, "atol", 0.0),
        getattr(step_size, "exponent", 0.0),
        run.zeno.window,
    )
    ws.ci[:] = (
        step_size.adaptive,
        run.landing.name == "aim",
        run.max_halvings,
        0,
        0,
        plan.method_id,
        run.zeno.continues,
        run.system.joint is not None,
    )


def _count(run: Run, ws: Workspace) -> None:
    iv = ws.iv
    run.steps += int(iv[k.I_STEPS])
    run.halvings += int(iv[k.I_HALVINGS])
    run.error_rejections += int(iv[k.I_REJECTIONS])
    run.field_evals += int(iv[k.I_FIELD])
    run.guard_evals += int(iv[k.I_GUARD])
    run.reset_evals += int(iv[k.I_RESETS])
    run.step_size.h_prop = float(ws.fs[k.F_HPROP])


def _outcome(run: Run, visit: ModeVisit, ws: Workspace, code: int) -> Outcome:
    """What the kernel's return code means, as the Python loop would have said it."""
    fs, iv, t, name = ws.fs, ws.iv, visit.t, visit.name
    transitions = visit.data.transitions
    n = visit.data.mode.dim
    if code == k.TRANSITION:
        e = int(iv[k.I_GUARD_INDEX])
        crossed = [e] + [f for f in range(len(transitions)) if ws.gv[f] < 0.0 and f != e]
        return cross(
            run, visit, e, float(fs[k.F_TC]), ws.q[:n].copy(), float(fs[k.F_LAND]), float(fs[k.F_TAU]), crossed
        )
    if code == k.FINISHED:
        return run.end_visit(visit, Ended(Status.FINISHED, "", float(fs[k.F_END])))
    if code == k.GUARD_NAN:
        message = messages.nan_guard(
            name, float(fs[k.F_NAN_T]), ws.x_new[:n], transitions[int(iv[k.I_GUARD_INDEX])].name
        )
        return run.end_visit(visit, Ended(Status.NON_FINITE, message, t))
    if code == k.NONFINITE_STEP:
        message = messages.non_finite_step(name, t, visit.x, float(fs[k.F_HTRIED]))
        return run.end_visit(visit, Ended(Status.NON_FINITE, message, t))
    if code == k.EXHAUSTED:
        message = messages.halving_exhausted(
            name, t, visit.x, int(iv[k.I_FAILED_HALVINGS]), transitions[int(iv[k.I_GUARD_INDEX])].name, run.eps
        )
        return run.end_visit(visit, Ended(Status.HALVING_EXHAUSTED, message, t))
    raise RuntimeError(f"compiled kernel returned unknown code {code}")  # pragma: no cover


def _with_width(buf: SegmentBuffer, width: int) -> SegmentBuffer:
    """``buf`` with rows of ``width`` entries (its points' first entries kept): the kernel
    stores the points of every mode of its table in one buffer as wide as the widest, Python
    stores a mode's points in a buffer of its own width."""
    if buf.x.shape[1] == width:
        return buf
    wide = SegmentBuffer(buf.mode, width, capacity=len(buf.t))
    n, size = min(width, buf.x.shape[1]), buf.size
    wide.t[:size], wide.x[:size, :n], wide.dx[:size, :n] = buf.t[:size], buf.x[:size, :n], buf.dx[:size, :n]
    wide.size = size
    return wide


def _grow(buf: SegmentBuffer) -> None:
    new = 4 * len(buf.t)  # every return from the kernel costs microseconds: grow fast
    buf.t = np.resize(buf.t, new)
    buf.x = np.resize(buf.x, (new, buf.x.shape[1]))
    buf.dx = np.resize(buf.dx, (new, buf.dx.shape[1]))


def _commit_records(run: Run, visit: ModeVisit, table: Table, ws: Workspace, n_rec: int) -> ModeVisit:
    """Turn the transitions the kernel crossed into Execution pieces (what ``strip.cross`` and
    the next visits' buffers would have built), and move the current segment into a fresh
    buffer of the visit of the mode the kernel is in, which is returned."""
    buf = visit.buf
    ends = ws.r_i[:n_rec, kt.R_END].tolist()
    # Thousands of small acyclic objects at once: the cyclic collector would scan the whole growing
    # execution again and again while they are made, and could free none of them.
    gc_was_enabled = gc.isenabled()
    gc.disable()
    try:
        _build_pieces(
            run,
            table,
            buf,
            ws.r_i[:n_rec].tolist(),
            ws.r_f[:n_rec].tolist(),
            ws.r_q[:n_rec].copy(),
            ws.r_after[:n_rec].copy(),
        )
    finally:
        if gc_was_enabled:
            gc.enable()
    for target in set(ws.r_i[:n_rec, kt.R_TARGET].tolist()):  # modes the kernel entered
        if target < len(table.datas):
            run.note_mode(table.datas[target])
    mode = table.names[int(ws.iv[kt.I_MODE])]
    if mode != visit.name:
        data = run.system.mode_data(mode)
        visit = ModeVisit(data, run.guard_fns(data), visit.t, visit.x)
    start, size = ends[-1], buf.size
    # As large as the old buffer: the steps to come will need it again.
    fresh = SegmentBuffer(mode, buf.x.shape[1], capacity=max(len(buf.t), 2 * (size - start)))
    m = size - start
    fresh.t[:m], fresh.x[:m], fresh.dx[:m] = buf.t[start:size], buf.x[start:size], buf.dx[start:size]
    fresh.size = m
    visit.buf = fresh
    return visit


def _build_pieces(
    run: Run, table: Table, buf: SegmentBuffer, r_i: list, r_f: list, qs: np.ndarray, afters: np.ndarray
) -> None:
    system, names = run.system, table.names
    T, X, DX = buf.t, buf.x, buf.dx
    q_rows, after_rows = list(qs), list(afters)  # row views, made in one go
    start = 0
    for j, (src, e, target, continued, end, length) in enumerate(r_i):
        mode = names[src]
        data = system.mode_data(mode)
        n = data.mode.dim
        # Views of this buffer: it is never written again once the tail moves out (copies of a
        # narrower mode's points).
        if n == X.shape[1]:
            x, dx = X[start:end], DX[start:end]
        else:
            x, dx = X[start:end, :n].copy(), DX[start:end, :n].copy()
        run.segments.append(Segment(mode, T[start:end], x, dx))
        tc, t_land, exit_time, tau = r_f[j]
        tr = data.transitions[e]
        name = tr.continuation.name if continued else tr.name
        q = q_rows[j][:n]
        after = after_rows[j][:length]
        run.strips.append(Strip(mode, name, tc, exit_time, q, t_land, tau))
        run.strip_time += exit_time - tc  # summed in the order the Python path sums them
        run.transitions.append(TransitionRecord(name, mode, names[target], e, tc, t_land, exit_time, q, after, tau))
        if continued:
            run.zeno.crossed(run, mode, tr.name, tc, exit_time, True, True)
        else:
            run.zeno.crossed(
                run,
                mode,
                tr.name,
                tc,
                exit_time,
                run.zeno.crossing(mode, tr.name, tc),
                False,
                tr.continuation is not None,
            )
        start = end
