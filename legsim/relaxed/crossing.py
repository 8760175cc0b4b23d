"""Crossing a strip (paper 000 Fig. 12, steps 10-14): a step that lands in a strip has its
crossing point q located on the step's own curve; the state is held at q for the rest of the
strip, eps - tau, and the reset is applied to q, not to the overshot landing point.

Bringing the state back along the flow keeps conserved quantities to the curve's accuracy,
whereas projecting the landing point along the guard's gradient would change a runner's energy
by O(tau) at every touchdown; resetting the overshot point instead would sink the state deeper at
every transition and stall a Zeno run in a stream of near-zero-time transitions. When a step
lands in several strips at once (simultaneous guards), the transition whose crossing comes first
on the curve is taken, unless the model resolves them together (its joint function: one impact
law for every contact that closes); the next mode then sees its own guard already crossed.

A mode that chooses its crossings' outcomes under the input applied after them
(``ModeFunctions.previewed``) has each crossing resolved with that input (``previewed_choice``,
``cross_jointly``): the outcome found under the input before the crossing is followed by the
controller into its target at its image, and the mode asked again under the input there, until
the choice repeats.

Accumulating crossings (a Zeno point ahead, ``rules.accumulating``) take the transition's
continuation when it has one and the run asks for it (paper 000, Thm. 26: past the accumulation
the relaxed execution holds the state instead of moving it). Each transition keeps a history row
(``layout.H_*``) for that rule: when its last crossing left the strip and the flight before.
"""

from __future__ import annotations

import numpy as np

from .calls import call_indexed, call_joint
from .curve import crossing_on_landing, landing_point, landing_slope
from .evaluate import (
    Tables,
    Visit,
    closed_reset,
    control_now,
    enter_controller,
    guards_at,
    guards_under,
    input_after,
    least,
    reset_under,
    visit_of,
)
from .layout import (
    END_FINISHED,
    END_MAX_TRANSITIONS,
    END_RESET_BROKE_DOWN,
    END_RESET_NON_FINITE,
    F_LAND_S,
    F_LAND_T1,
    F_STRIP_TIME,
    F_T,
    H_FLIGHT,
    H_LAST_EXIT,
    H_SEEN,
    I_BREAKDOWN,
    I_END,
    I_END_INDEX,
    I_LAND_E,
    I_LAST_SOURCE,
    I_MODE,
    I_PHASE,
    I_POINTS,
    I_RECORDS,
    I_RESET_EVALS,
    I_TRANSITIONS,
    I_VISITS,
    J_TARGET,
    KIND_CONTINUED,
    KIND_CUT,
    KIND_JOINT,
    KIND_JOINT_CONTINUED,
    KIND_PLAIN,
    M_J0,
    M_JOINT_HISTORY,
    M_NJ,
    M_READY,
    M_T0,
    NO_CONTINUATION,
    PHASE_ENDED,
    PHASE_ENTER,
    R_ACCUMULATES,
    R_DEPTH,
    R_DIM_AFTER,
    R_DIM_BEFORE,
    R_EXIT,
    R_HAS_CONTINUATION,
    R_INDEX,
    R_JOINT,
    R_KIND,
    R_LANDING,
    R_ORDER_A,
    R_ORDER_B,
    R_SOURCE,
    R_TARGET,
    R_TIME,
    S_CONTINUES,
    S_EPS,
    S_MAX_TRANSITIONS,
    S_MEMORY,
    S_T_FINAL,
    S_WINDOW,
    T_CONTINUATION,
    T_TARGET,
    V_FIRST,
    V_MODE,
)
from .rules import accumulating, entered_in_strip, flight_since, past_strip, strip_exit_time
from .stages import MethodArrays, all_finite
from .stepping import CROSSING_TOL

#: What crossing a strip leads to: the next mode's entry, or the run's end.
CROSSED, ENDED = range(2)


