"""The relaxed hybrid integrator's loop (paper 000, Fig. 12; paper 003, Definition 14 for Euler).

Each guard is thickened into a strip ``-eps <= guard < 0``. Inside a mode any Runge-Kutta method
takes steps; a trial step that would leave the relaxed domain is shortened until it lands in it;
a step that lands in a strip crosses it: q is located on the step's curve, the state held there
for the rest of the strip, eps - tau, and the reset applied at q::

    while t < t_final:
        enter the mode at (t, x)                    # entering: field, guards, a strip at once
        trial = step(t, x, h)                       # stepping: method, step-size rule
        while trial leaves the relaxed domain:      # landing rule: halve | aim | dense
            trial = shorten(trial)
        if trial lands in a strip:                  # crossing: locate q, hold eps - tau, reset at q
            mode, x, t = cross(trial)
        else:
            t, x = trial.t1, trial.x1

This source is the only statement of that loop. It is plain Python over arrays
(``legsim.relaxed.layout`` names their slots): run as it is, it steps a model of Python callables;
compiled by numba (``legsim.compiled``), the same functions step a model of compiled functions.
It hands back to its driver (``legsim.relaxed.driver``) when the run ends, when a mode to enter
has no row yet, when an output buffer is full, or when a progress report is due; the driver
resumes it where it stopped.
"""

from __future__ import annotations

from .crossing import append_point, cross_landing
from .entering import NOT_READY, cross_at_sample, enter
from .evaluate import Tables, Visit, field_at, hold_control, least, visit_of
from .layout import (
    END_FINISHED,
    END_MAX_STEPS,
    END_STALLED,
    F_LAND_T1,
    F_STALL_T,
    F_T,
    I_END,
    I_END_INDEX,
    I_MODE,
    I_PHASE,
    I_POINTS,
    I_RECORDS,
    I_REPORTED,
    I_REPORTED_TRANSITIONS,
    I_STALL_COUNT,
    I_STEPS,
    I_TRANSITIONS,
    I_VISITS,
    PHASE_ENDED,
    PHASE_ENTER,
    RETURN_ENDED,
    RETURN_FULL,
    RETURN_NEED_MODE,
    RETURN_PROGRESS,
    S_H_MAX,
    S_HOLD,
    S_MAX_STEPS,
    S_MEMORY,
    S_PROGRESS_STEPS,
    S_T_FINAL,
)
from .rules import finish_tolerance
from .stages import INFO_FSAL, INFO_STAGES, MethodArrays
from .stepping import STEP_ENDED, take_step
from .workspace import Workspace

#: Room an iteration of the loop needs in the output buffers: the points of a step, a crossing
#: and an entry; the records of a crossing and a crossing at once; the visits of two entries.
ROOM_POINTS, ROOM_RECORDS, ROOM_VISITS = 4, 2, 2
#: ``run`` goes on.
GOING = -1
#: A run whose last ``STALL_WINDOW`` steps and crossings moved time by less than
#: ``STALL_FRACTION`` of h has stopped advancing (an eps too thin to land in, a model that
#: traps the step at a guard): it ends, rather than crawl on.
STALL_WINDOW, STALL_FRACTION = 1000, 1e-6


def run(tab: Tables, ws, method: MethodArrays) -> int:
    """Run from where ws says (``I_PHASE``) until the run ends or the driver is needed
    (``layout.RETURN_*``)."""
    while True:
        phase = ws.iv[I_PHASE]
        if phase == PHASE_ENDED:
            return RETURN_ENDED
        if not has_room(ws):
            return RETURN_FULL
        if phase == PHASE_ENTER:
            if enter(tab, ws, method) == NOT_READY:
                return RETURN_NEED_MODE
            code = GOING
        else:
            code = step_once(tab, ws, method)
        if code == GOING and ws.iv[I_PHASE] != PHASE_ENDED and stalled(ws):
            return end_loop(ws, END_STALLED)
        if code != GOING:
            return code


def run_flat(tab: tuple, ws: tuple, method: tuple) -> int:
    """``run`` with its three arguments as plain tuples of their arrays: the compiled loop's
    entry. numba's dispatch types a plain tuple of arrays in C but a named one field by field in
    Python, several times slower for the ~50 arrays of a run (docs/architecture.md, "The loop")."""
    return run(Tables(*tab), Workspace(*ws), MethodArrays(*method))


