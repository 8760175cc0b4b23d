"""Transitions inside the compiled kernel: the crossing of a strip, the reset at q, the Zeno
continuation and the entry of the next mode, for the modes of a system's table (``table``).

Plain Python that numba compiles with the kernel (``generate``). It takes the decisions
``relaxed.strip.cross`` and ``relaxed.entry.enter_mode`` take, with the same rules
(``legsim.relaxed.rules``) in the same order; what it cannot take it hands back to Python
untouched, so that the Python loop takes it as it always does:

* a landing that crossed several guards when the model resolves them jointly, or two
  self-transitions whose resets the run compares (``relaxed.simultaneous``);
* a crossing past the transition budget or whose strip outlasts the run;
* a reset or a continuation image that is not finite, a continuation into a mode outside the
  table, or one whose target's guards are nan there (the Python model decides);
* the entry of a mode outside the table (modes without twins) or not yet ready (its twin not
  yet checked against the Python callables, which Python does at its first entry before it
  hands the entry back: ``ENTER``), or of a state the entry's special cases handle (a
  non-finite field or guard, a state past a strip).

The mode table: ``mi`` (one row per mode: function set, dimension, guard count, span of its
parameters in ``P``, first transition slot, whether its twin has resets, whether it is
ready), ``ti`` (one row per
transition slot: target, continuation target, whether the twin computes the continuation's
reset, joint group, self-transition, Zeno history row), ``hist`` (per history row: whether the
transition was crossed since the run began or its last continuation, when that crossing left
its strip, the flight before it; ``relaxed.zeno.ZenoWatch``'s histories). Mode indices at or
past ``mi.shape[0]`` name modes outside the table.
"""

from __future__ import annotations

import math

from ..relaxed.rules import (
    accumulating,
    entered_in_strip,
    flight_since,
    past_strip,
    restarted_step,
    scaled_rms,
    starting_guess,
    starting_step,
    strip_exit_time,
)

# Return codes: the step loop goes on in the entered mode; Python takes the crossing; Python
# enters the mode the kernel reached.
CONTINUE = -1
TRANSITION = 1
NEXT = 7

# Positions in iv of the current mode, the length of the state handed back, and the entry that
# Python hands to the kernel (``CROSS``: none) (the kernel's others: ``kernel``).
I_MODE, I_XLEN, I_ENTER = 10, 11, 12
# What ``transit`` starts with: the crossing of a strip, or the entry of mode m from (t, xw)
# that Python hands over, continuing the flow of the mode before or starting a new one.
CROSS, ENTER, ENTER_NEW_FLOW = 0, 1, 2
# cf: t_final, h_max, eps, rtol, atol, step exponent, Zeno window.
CF_T_FINAL, CF_H_MAX, CF_EPS, CF_RTOL, CF_ATOL, CF_EXPONENT, CF_WINDOW = range(7)
# ci: adaptive, aim, max_halvings, max_steps, transition budget, method id, continuation, joint.
CI_ADAPTIVE, CI_AIM, CI_MAX_HALVINGS, CI_MAX_STEPS, CI_BUDGET, CI_METHOD, CI_CONTINUES, CI_JOINT = range(8)
# cnt: evaluations made by transitions.
N_FIELD, N_GUARD, N_RESET = range(3)
# Columns of mi, ti, hist and of the records' integers.
MI_FID, MI_DIM, MI_NG, MI_P0, MI_P1, MI_SLOT, MI_RESETS, MI_READY = range(8)
TI_TARGET, TI_CONT, TI_CONT_OK, TI_GROUP, TI_SELF, TI_HIST = range(6)
#: The joint group of a transition whose twin declares none (``CompiledMode.joint_groups``).
UNKNOWN_GROUP = -2
H_HAS, H_LAST, H_FLIGHT = range(3)
R_SRC, R_E, R_TARGET, R_KIND, R_END, R_LEN = range(6)
#: No mode (a transition without continuation; a crossing Python must decide).
NO_MODE = -1


def _twin_field(fid, t, x, p):  # bound in the generated module: the field of function set fid
    raise NotImplementedError


def _twin_guards(fid, x, p):  # bound in the generated module
    raise NotImplementedError