def append_point(ws, t: float, x: np.ndarray, dx: np.ndarray) -> None:
    """Store a point of the execution (t, x, f there)."""
    i = ws.iv[I_POINTS]
    n = x.shape[0]
    ws.T[i] = t
    for d in range(n):
        ws.X[i, d] = x[d]
        ws.DX[i, d] = dx[d]
    ws.iv[I_POINTS] = i + 1


def zero(values: np.ndarray) -> None:
    """Set values to zeros (the slope stored with a point whose field is not finite)."""
    for d in range(values.shape[0]):
        values[d] = 0.0


def start_visit(ws, mode: int) -> None:
    """Start the visit of mode row ``mode``: its points follow."""
    v = ws.iv[I_VISITS]
    ws.visits[v, V_MODE] = mode
    ws.visits[v, V_FIRST] = ws.iv[I_POINTS]
    ws.iv[I_VISITS] = v + 1


def locate(tab: Tables, vis: Visit, ws, method: MethodArrays) -> tuple[int, float]:
    """(guard, fraction s of q): the earliest crossing on the landing's curve among the guards
    the step ended past, unless the landing rule located it already."""
    if ws.iv[I_LAND_E] >= 0:
        return ws.iv[I_LAND_E], ws.fs[F_LAND_S]
    t, n = ws.fs[F_T], vis.n
    best_e, best_s = -1, 0.0
    for e in range(vis.guards):
        if ws.g1[e] < 0.0:
            guards_at(tab, vis, ws, t, ws.x[:n], ws.g_w)
            s, _ = crossing_on_landing(tab, vis, ws, method, e, 0.0, ws.g_w[e], ws.g1[e], CROSSING_TOL * ws.cf[S_EPS])
            if best_e < 0 or s < best_s:
                best_e, best_s = e, s
    return best_e, best_s


def cross_landing(tab: Tables, vis: Visit, ws, method: MethodArrays) -> int:
    """The accepted step ended in one or more strips: store q (on the step's curve; the step's
    start when q is not finite there, or replacing the start when its time rounds to it), then
    cross the strip of the first crossing."""
    e, s = locate(tab, vis, ws, method)
    t, n = ws.fs[F_T], vis.n
    t1 = ws.fs[F_LAND_T1]
    for d in range(n):
        ws.q[d] = ws.x[d]
    tc = t
    if s > 0.0:
        landing_point(method, vis, ws, s, ws.w)
        if all_finite(ws.w[:n]):
            for d in range(n):
                ws.q[d] = ws.w[d]
            landing_slope(method, vis, ws, s, ws.w)
            tc = t + s * (t1 - t)
            if tc <= t:  # q differs from the step's start by rounding only: it replaces it
                tc = t
                last = ws.iv[I_POINTS] - 1
                for d in range(n):
                    ws.X[last, d] = ws.q[d]
                    ws.DX[last, d] = ws.w[d]
            else:
                append_point(ws, tc, ws.q[:n], ws.w[:n])
    count, order_a, order_b = crossed_set(tab, vis, ws, e)
    return cross(tab, vis, ws, e, tc, t1, -ws.g1[e], count, order_a, order_b)


def crossed_set(tab: Tables, vis: Visit, ws, e: int) -> tuple[int, int, int]:
    """Mark the guards the landing crossed in ws.crossed by their order (1.0 for e, the first
    crossing on the curve, then 2.0, 3.0, ... for the others in the mode's order; 0.0 for the
    rest): (their count, the first two self-transitions among them in that order, -1 where
    there are fewer)."""
    for f in range(vis.guards):
        ws.crossed[f] = 0.0
    base = tab.modes[vis.mode, M_T0]
    count, first, second = 0, -1, -1
    for k in range(vis.guards + 1):
        f = e if k == 0 else k - 1
        if k > 0 and (f == e or ws.g1[f] >= 0.0):
            continue
        count += 1
        ws.crossed[f] = float(count)
        if tab.transitions[base + f, T_TARGET] == vis.mode:
            if first < 0:
                first = f
            elif second < 0:
                second = f
    return count, first, second


