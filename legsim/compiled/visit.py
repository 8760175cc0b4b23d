"""The compiled path's Python side: hand a mode visit's step loop to the kernel, turn the
transitions it crossed into Execution pieces in batches, and its return code into the same
outcome the Python loop reaches (``relaxed.integrate.run_visit``), with the same messages."""

from __future__ import annotations

import gc

import numpy as np

from ..execution import Segment, SegmentBuffer, Status, Strip, TransitionRecord
from ..relaxed import messages
from ..relaxed.outcomes import Ended, Entered, Outcome
from ..relaxed.run import ModeVisit, Run
from ..relaxed.strip import cross
from ..relaxed.integrate import out_of_steps
from . import kernel as k
from .generate import get_kernel, no_resets, plan_for
from .twin import check_twin, crosses_in_kernel

#: Transitions the kernel records per call before Python turns them into Execution pieces.
RECORD_CHUNK = 4096
#: Steps per kernel call when a progress callback wants reports (about 1 ms of work).
PROGRESS_CHUNK = 8192
_NO_LIMIT = 1 << 62


class Workspace:
    """Per-run scratch arrays of the kernel for one mode (reused across visits)."""

    def __init__(self, n: int, stages: int, n_guards: int) -> None:
        self.K = np.zeros((stages, n))
        self.XS, self.x_new, self.k1, self.work = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)
        self.q, self.dq = np.zeros(n), np.zeros(n)
        self.gv = np.zeros(max(1, n_guards))
        self.fs = np.zeros(8)
        self.iv = np.zeros(10, dtype=np.int64)
        self.cf = np.zeros(6)
        self.ci = np.zeros(7, dtype=np.int64)
        self.r_e = np.zeros(RECORD_CHUNK, dtype=np.int64)
        self.r_f = np.zeros((RECORD_CHUNK, 4))
        self.r_q = np.zeros((RECORD_CHUNK, n))
        self.r_after = np.zeros((RECORD_CHUNK, n))
        self.seg_end = np.zeros(RECORD_CHUNK, dtype=np.int64)


def run_visit_compiled(run: Run, visit: ModeVisit) -> Outcome:
    """The step loop of one mode visit, compiled. With in-kernel transitions one call covers
    many visits of the same mode."""
    data, twin = visit.data, visit.data.mode.compiled
    checked = run.scratch.setdefault("compiled_checked", {})
    if visit.name not in checked:
        checked[visit.name] = check_twin(run.system.name, data, visit.t, visit.x, visit.k0)
    ws = _workspace(run, visit, twin.n_guards)
    kernel = get_kernel(twin.field, twin.guards, no_resets if twin.resets is None else twin.resets)
    plan = plan_for(run.tableau)
    x = np.array(visit.x, dtype=float)
    ws.K[0] = visit.k0
    in_kernel = crosses_in_kernel(data, run.zeno.continues, checked[visit.name]) and run.system.joint is None
    _settings(run, ws, plan, in_kernel)
    ws.fs[k.F_T], ws.fs[k.F_HPROP] = visit.t, run.step_size.h_prop
    while True:
        ws.ci[3] = min(PROGRESS_CHUNK if run.has_progress else _NO_LIMIT, run.max_steps - run.steps)
        ws.ci[5] = max(0, run.max_transitions - len(run.transitions))
        ws.iv[k.I_SIZE] = visit.buf.size
        buf = visit.buf
        code = kernel(twin.params, twin.n_guards, plan.c, plan.n_groups, plan.weights, plan.n_members, plan.members,
                      plan.b_err, plan.fsal, x, ws.K, ws.XS, ws.x_new, ws.k1, ws.gv, ws.work, ws.q, ws.dq, buf.t, buf.x,
                      buf.dx, ws.fs, ws.iv, ws.cf, ws.ci, ws.r_e, ws.r_f, ws.r_q, ws.r_after, ws.seg_end)
        buf.size = int(ws.iv[k.I_SIZE])
        _count(run, ws)
        if ws.iv[k.I_RECORDS]:
            visit.buf = _commit_records(run, visit, ws, int(ws.iv[k.I_RECORDS]))
        visit.t = float(ws.fs[k.F_T])
        if code == k.BUFFER_FULL:
            _grow(visit.buf)
        elif code == k.CHUNK:
            run.tick(visit.t)
            if run.steps >= run.max_steps:
                visit.x = x
                return run.end_visit(visit, out_of_steps(run, visit))
        elif code == k.RECORDS_FULL:
            run.tick(visit.t)
        else:
            break
    visit.x = x
    if code == k.GUARD_NAN and twin.fallback:
        return _python_rest(run, visit, ws)
    return _outcome(run, visit, ws, code)


def _python_rest(run: Run, visit: ModeVisit, ws: Workspace) -> Outcome:
    """The rest of the visit on the Python loop, from the kernel's last accepted point: a twin
    with ``fallback`` returns nan guards past its model's range, where the Python callables
    raise the ModelBreakdown the loop shortens the step for (or ends the run with)."""
    from ..relaxed.integrate import run_visit

    visit.k0 = ws.K[0].copy()
    return run_visit(run, visit, python=True)


def _workspace(run: Run, visit: ModeVisit, n_guards: int) -> Workspace:
    spaces = run.scratch.setdefault("compiled_workspaces", {})
    ws = spaces.get(visit.name)
    if ws is None:
        ws = spaces[visit.name] = Workspace(visit.data.mode.dim, run.tableau.stages, n_guards)
    return ws