def _twin_resets(fid, x, p, e):  # bound in the generated module
    raise NotImplementedError


def _k_finite(v):
    # A loop, not all() over a generator: numba compiles this function.
    for d in range(v.shape[0]):  # noqa: SIM110
        if not math.isfinite(v[d]):
            return False
    return True


def _k_argmin(values, n):
    # The first least value's index, as min(range(n), key=values.__getitem__).
    e = 0
    for j in range(1, n):
        if values[j] < values[e]:
            e = j
    return e


def _k_store(T, X, DX, size, t, x, dx):
    T[size] = t
    for d in range(x.shape[0]):
        X[size, d] = x[d]
        DX[size, d] = dx[d]
    return size + 1


def single_crossing(ti, slot0, gv, n_guards, joint):
    """Whether the landing whose guard values are gv may be crossed by its first crossing
    alone, as relaxed.strip.cross crosses it when neither the model's joint function
    (``joint``: the system has one; it resolves the crossings when all have a joint group and
    they span two groups or more, ``CompiledMode.joint_groups``; a group UNKNOWN_GROUP sends
    every such landing to Python) nor the order check (two crossed self-transitions,
    ``relaxed.simultaneous``) has anything to do."""
    crossed = 0
    selfs = 0
    unknown = False
    grouped = True
    first = -1
    spans = False
    for j in range(n_guards):
        if gv[j] < 0.0:
            crossed += 1
            k = slot0 + j
            if ti[k, TI_SELF] != 0:
                selfs += 1
            group = ti[k, TI_GROUP]
            if group == UNKNOWN_GROUP:
                unknown = True
            elif group < 0:
                grouped = False
            elif first < 0:
                first = group
            elif group != first:
                spans = True
    jointly = joint and (unknown or (grouped and spans))
    return crossed < 2 or (not jointly and selfs < 2)


def _k_copy(v, out):
    for d in range(v.shape[0]):
        out[d] = v[d]


def _k_admits(P, mi, cont, image, eps):
    """relaxed.strip._continued_image's test of a continuation image in its target mode cont:
    (admitted, guard evaluations, nan guard)."""
    nc = mi[cont, MI_NG]
    if nc == 0:
        return True, 0, False
    g = _twin_guards(mi[cont, MI_FID], image, P[mi[cont, MI_P0] : mi[cont, MI_P1]])
    gmin = g[0]
    for j in range(nc):
        if g[j] != g[j]:
            return False, nc, True
        if g[j] < gmin:
            gmin = g[j]
    return not entered_in_strip(gmin, eps), nc, False


def _k_decide(P, mi, ti, hist, q, raw, cf, ci, m, e, tc):
    """What relaxed.strip.cross makes of the crossing of transition e of mode m at tc from q:
    its continuation when the crossings accumulate and its image lies in its target's domain,
    else its reset. The image goes to raw. Returns (target, continued, image length, reset
    evaluations, guard evaluations), target NO_MODE when Python must decide."""
    fid = mi[m, MI_FID]
    p = P[mi[m, MI_P0] : mi[m, MI_P1]]
    k = mi[m, MI_SLOT] + e
    row = ti[k, TI_HIST]
    accumulates = hist[row, H_HAS] != 0.0 and accumulating(hist[row, H_FLIGHT], tc - hist[row, H_LAST], cf[CF_WINDOW])
    cont = ti[k, TI_CONT]
    resets = 0
    guards = 0
    if accumulates and ci[CI_CONTINUES] != 0 and cont != NO_MODE:
        if cont >= mi.shape[0] or ti[k, TI_CONT_OK] == 0:
            return NO_MODE, False, 0, resets, guards
        image = _twin_resets(fid, q, p, mi[m, MI_NG] + e)
        resets += 1
        if not _k_finite(image) or image.shape[0] > raw.shape[0]:
            return NO_MODE, False, 0, resets, guards
        admitted, evals, nan = _k_admits(P, mi, cont, image, cf[CF_EPS])
        guards += evals
        if nan:
            return NO_MODE, False, 0, resets, guards
        if admitted:
            _k_copy(image, raw)
            return cont, True, image.shape[0], resets, guards
    image = _twin_resets(fid, q, p, e)
    resets += 1
    if not _k_finite(image) or image.shape[0] > raw.shape[0]:
        return NO_MODE, False, 0, resets, guards
    _k_copy(image, raw)
    return ti[k, TI_TARGET], False, image.shape[0], resets, guards