def cross(
    tab: Tables, vis: Visit, ws, e: int, tc: float, t_land: float, tau: float, count: int, order_a: int, order_b: int
) -> int:
    """Cross the strip of transition e entered at time tc at the guard point ws.q by a step
    that landed at t_land, depth tau: hold q until t_land + eps - tau, then reset (module
    docstring). ``count`` guards were crossed together (marked in ws.crossed)."""
    if ws.iv[I_TRANSITIONS] >= ws.ci[S_MAX_TRANSITIONS]:
        record_cut(tab, vis, ws, e, tc, tc, t_land, tau)
        return end_crossing(ws, END_MAX_TRANSITIONS, e, tc)
    exit_time = strip_exit_time(t_land, ws.cf[S_EPS], tau)
    t_final = ws.cf[S_T_FINAL]
    if exit_time >= t_final:
        record_cut(tab, vis, ws, e, tc, t_final, t_land, tau)
        return end_crossing(ws, END_FINISHED, e, t_final)
    if count > 1 and vis.joint >= 0 and cross_jointly(tab, vis, ws, e, tc, t_land, tau, exit_time):
        return CROSSED
    previewed = vis.previewed and vis.control >= 0
    if previewed:
        e = previewed_choice(tab, vis, ws, e, tc, t_land, exit_time)
    row = tab.modes[vis.mode, M_T0] + e
    accumulates = crossings_accumulate(ws, row, tc)
    continuation = tab.transitions[row, T_CONTINUATION]
    has_continuation = continuation != NO_CONTINUATION
    if accumulates and has_continuation and ws.ci[S_CONTINUES] == 1:
        target = visit_of(tab, ws.ci[S_MEMORY], continuation)
        if continued_image(tab, vis, target, ws, e, tc, exit_time):
            record(tab, vis, ws, e, KIND_CONTINUED, -1, continuation, tc, t_land, exit_time, tau, target.n)
            set_order(ws, order_a, order_b, True, has_continuation)
            crossed_history(ws, row, tc, exit_time, True)
            return enter_next(ws, continuation, exit_time, target.n)
    target = visit_of(tab, ws.ci[S_MEMORY], tab.transitions[row, T_TARGET])
    ws.iv[I_BREAKDOWN] = 0
    if previewed:  # the image under the input its outcome was chosen under
        reset_under(tab, vis, target, ws, e, tc, exit_time, ws.q[: vis.n], ws.u_after, ws.w)
    else:
        closed_reset(tab, vis, target, ws, e, tc, exit_time, ws.q[: vis.n], ws.w)
    if ws.iv[I_BREAKDOWN] == 1 or (vis.nan_breaks and not all_finite(ws.w[: target.n])):
        return end_crossing(ws, END_RESET_BROKE_DOWN, e, tc)
    record(tab, vis, ws, e, KIND_PLAIN, -1, target.mode, tc, t_land, exit_time, tau, target.n)
    set_order(ws, order_a, order_b, accumulates, has_continuation)
    crossed_history(ws, row, tc, exit_time, False)
    if not all_finite(ws.w[: target.n]):
        start_visit(ws, target.mode)
        zero(ws.k1[: target.n])
        append_point(ws, exit_time, ws.w[: target.n], ws.k1[: target.n])
        return end_crossing(ws, END_RESET_NON_FINITE, e, exit_time)
    return enter_next(ws, target.mode, exit_time, target.n)


def enter_next(ws, mode: int, t: float, n: int) -> int:
    """Continue in ``mode`` at time t from the image in ws.w[:n]."""
    for d in range(n):
        ws.x[d] = ws.w[d]
    ws.iv[I_MODE] = mode
    ws.fs[F_T] = t
    ws.iv[I_PHASE] = PHASE_ENTER
    return CROSSED