def _settings(run: Run, ws: Workspace, plan, in_kernel: bool) -> None:
    step_size = run.step_size
    ws.cf[:] = (run.t_final, step_size.h_max, run.eps, getattr(step_size, "rtol", 0.0),
                getattr(step_size, "atol", 0.0), getattr(step_size, "exponent", 0.0))
    ws.ci[:5] = (step_size.adaptive, run.landing.name == "aim", run.max_halvings, 0, in_kernel)
    ws.ci[6] = plan.method_id


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
    if code == k.TRANSITION:
        e = int(iv[k.I_GUARD_INDEX])
        crossed = [e] + [f for f in range(len(transitions)) if ws.gv[f] < 0.0 and f != e]
        return cross(run, visit, e, float(fs[k.F_TC]), ws.q.copy(), float(fs[k.F_LAND]), float(fs[k.F_TAU]), crossed)
    if code == k.NEXT:
        # The state entering the mode again needs the entry's special cases (in a strip, or a
        # non-finite field or guard): the Python entry takes it from here. The segment before it
        # was committed with its transition; nothing of the next one is stored yet.
        return Entered(name, visit.x.copy(), t)
    if code == k.FINISHED:
        return run.end_visit(visit, Ended(Status.FINISHED, "", float(fs[k.F_END])))
    if code == k.GUARD_NAN:
        message = messages.nan_guard(name, float(fs[k.F_NAN_T]), ws.x_new, transitions[int(iv[k.I_GUARD_INDEX])].name)
        return run.end_visit(visit, Ended(Status.NON_FINITE, message, t))
    if code == k.NONFINITE_STEP:
        message = messages.non_finite_step(name, t, visit.x, float(fs[k.F_HTRIED]))
        return run.end_visit(visit, Ended(Status.NON_FINITE, message, t))
    if code == k.EXHAUSTED:
        message = messages.halving_exhausted(name, t, visit.x, int(iv[k.I_FAILED_HALVINGS]),
                                             transitions[int(iv[k.I_GUARD_INDEX])].name, run.eps)
        return run.end_visit(visit, Ended(Status.HALVING_EXHAUSTED, message, t))
    raise RuntimeError(f"compiled kernel returned unknown code {code}")  # pragma: no cover


def _grow(buf: SegmentBuffer) -> None:
    new = 4 * len(buf.t)  # every return from the kernel costs microseconds: grow fast
    buf.t = np.resize(buf.t, new)
    buf.x = np.resize(buf.x, (new, buf.x.shape[1]))
    buf.dx = np.resize(buf.dx, (new, buf.dx.shape[1]))


def _commit_records(run: Run, visit: ModeVisit, ws: Workspace, n_rec: int) -> SegmentBuffer:
    """Turn the transitions the kernel crossed into Execution pieces (what ``strip.cross`` and
    the next visit's buffer would have built), and move the current segment into a fresh
    buffer, which is returned."""
    buf, mode = visit.buf, visit.name
    r_f = ws.r_f[:n_rec].tolist()
    ends = ws.seg_end[:n_rec].tolist()
    # Thousands of small acyclic objects at once: the cyclic collector would scan the whole growing
    # execution again and again while they are made, and could free none of them.
    gc_was_enabled = gc.isenabled()
    gc.disable()
    try:
        _build_pieces(run, visit, ws.r_e[:n_rec].tolist(), r_f, ws.r_q[:n_rec].copy(), ws.r_after[:n_rec].copy(), ends)
    finally:
        if gc_was_enabled:
            gc.enable()
    start, size = ends[-1], buf.size
    # As large as the old buffer: the steps to come will need it again.
    fresh = SegmentBuffer(mode, buf.x.shape[1], capacity=max(len(buf.t), 2 * (size - start)))
    m = size - start
    fresh.t[:m], fresh.x[:m], fresh.dx[:m] = buf.t[start:size], buf.x[start:size], buf.dx[start:size]
    fresh.size = m
    return fresh


def _build_pieces(run: Run, visit: ModeVisit, r_e: list, r_f: list, qs: np.ndarray, afters: np.ndarray,
                  ends: list) -> None:
    mode, trs, buf = visit.name, visit.data.transitions, visit.buf
    T, X, DX = buf.t, buf.x, buf.dx
    q_rows, after_rows = list(qs), list(afters)  # row views, made in one go
    start = 0
    for j, end in enumerate(ends):
        # Views of this buffer: it is never written again once the tail moves out.
        run.segments.append(Segment(mode, T[start:end], X[start:end], DX[start:end]))
        tc, t_land, exit_time, tau = r_f[j]
        tr = trs[r_e[j]]
        run.strips.append(Strip(mode, tr.name, tc, exit_time, q_rows[j], t_land, tau))
        run.strip_time += exit_time - tc  # summed in the order the Python path sums them
        run.transitions.append(TransitionRecord(tr.name, mode, mode, r_e[j], tc, t_land, exit_time, q_rows[j],
                                                after_rows[j], tau))
        run.zeno.crossed(run, mode, tr.name, tc, exit_time, run.zeno.crossing(mode, tr.name, tc), False,
                         tr.continuation is not None)
        start = end

