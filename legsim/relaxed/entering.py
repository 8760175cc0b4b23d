"""Entering a mode (at the start of a run or at a strip's exit).

* The field and guards are evaluated on the entering state; a non-finite value ends the run.
* A state that enters a mode already inside one of its strips (a reset image at a guard
  intersection, or an initial state in a strip) crosses that strip at once, with q = x; one past
  a guard by more than eps ends the run (``END_RESET_OUTSIDE``).
* Under a zero-order hold each step's start is a new sample of the controller, and a guard that
  reads the input jumps there by design: the guards are evaluated again under the new sample, and
  a strip entered or passed there is crossed at once, at the sample (``cross_at_sample``).
* With error control the new mode restarts at the standard starting step, and with dense landing
  a mode entered a hair before another guard's strip (the second foot of a symmetric touchdown)
  takes one short step to that strip instead of a full step (``short_first_step``).
"""

from __future__ import annotations

import math

import numpy as np

from .crossing import CROSSED, append_point, cross, cross_landing, start_visit, zero
from .curve import set_hermite
from .evaluate import Tables, Visit, argleast, field_at, guards_at, hold_control, visit_of
from .layout import (
    END_FIELD_AT_ENTRY,
    END_GUARD_AT_ENTRY,
    END_RESET_OUTSIDE,
    F_H_PROP,
    F_T,
    I_END,
    I_END_INDEX,
    I_JACOBIAN_AGE,
    I_LAST_SOURCE,
    I_MODE,
    I_PHASE,
    I_STEPS,
    I_TRANSITIONS,
    LAND_DENSE,
    M_READY,
    M_T0,
    PHASE_ENDED,
    PHASE_STEP,
    S_ADAPTIVE,
    S_ATOL,
    S_EPS,
    S_EXPONENT,
    S_H_MAX,
    S_LANDING,
    S_MEMORY,
    S_RTOL,
    S_T_FINAL,
    T_TARGET,
)
from .rules import (
    entered_in_strip,
    on_guard_depth,
    past_strip,
    restarted_step,
    scaled_rms,
    starting_guess,
    starting_step,
)
from .stages import all_finite

#: What entering a mode leads to: the mode's steps; a crossing at once (another entry, or the
#: run's end); the run's end; the mode has no row of targets yet (the driver builds them).
ENTERED, CROSSED_AT_ONCE, ENTRY_ENDED, NOT_READY = range(4)
#: A simultaneous event: a guard's strip is reached within this share of the next step.
SIMULTANEOUS = 1e-3


def enter(tab: Tables, ws, method) -> int:
    """Enter mode ws.iv[I_MODE] at (F_T, ws.x): its first point stored, its guards at
    ws.g_here (module docstring)."""
    mode = ws.iv[I_MODE]
    if tab.modes[mode, M_READY] == 0:
        return NOT_READY
    vis = visit_of(tab, ws.ci[S_MEMORY], mode)
    t, n = ws.fs[F_T], vis.n
    ws.iv[I_JACOBIAN_AGE] = -1  # a new mode's field: a linearly implicit method needs its Jacobian
    x = ws.x[:n]
    start_visit(ws, mode)
    hold_control(tab, vis, ws, t, x)
    field_at(tab, vis, ws, t, x, ws.K[0])
    if not all_finite(ws.K[0, :n]):
        zero(ws.k1[:n])
        append_point(ws, t, x, ws.k1[:n])
        return end_entry(ws, END_FIELD_AT_ENTRY, -1)
    append_point(ws, t, x, ws.K[0, :n])
    gmin = guards_at(tab, vis, ws, t, x, ws.g_here)
    bad = first_nonfinite(ws.g_here, vis.guards)
    if bad >= 0:
        return end_entry(ws, END_GUARD_AT_ENTRY, bad)
    if vis.guards > 0 and entered_in_strip(gmin, ws.cf[S_EPS]):
        return cross_at_once(tab, vis, ws, vis.crosses_jumps)
    ws.iv[I_PHASE] = PHASE_STEP
    if ws.ci[S_ADAPTIVE] == 1 and ws.iv[I_TRANSITIONS] > 0 and ws.iv[I_LAST_SOURCE] != mode:
        # Not after a self-transition: the same field goes on.
        restart(tab, vis, ws)
        if ws.ci[S_LANDING] == LAND_DENSE and vis.guards > 0 and short_first_step(tab, vis, ws, method):
            return CROSSED_AT_ONCE
    return ENTERED