def end_crossing(ws, reason: int, index: int, t: float) -> int:
    """End the run at a strip (``layout.END_*``), at time t."""
    ws.iv[I_END] = reason
    ws.iv[I_END_INDEX] = index
    ws.iv[I_PHASE] = PHASE_ENDED
    ws.fs[F_T] = t
    return ENDED


def continued_image(tab: Tables, vis: Visit, target: Visit, ws, e: int, tc: float, exit_time: float) -> bool:
    """The continuation's image of q into ws.w, and whether it lies in its target's domain (the
    constraint it enters would not pull at once); when it does not, the transition is taken."""
    ws.iv[I_BREAKDOWN] = 0
    closed_reset(tab, vis, target, ws, vis.guards + e, tc, exit_time, ws.q[: vis.n], ws.w)
    if ws.iv[I_BREAKDOWN] == 1 or not all_finite(ws.w[: target.n]):
        return False
    gmin = guards_at(tab, target, ws, exit_time, ws.w[: target.n], ws.g_w)
    return gmin == gmin and not entered_in_strip(gmin, ws.cf[S_EPS])


def cross_jointly(tab: Tables, vis: Visit, ws, e: int, tc: float, t_land: float, tau: float, exit_time: float) -> bool:
    """The model's joint resolution of the transitions crossed together (ws.crossed): their
    continuation (every striker plastic) when these joint crossings accumulate. False when the
    model takes them one after the other."""
    row = tab.modes[vis.mode, M_JOINT_HISTORY]
    accumulates = crossings_accumulate(ws, row, tc)
    rest = accumulates and ws.ci[S_CONTINUES] == 1
    control_now(tab, vis, ws, tc, ws.q[: vis.n])
    outcome = call_joint(
        tab.functions, vis.joint, 1 if rest else 0, tc, ws.q[: vis.dim], ws.u, vis.p, ws.crossed[: vis.guards], ws.w
    )
    check_outcome(tab, vis, outcome)
    for _ in range(PREVIEW_ROUNDS if vis.previewed and vis.control >= 0 else 0):
        if outcome < 0:
            break
        target = visit_of(tab, ws.ci[S_MEMORY], tab.joints[tab.modes[vis.mode, M_J0] + outcome, J_TARGET])
        after_entry(ws, vis, target)
        input_after(tab, target, ws, exit_time, ws.w[: target.n], ws.u_after)
        again = call_joint(tab.functions, vis.joint, 1 if rest else 0, tc, ws.q[: vis.dim], ws.u_after, vis.p,
                           ws.crossed[: vis.guards], ws.w)  # fmt: skip
        check_outcome(tab, vis, again)
        if again == outcome or again < 0:
            break
        outcome = again
    if outcome < 0:
        return False
    ws.iv[I_RESET_EVALS] += 1
    target = visit_of(tab, ws.ci[S_MEMORY], tab.joints[tab.modes[vis.mode, M_J0] + outcome, J_TARGET])
    for d in range(ws.ci[S_MEMORY]):
        ws.w[target.dim + d] = ws.q[vis.dim + d]
    enter_controller(tab, target, ws, exit_time, ws.w[: target.n])
    kind = KIND_JOINT_CONTINUED if rest else KIND_JOINT
    record(tab, vis, ws, e, kind, outcome, target.mode, tc, t_land, exit_time, tau, target.n)
    # A joint crossing always has its continuation: every striker plastic.
    set_order(ws, -1, -1, accumulates, True)
    crossed_history(ws, row, tc, exit_time, rest)
    enter_next(ws, target.mode, exit_time, target.n)
    return True


def check_outcome(tab: Tables, vis: Visit, outcome: int) -> None:
    """An index past the mode's joint outcomes would pick another mode's row as the target."""
    if outcome >= tab.modes[vis.mode, M_NJ]:
        raise IndexError("the joint function returned an index past its mode's joint_outcomes")