def _k_record(r_i, r_f, r_q, r_after, k, m, e, target, continued, end, tc, t_land, exit_time, tau, q, raw, length):
    # The transition crossed in the kernel, for Python to turn into Execution pieces; the
    # segment before it ends at buffer row `end`.
    r_i[k, R_SRC] = m
    r_i[k, R_E] = e
    r_i[k, R_TARGET] = target
    r_i[k, R_KIND] = 1 if continued else 0
    r_i[k, R_END] = end
    r_i[k, R_LEN] = length
    r_f[k, 0] = tc
    r_f[k, 1] = t_land
    r_f[k, 2] = exit_time
    r_f[k, 3] = tau
    for d in range(q.shape[0]):
        r_q[k, d] = q[d]
    for d in range(length):
        r_after[k, d] = raw[d]


def _k_remember(hist, row, continued, tc, exit_time):
    # relaxed.zeno.ZenoWatch.crossed's history of the transition: forgotten after its
    # continuation (a later crossing starts a new sequence).
    if continued:
        hist[row, H_HAS] = 0.0
        return
    flight = flight_since(hist[row, H_HAS] != 0.0, hist[row, H_LAST], tc)
    hist[row, H_HAS] = 1.0
    hist[row, H_LAST] = exit_time
    hist[row, H_FLIGHT] = flight


def _k_starting_step(fid, p, t, x, k0, work, cf, h_prop):
    # relaxed.step_size.ErrorControl.starting_step on the twin's field (one evaluation).
    rtol, atol = cf[CF_RTOL], cf[CF_ATOL]
    d1 = scaled_rms(k0, x, rtol, atol)
    h0 = starting_guess(scaled_rms(x, x, rtol, atol), d1, cf[CF_H_MAX])
    for d in range(x.shape[0]):
        work[d] = x[d] + h0 * k0[d]
    f1 = _twin_field(fid, t + h0, work, p)
    for d in range(x.shape[0]):
        work[d] = f1[d] - k0[d]
    d2 = scaled_rms(work, x, rtol, atol) / h0
    if not math.isfinite(d2):
        return h_prop
    return starting_step(h0, d1, d2, cf[CF_EXPONENT])


def _k_entry(P, mi, m, t, xw, Kw, cf):
    """relaxed.entry.enter_mode's evaluations of mode m at (t, xw[:n]): k0 into Kw[:n].
    Returns (code, guard index, depth): CONTINUE with index -1 when the flow starts here, with
    the index of the guard whose strip it entered (crossed at once, at depth -g), or NEXT when
    the entry's special cases need Python."""
    n = mi[m, MI_DIM]
    fid = mi[m, MI_FID]
    p = P[mi[m, MI_P0] : mi[m, MI_P1]]
    x = xw[:n]
    k0 = _twin_field(fid, t, x, p)
    if not _k_finite(k0):
        return NEXT, -1, 0.0
    _k_copy(k0, Kw)
    ng = mi[m, MI_NG]
    if ng == 0:
        return CONTINUE, -1, 0.0
    g = _twin_guards(fid, x, p)
    if not _k_finite(g):
        return NEXT, -1, 0.0
    e = _k_argmin(g, ng)
    if not entered_in_strip(g[e], cf[CF_EPS]):
        return CONTINUE, -1, 0.0
    if past_strip(g[e], cf[CF_EPS]):
        return NEXT, -1, 0.0
    return CONTINUE, e, -g[e]