def end_entry(ws, reason: int, index: int) -> int:
    """End the run at a mode's entry (``layout.END_*``)."""
    ws.iv[I_END] = reason
    ws.iv[I_END_INDEX] = index
    ws.iv[I_PHASE] = PHASE_ENDED
    return ENTRY_ENDED


def first_nonfinite(values: np.ndarray, count: int) -> int:
    """Index of the first of values[:count] that is not finite, -1 when all are."""
    for e in range(count):
        if not math.isfinite(values[e]):
            return e
    return -1


def cross_at_sample(tab: Tables, vis: Visit, ws) -> int:
    """A held controller was sampled again at the step's start (t, x): the guards under the new
    sample into ws.g_here, and a strip the sample put the state in, or past, crossed at once
    there. A guard past its strip here has jumped with the held input, which is how a zero-order
    hold switches (a digital controller acts at its samples), not a model's error."""
    t, n = ws.fs[F_T], vis.n
    gmin = guards_at(tab, vis, ws, t, ws.x[:n], ws.g_here)
    bad = first_nonfinite(ws.g_here, vis.guards)
    if bad >= 0:
        return end_entry(ws, END_GUARD_AT_ENTRY, bad)
    if gmin < 0.0:
        return cross_at_once(tab, vis, ws, True)
    return ENTERED


def cross_at_once(tab: Tables, vis: Visit, ws, jumped: bool) -> int:
    """The state at a mode's entry (or a held controller's sample) lies in a strip: cross it at
    once with q = x. Past the strip it ends the run, unless the guard has ``jumped`` there (the
    mode crosses its guards where they jump, or a held input changed): a state entering past a
    strip has then met a jump of that guard."""
    e = argleast(ws.g_here, vis.guards)
    t = ws.fs[F_T]
    if past_strip(ws.g_here[e], ws.cf[S_EPS]) and not jumped:
        return end_entry(ws, END_RESET_OUTSIDE, e)
    for d in range(vis.n):
        ws.q[d] = ws.x[d]
        ws.x1[d] = ws.x[d]  # the landing point too, where a previewed crossing is asked again
    for f in range(vis.guards):
        ws.crossed[f] = 1.0 if f == e else 0.0
        ws.g1[f] = ws.g_here[f]
    outcome = cross(tab, vis, ws, e, t, t, -ws.g_here[e], 1, -1, -1)
    return CROSSED_AT_ONCE if outcome == CROSSED else ENTRY_ENDED


def restart(tab: Tables, vis: Visit, ws) -> None:
    """A new mode's flow (a stance after a touchdown) may want a much shorter step than the one
    the previous mode ended with: start it at the smaller of that and the standard starting step
    of Hairer, Norsett and Wanner (I, Sec. II.4), from f at x and one explicit Euler step away.
    The norms run over the plant's coordinates (the memory does not flow)."""
    t, dim = ws.fs[F_T], vis.dim
    rtol, atol = ws.cf[S_RTOL], ws.cf[S_ATOL]
    x, k0 = ws.x[:dim], ws.K[0, :dim]
    d1 = scaled_rms(k0, x, rtol, atol)
    h0 = starting_guess(scaled_rms(x, x, rtol, atol), d1, ws.cf[S_H_MAX])
    for d in range(vis.n):
        ws.XS[d] = ws.x[d] + h0 * ws.K[0, d]
    field_at(tab, vis, ws, t + h0, ws.XS[: vis.n], ws.w)
    for d in range(dim):
        ws.w[d] = ws.w[d] - k0[d]
    d2 = scaled_rms(ws.w[:dim], x, rtol, atol) / h0
    if math.isfinite(d2):
        ws.fs[F_H_PROP] = restarted_step(ws.fs[F_H_PROP], starting_step(h0, d1, d2, ws.cf[S_EXPONENT]))