#: Most times a previewed crossing's choice is asked again (a choice that does not repeat by then
#: is taken as it stands).
PREVIEW_ROUNDS = 4


def after_entry(ws, vis: Visit, target: Visit) -> None:
    """The memory before the crossing (ws.q's) after the target's state in ws.w."""
    for d in range(ws.ci[S_MEMORY]):
        ws.w[target.dim + d] = ws.q[vis.dim + d]


def previewed_choice(tab: Tables, vis: Visit, ws, e: int, tc: float, t_land: float, t_enter: float) -> int:
    """The transition crossed at q (ws.q) by a mode that chooses outcomes under the input after
    them. From transition e, found past at the landing point ws.x1 (time t_land): its image of q
    under the input it is asked under, the controller's input there after its entry, and the
    mode's guards at the landing point again under that input. e is taken when they choose it
    again and its image lies in its target's relaxed domain under that input (or its target is
    not built yet); while they choose it again, it is asked again under the new input;
    otherwise the deepest guard that became past (one not past under the input before the
    crossing, ws.g1) is asked next, at most ``PREVIEW_ROUNDS`` times. When none is taken (the
    controller's inputs before and after disagree about the outcome), the first asked whose
    image lies in its target's domain under the input there is taken; failing that, the first
    transition stands, and its entry ends the run (reset_outside_domain) or, in a mode that
    crosses jumps, crosses the guard it lies past at once. The guards are asked at
    the landing point, not at q: q lies on the guard to within rounding, where the crossing's
    outcome is not decided.
    Leaves in ws.u_after the input the returned transition's image is taken under; ws.u, ws.w
    and ws.u_kept are scratch."""
    first, kept = e, -1
    control_now(tab, vis, ws, tc, ws.q[: vis.n])
    copy_input(ws.u, ws.u_after)
    for _ in range(PREVIEW_ROUNDS):
        target = visit_of(tab, ws.ci[S_MEMORY], tab.transitions[tab.modes[vis.mode, M_T0] + e, T_TARGET])
        copy_input(ws.u_after, ws.u)  # the input e is asked under
        if vis.reset >= 0:
            call_indexed(tab.functions, vis.reset, e, tc, ws.q[: vis.dim], ws.u, vis.p, ws.w[: target.dim])
        else:
            for d in range(target.dim):
                ws.w[d] = ws.q[d]
        after_entry(ws, vis, target)
        input_after(tab, target, ws, t_enter, ws.w[: target.n], ws.u_after)
        built = tab.modes[target.mode, M_READY] == 1
        inside = built and enters_inside(tab, target, ws, t_enter)
        if inside and kept < 0:
            kept = e
            copy_input(ws.u, ws.u_kept)
        guards_under(tab, vis, ws, t_land, ws.x1[: vis.n], ws.u_after, ws.g_w)
        if ws.g_w[e] < 0.0:
            if inside or not built:
                return e  # chosen again under the input after it, its image taken under that
            continue
        e = newly_past(ws.g_w, ws.g1, vis.guards)
        if e < 0:
            break
    if kept >= 0:
        copy_input(ws.u_kept, ws.u_after)
        return kept
    control_now(tab, vis, ws, tc, ws.q[: vis.n])
    copy_input(ws.u, ws.u_after)
    return first


def copy_input(source: np.ndarray, out: np.ndarray) -> None:
    """out[:] = source[:] (inputs of equal length)."""
    for d in range(source.shape[0]):
        out[d] = source[d]


def enters_inside(tab: Tables, target: Visit, ws, t_enter: float) -> bool:
    """Whether the image in ws.w lies in ``target``'s relaxed domain under the input in
    ws.u_after (its entry would not end the run)."""
    guards_under(tab, target, ws, t_enter, ws.w[: target.n], ws.u_after, ws.g_w)
    entered = least(ws.g_w, target.guards)
    return entered == entered and not past_strip(entered, ws.cf[S_EPS])