def transit(
    P,
    mi,
    ti,
    hist,
    xw,
    Kw,
    workw,
    qw,
    raw,
    T,
    X,
    DX,
    iv,
    cf,
    ci,
    cnt,
    r_i,
    r_f,
    r_q,
    r_after,
    m,
    e,
    tc,
    t_land,
    tau,
    t,
    size,
    n_rec,
    h_prop,
    start,
):
    """relaxed.strip.cross of transition e of mode m, located at (tc, q = qw[:n]) by a step
    from t that landed at t_land at depth tau; then relaxed.entry.enter_mode of its target, and
    of every target whose strip an entered state lies in (crossed at once, q = the state), until
    a mode's flow starts. With ``start`` ENTER or ENTER_NEW_FLOW it begins with the entry of
    mode m from (t, xw) instead (Python took the crossing before, or it is the run's start).
    Returns (code, mode, t, buffer size, records, h_prop): CONTINUE (the step loop goes on from
    (t, xw, Kw)), TRANSITION (Python crosses this first crossing; nothing was done), or NEXT
    (Python enters mode `mode` at t from xw[:iv[I_XLEN]]; the crossings before are recorded)."""
    t_final, eps = cf[CF_T_FINAL], cf[CF_EPS]
    limit = min(ci[CI_BUDGET], r_i.shape[0])
    first = start == CROSS
    entering = not first
    # Where the flow before came from: a new flow restarts the step size (relaxed.entry).
    source = NO_MODE if start == ENTER_NEW_FLOW else m
    while True:
        if entering:  # the entry Python handed over: no crossing before it here
            entering = False
        else:
            n = mi[m, MI_DIM]
            exit_time = strip_exit_time(t_land, eps, tau)
            handover = TRANSITION if first else NEXT
            if n_rec >= limit or exit_time >= t_final or mi[m, MI_RESETS] == 0 or size >= T.shape[0]:
                return handover, m, t, size, n_rec, h_prop
            target, continued, length, resets, guards = _k_decide(P, mi, ti, hist, qw[:n], raw, cf, ci, m, e, tc)
            if target == NO_MODE:
                return handover, m, t, size, n_rec, h_prop
            if not first:  # the state entered in the strip: its own one-point segment, its evaluations
                size = _k_store(T, X, DX, size, tc, xw[:n], Kw[:n])
                cnt[N_FIELD] += 1
                cnt[N_GUARD] += mi[m, MI_NG]
            _k_record(
                r_i,
                r_f,
                r_q,
                r_after,
                n_rec,
                m,
                e,
                target,
                continued,
                size,
                tc,
                t_land,
                exit_time,
                tau,
                qw[:n],
                raw,
                length,
            )
            _k_remember(hist, ti[mi[m, MI_SLOT] + e, TI_HIST], continued, tc, exit_time)
            cnt[N_GUARD] += guards
            cnt[N_RESET] += resets
            n_rec += 1
            t = exit_time
            first = False
            source = m
            m = target
            _k_copy(raw[:length], xw)
            iv[I_XLEN] = length
        if m >= mi.shape[0] or mi[m, MI_READY] == 0:
            return NEXT, m, t, size, n_rec, h_prop
        code, e, tau = _k_entry(P, mi, m, t, xw, Kw, cf)
        if code == NEXT:
            return NEXT, m, t, size, n_rec, h_prop
        n = mi[m, MI_DIM]
        if e >= 0:
            _k_copy(xw[:n], qw)
            tc = t
            t_land = t
            continue
        if size >= T.shape[0]:
            return NEXT, m, t, size, n_rec, h_prop
        size = _k_store(T, X, DX, size, t, xw[:n], Kw[:n])
        cnt[N_FIELD] += 1
        cnt[N_GUARD] += mi[m, MI_NG]
        if ci[CI_ADAPTIVE] != 0 and source != m:  # a new flow: the standard starting step
            p = P[mi[m, MI_P0] : mi[m, MI_P1]]
            h_prop = restarted_step(h_prop, _k_starting_step(mi[m, MI_FID], p, t, xw[:n], Kw[:n], workw, cf, h_prop))
            cnt[N_FIELD] += 1
        return CONTINUE, m, t, size, n_rec, h_prop


#: The functions of this module the generated kernel holds.
TRANSIT_FUNCTIONS = (
    _k_finite,
    _k_argmin,
    _k_store,
    single_crossing,
    _k_copy,
    _k_admits,
    _k_decide,
    _k_record,
    _k_remember,
    _k_starting_step,
    _k_entry,
    transit,
)
#: The rules they call, compiled from their own source.
TRANSIT_RULES = (
    accumulating,
    entered_in_strip,
    flight_since,
    past_strip,
    restarted_step,
    scaled_rms,
    starting_guess,
    starting_step,
    strip_exit_time,
)