def short_first_step(tab: Tables, vis: Visit, ws, method) -> bool:
    """The first step of a newly entered mode when the flow reaches the middle of some guard's
    strip within ``SIMULTANEOUS`` of the step it would take (a simultaneous event): a step of
    exactly that length by Heun's method, whose Euler estimate must pass the error test (its
    local error is O(tau^3), tau ~ eps / speed). It is an ordinary relaxed step: accepted only if
    it lands in the relaxed domain, the crossing then found on its own quadratic interpolant (the
    cubic Hermite interpolant of its ends is that quadratic). Returns whether it crossed."""
    tau = time_to_simultaneous_strip(tab, vis, ws)
    t, n, dim = ws.fs[F_T], vis.n, vis.dim
    if tau != tau or not t + tau > t or t + tau >= ws.cf[S_T_FINAL]:
        return False
    for d in range(n):
        ws.XS[d] = ws.x[d] + tau * ws.K[0, d]
    field_at(tab, vis, ws, t + tau, ws.XS[:n], ws.k1)
    for d in range(n):
        ws.x1[d] = ws.x[d] + (0.5 * tau) * (ws.K[0, d] + ws.k1[d])
    rtol, atol = ws.cf[S_RTOL], ws.cf[S_ATOL]
    total = 0.0
    for d in range(dim):
        r = (0.5 * tau) * (ws.k1[d] - ws.K[0, d]) / (atol + rtol * max(abs(ws.x[d]), abs(ws.x1[d])))
        total += r * r
    if not math.sqrt(total / dim) <= 1.0:
        return False
    gmin = guards_at(tab, vis, ws, t + tau, ws.x1[:n], ws.g1)
    if first_nonfinite(ws.g1, vis.guards) >= 0 or not (-ws.cf[S_EPS] <= gmin < 0.0) or not all_finite(ws.x1[:n]):
        return False
    ws.iv[I_STEPS] += 1
    set_hermite(ws, t + tau)
    cross_landing(tab, vis, ws, method)
    return True


def time_to_simultaneous_strip(tab: Tables, vis: Visit, ws) -> float:
    """The time for the flow to reach the middle of the nearest strip of a guard that is within
    eps ahead, or on the guard (``rules.on_guard_depth``: the second foot of a symmetric touchdown
    reaches the ground with the first one, to rounding), and closing (guards leading straight
    back to the mode just left are not considered: a shallow graze must be stepped over, not
    crossed back and forth); nan when none is reached within ``SIMULTANEOUS`` of the next step."""
    eps, t, n = ws.cf[S_EPS], ws.fs[F_T], vis.n
    h_next = min(ws.fs[F_H_PROP], ws.cf[S_H_MAX])
    came_from = ws.iv[I_LAST_SOURCE]
    speed = 0.0
    for d in range(n):
        speed += ws.K[0, d] * ws.K[0, d]
    speed = math.sqrt(speed)
    if not (math.isfinite(speed) and speed > 0.0):
        return math.nan
    dt = 1e-7 / max(1.0, speed)
    for d in range(n):
        ws.XS[d] = ws.x[d] + dt * ws.K[0, d]
    guards_at(tab, vis, ws, t + dt, ws.XS[:n], ws.g_w)
    base = tab.modes[vis.mode, M_T0]
    on_guard = -on_guard_depth(eps)
    tau = math.nan
    for e in range(vis.guards):
        g = ws.g_here[e]
        if tab.transitions[base + e, T_TARGET] == came_from or not on_guard <= g <= eps:
            continue
        rate = (ws.g_w[e] - g) / dt
        if not rate < 0.0:
            continue
        reach = (g + 0.5 * eps) / -rate
        if reach <= SIMULTANEOUS * h_next and (tau != tau or reach < tau):
            tau = reach
    return tau