def newly_past(values: np.ndarray, before: np.ndarray, count: int) -> int:
    """Index of the deepest of values[:count] that is past (< 0) where before[:count] was not;
    -1 when there is none."""
    best = -1
    for f in range(count):
        if values[f] < 0.0 and not before[f] < 0.0 and (best < 0 or values[f] < values[best]):
            best = f
    return best


def crossings_accumulate(ws, row: int, tc: float) -> bool:
    """Whether the crossings of history row ``row`` accumulate with one at tc."""
    seen = ws.history[row, H_SEEN] == 1.0
    return seen and accumulating(ws.history[row, H_FLIGHT], tc - ws.history[row, H_LAST_EXIT], ws.cf[S_WINDOW])


def crossed_history(ws, row: int, tc: float, exit_time: float, continued: bool) -> None:
    """Record a crossing at tc, its strip left at ``exit_time``, in history row ``row``; a
    continuation starts the history anew (the model took over)."""
    seen = ws.history[row, H_SEEN] == 1.0
    flight = flight_since(seen, ws.history[row, H_LAST_EXIT], tc)
    if continued:
        ws.history[row, H_SEEN] = 0.0
        return
    ws.history[row, H_SEEN] = 1.0
    ws.history[row, H_LAST_EXIT] = exit_time
    ws.history[row, H_FLIGHT] = flight


def record(
    tab: Tables,
    vis: Visit,
    ws,
    e: int,
    kind: int,
    joint: int,
    target: int,
    tc: float,
    t_land: float,
    exit_time: float,
    tau: float,
    n_after: int,
) -> None:
    """Store the crossing of transition e (q in ws.q, the image in ws.w) and count it."""
    r = ws.iv[I_RECORDS]
    ws.rec_f[r, R_TIME] = tc
    ws.rec_f[r, R_LANDING] = t_land
    ws.rec_f[r, R_EXIT] = exit_time
    ws.rec_f[r, R_DEPTH] = tau
    ws.rec_i[r, R_SOURCE] = vis.mode
    ws.rec_i[r, R_INDEX] = e
    ws.rec_i[r, R_TARGET] = target
    ws.rec_i[r, R_KIND] = kind
    ws.rec_i[r, R_JOINT] = joint
    ws.rec_i[r, R_DIM_BEFORE] = vis.n
    ws.rec_i[r, R_DIM_AFTER] = n_after
    for d in range(vis.n):
        ws.rec_q[r, d] = ws.q[d]
    for d in range(n_after):
        ws.rec_x[r, d] = ws.w[d]
    ws.iv[I_RECORDS] = r + 1
    ws.fs[F_STRIP_TIME] += exit_time - tc
    if kind != KIND_CUT:
        ws.iv[I_TRANSITIONS] += 1
        ws.iv[I_LAST_SOURCE] = vis.mode


def set_order(ws, order_a: int, order_b: int, accumulates: bool, has_continuation: bool) -> None:
    """Complete the last record: the self-transitions crossed together, the Zeno flags."""
    r = ws.iv[I_RECORDS] - 1
    ws.rec_i[r, R_ORDER_A] = order_a
    ws.rec_i[r, R_ORDER_B] = order_b
    ws.rec_i[r, R_ACCUMULATES] = 1 if accumulates else 0
    ws.rec_i[r, R_HAS_CONTINUATION] = 1 if has_continuation else 0


def record_cut(tab: Tables, vis: Visit, ws, e: int, tc: float, until: float, t_land: float, tau: float) -> None:
    """Store the strip of a run that ends inside it (held at q from tc until ``until``)."""
    record(tab, vis, ws, e, KIND_CUT, -1, vis.mode, tc, t_land, until, tau, 0)
    set_order(ws, -1, -1, False, False)