def has_room(ws) -> bool:
    """Whether the output buffers have room for one more iteration."""
    return (
        ws.iv[I_POINTS] + ROOM_POINTS <= ws.T.shape[0]
        and ws.iv[I_RECORDS] + ROOM_RECORDS <= ws.rec_f.shape[0]
        and ws.iv[I_VISITS] + ROOM_VISITS <= ws.visits.shape[0]
    )


def step_once(tab: Tables, ws, method: MethodArrays) -> int:
    """One accepted step of the current mode: the point stored, or the strip it landed in
    crossed; ``GOING``, or why the loop hands back."""
    vis = visit_of(tab, ws.ci[S_MEMORY], ws.iv[I_MODE])
    t = ws.fs[F_T]
    remaining = ws.cf[S_T_FINAL] - t
    if remaining <= finish_tolerance(ws.cf[S_T_FINAL]):
        if remaining > 0.0:
            ws.fs[F_T] = ws.cf[S_T_FINAL]
        return end_loop(ws, END_FINISHED)
    if ws.iv[I_STEPS] >= ws.ci[S_MAX_STEPS]:
        return end_loop(ws, END_MAX_STEPS)
    if take_step(tab, vis, ws, method, remaining) == STEP_ENDED:
        ws.iv[I_PHASE] = PHASE_ENDED
        return RETURN_ENDED
    if least(ws.g1, vis.guards) >= 0.0:
        advance(tab, vis, ws, method)
        if ws.ci[S_HOLD] == 1 and vis.guards > 0:
            cross_at_sample(tab, vis, ws)
    else:
        cross_landing(tab, vis, ws, method)
    return GOING if not report_due(ws) else RETURN_PROGRESS


def stalled(ws) -> bool:
    """Whether the run has stopped advancing time: its last ``STALL_WINDOW`` entries, steps and
    crossings moved it by less than ``STALL_FRACTION`` of h."""
    ws.iv[I_STALL_COUNT] += 1
    if ws.iv[I_STALL_COUNT] < STALL_WINDOW:
        return False
    if ws.fs[F_T] - ws.fs[F_STALL_T] < STALL_FRACTION * ws.cf[S_H_MAX]:
        return True
    ws.iv[I_STALL_COUNT] = 0
    ws.fs[F_STALL_T] = ws.fs[F_T]
    return False


def report_due(ws) -> bool:
    """Whether a progress report is due: every ``S_PROGRESS_STEPS`` steps or transitions (a Zeno
    run may cross many strips per step)."""
    every = ws.ci[S_PROGRESS_STEPS]
    if every <= 0:
        return False
    if ws.iv[I_STEPS] - ws.iv[I_REPORTED] >= every or ws.iv[I_TRANSITIONS] - ws.iv[I_REPORTED_TRANSITIONS] >= every:
        ws.iv[I_REPORTED] = ws.iv[I_STEPS]
        ws.iv[I_REPORTED_TRANSITIONS] = ws.iv[I_TRANSITIONS]
        return True
    return False


def end_loop(ws, reason: int) -> int:
    """End the run inside a mode (``layout.END_*``)."""
    ws.iv[I_END] = reason
    ws.iv[I_END_INDEX] = -1
    ws.iv[I_PHASE] = PHASE_ENDED
    return RETURN_ENDED


def advance(tab: Tables, vis: Visit, ws, method: MethodArrays) -> None:
    """Move to the accepted step's end and store the point, with f there: under a zero-order
    hold the controller is sampled again there (f changes), with FSAL the step's last stage,
    else one evaluation."""
    n = vis.n
    t = ws.fs[F_LAND_T1]
    ws.fs[F_T] = t
    for d in range(n):
        ws.x[d] = ws.x1[d]
    for e in range(vis.guards):
        ws.g_here[e] = ws.g1[e]
    if ws.ci[S_HOLD] == 1:
        hold_control(tab, vis, ws, t, ws.x[:n])
        field_at(tab, vis, ws, t, ws.x[:n], ws.K[0])
    elif method.info[INFO_FSAL] == 1:
        s = method.info[INFO_STAGES]
        for d in range(n):
            ws.K[0, d] = ws.K[s - 1, d]
    else:
        field_at(tab, vis, ws, t, ws.x[:n], ws.K[0])
    append_point(ws, t, ws.x[:n], ws.K[0, :n])
