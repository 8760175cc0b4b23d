"""The closed loop's evaluations in one mode: field, guards, resets and the controller, with the
evaluations counted.

A run's state is the plant's state followed by the controller's memory (``Visit.n`` entries:
``dim`` of the plant, then ``memory``). The controller's input u is evaluated at every
evaluation of the field or the guards, at the same (t, x), except under a zero-order hold,
where it is evaluated once at each step's start (``hold_control``) and kept over the step. The
memory does not flow (its derivative is 0); it changes at mode entries only, when a transition's
reset is followed by the controller's entry function (``closed_reset``).
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np

from .calls import call_indexed, call_state
from .layout import (
    I_FIELD_EVALS,
    I_GUARD_EVALS,
    I_RESET_EVALS,
    M_C0,
    M_C1,
    M_CONTROL,
    M_CROSSES_JUMPS,
    M_DIM,
    M_ENTER,
    M_FIELD,
    M_GUARD_FN,
    M_GUARDS,
    M_JOINT,
    M_NAN_BREAKS,
    M_P0,
    M_P1,
    M_PREVIEWED,
    M_RESET,
    S_HOLD,
    S_MEMORY,
)

#: A run's tables (``legsim.relaxed.tables``): the function table, the mode, transition and
#: joint-outcome tables (``layout.M_*``, ``T_*``, ``J_*``) and every parameter array P.
Tables = namedtuple("Tables", "functions modes transitions joints P")
#: One mode as the loop evaluates it: its row, the state length n (plant dim + memory), the
#: plant's dim, its guard count, its functions' indices (-1: none), its parameters p and the
#: controller's pc there, whether a nan from its functions means "past the model's range", and
#: whether its crossings are resolved with the input applied after them, and whether a guard
#: that jumps past its strip is crossed where it jumps.
Visit = namedtuple(
    "Visit", "mode n dim guards field guard_fn reset joint control enter p pc nan_breaks previewed crosses_jumps"
)


def visit_of(tab: Tables, memory: int, mode: int) -> Visit:
    """The ``Visit`` of mode row ``mode`` in a run whose controller keeps ``memory`` values."""
    row = tab.modes[mode]
    dim = row[M_DIM]
    return Visit(
        mode,
        dim + memory,
        dim,
        row[M_GUARDS],
        row[M_FIELD],
        row[M_GUARD_FN],
        row[M_RESET],
        row[M_JOINT],
        row[M_CONTROL],
        row[M_ENTER],
        tab.P[row[M_P0] : row[M_P1]],
        tab.P[row[M_C0] : row[M_C1]],
        row[M_NAN_BREAKS] == 1,
        row[M_PREVIEWED] == 1,
        row[M_CROSSES_JUMPS] == 1,
    )


def control_now(tab: Tables, vis: Visit, ws, t: float, x: np.ndarray) -> None:
    """The controller's input at (t, x) into ws.u (nothing without a controller); an entry it
    leaves unwritten is nan, never an earlier call's value."""
    if vis.control >= 0:
        unwritten(ws.u, ws.u.shape[0])
        call_state(tab.functions, vis.control, t, x[: vis.dim], x[vis.dim : vis.n], vis.pc, ws.u)


def hold_control(tab: Tables, vis: Visit, ws, t: float, x: np.ndarray) -> None:
    """Under a zero-order hold, sample the controller at a step's start (t, x)."""
    if ws.ci[S_HOLD] == 1:
        control_now(tab, vis, ws, t, x)


def field_at(tab: Tables, vis: Visit, ws, t: float, x: np.ndarray, out: np.ndarray) -> None:
    """dx/dt of the closed loop at (t, x) into out[:n] (the memory's entries 0)."""
    if ws.ci[S_HOLD] == 0:
        control_now(tab, vis, ws, t, x)
    unwritten(out, vis.dim)
    call_state(tab.functions, vis.field, t, x[: vis.dim], ws.u, vis.p, out[: vis.dim])
    for d in range(vis.dim, vis.n):
        out[d] = 0.0
    ws.iv[I_FIELD_EVALS] += 1


def guards_at(tab: Tables, vis: Visit, ws, t: float, x: np.ndarray, out: np.ndarray) -> float:
    """Every guard of the mode at (t, x) into out[:guards]; returns the least (nan when one is
    nan, +inf without guards)."""
    if vis.guards == 0:
        return np.inf
    if ws.ci[S_HOLD] == 0:
        control_now(tab, vis, ws, t, x)
    unwritten(out, vis.guards)
    call_state(tab.functions, vis.guard_fn, t, x[: vis.dim], ws.u, vis.p, out[: vis.guards])
    ws.iv[I_GUARD_EVALS] += vis.guards
    return least(out, vis.guards)


def guards_under(tab: Tables, vis: Visit, ws, t: float, x: np.ndarray, u: np.ndarray, out: np.ndarray) -> None:
    """Every guard of the mode at (t, x) under the given input u (not the controller's there)
    into out[:guards]."""
    if vis.guards > 0:
        unwritten(out, vis.guards)
        call_state(tab.functions, vis.guard_fn, t, x[: vis.dim], u, vis.p, out[: vis.guards])
        ws.iv[I_GUARD_EVALS] += vis.guards


def input_after(tab: Tables, target: Visit, ws, t: float, x: np.ndarray, u: np.ndarray) -> None:
    """The controller's input in ``target``'s mode at (t, x) into u, x the target's state whose
    memory x[dim:n] the controller's entry updates in place (a preview: x is scratch)."""
    enter_controller(tab, target, ws, t, x)
    unwritten(u, u.shape[0])
    call_state(tab.functions, target.control, t, x[: target.dim], x[target.dim : target.n], target.pc, u)


def unwritten(out: np.ndarray, count: int) -> None:
    """out[:count] set to nan before a model function writes its result there: an entry it
    leaves unwritten is then a non-finite value the loop reports (naming the mode, or the
    transition of a guard), never the previous call's value taken for this one's."""
    for d in range(count):
        out[d] = np.nan


def least(values: np.ndarray, count: int) -> float:
    """The least of values[:count], nan when one of them is nan."""
    low = np.inf
    for e in range(count):
        v = values[e]
        if v != v:
            return np.nan
        if v < low:
            low = v
    return low


def argleast(values: np.ndarray, count: int) -> int:
    """Index of the least of values[:count] (the first of equals)."""
    best = 0
    for e in range(1, count):
        if values[e] < values[best]:
            best = e
    return best


def closed_reset(
    tab: Tables, vis: Visit, target: Visit, ws, e: int, t: float, t_enter: float, q: np.ndarray, out: np.ndarray
) -> None:
    """The closed loop's reset of transition e (e >= guards: its continuation) at the guard point
    q reached at time t, the target entered at ``t_enter``: the plant's reset into
    out[:target.dim], the memory carried and then updated by the controller's entry function
    into out[target.dim:target.n]."""
    if ws.ci[S_HOLD] == 0:
        control_now(tab, vis, ws, t, q)
    reset_under(tab, vis, target, ws, e, t, t_enter, q, ws.u, out)


def reset_under(
    tab: Tables, vis: Visit, target: Visit, ws, e: int, t: float, t_enter: float, q: np.ndarray, u: np.ndarray,
    out: np.ndarray,
) -> None:  # fmt: skip
    """``closed_reset`` with the plant's reset under the given input u (a previewed crossing's:
    the input its outcome was chosen under)."""
    if vis.reset >= 0:
        unwritten(out, target.dim)
        call_indexed(tab.functions, vis.reset, e, t, q[: vis.dim], u, vis.p, out[: target.dim])
    else:
        for d in range(target.dim):
            out[d] = q[d]
    ws.iv[I_RESET_EVALS] += 1
    memory = ws.ci[S_MEMORY]
    for d in range(memory):
        out[target.dim + d] = q[vis.dim + d]
    enter_controller(tab, target, ws, t_enter, out)


def enter_controller(tab: Tables, vis: Visit, ws, t: float, x: np.ndarray) -> None:
    """The controller enters ``vis``'s mode at (t, x): its entry function updates the memory
    x[dim:n] in place (through ws.m_new)."""
    if vis.enter < 0:
        return
    memory = ws.ci[S_MEMORY]
    unwritten(ws.m_new, memory)
    call_state(tab.functions, vis.enter, t, x[: vis.dim], x[vis.dim : vis.n], vis.pc, ws.m_new[:memory])
    for d in range(memory):
        x[vis.dim + d] = ws.m_new[d]
