"""One accepted step inside a mode (paper 000 Fig. 12, steps 2-9): a trial step of the method,
judged by the step-size rule, shortened by the landing rule until it lands in the relaxed domain.

* Step-size rules: fixed steps (every step starts from h) or error control by the method's
  embedded pair (``rules.proposed_step`` and its neighbours).
* Landing rules (``layout.LAND_*``): ``halve`` the step (the paper's rule); ``aim`` the retry at
  the step length where the failed step's Hermite interpolant reaches the middle of the deepest
  strip (at most ``rules.MAX_AIMS`` aims, then halving); ``dense``: once a step past a strip
  passes the error test, land on its own continuous extension, with no retried step.

A trial whose state is not finite, or whose model says the state is past its range (a Python
model's ModelBreakdown, or a nan from a model whose nans mean that), has left the relaxed domain
as one past a strip does, and is shortened the same way.
"""

from __future__ import annotations

import math

from .curve import crossing_on_landing, guard_on_landing, set_dense, set_hermite
from .evaluate import Tables, Visit, argleast, field_at, guards_at
from .layout import (
    END_BROKE_DOWN,
    END_GUARD_NAN,
    END_HALVING_EXHAUSTED,
    END_NON_FINITE_STEP,
    F_H_PROP,
    F_H_TRIED,
    F_LAND_S,
    F_LAND_T1,
    F_T,
    I_BREAKDOWN,
    I_END,
    I_END_COUNT,
    I_END_INDEX,
    I_HALVINGS,
    I_JACOBIAN_AGE,
    I_LAND_CONVERGED,
    I_LAND_E,
    I_REJECTIONS,
    I_STEPS,
    LAND_DENSE,
    LAND_HALVE,
    S_ADAPTIVE,
    S_ATOL,
    S_EPS,
    S_EXPONENT,
    S_H_MAX,
    S_LANDING,
    S_MAX_HALVINGS,
    S_RTOL,
    S_T_FINAL,
)
from .rules import (
    MAX_AIMS,
    aimed_step,
    fixed_proposal,
    kept_proposal,
    proposed_step,
    rejected_step,
    shortening_exhausted,
    trial_length,
    within_rounding,
)
from .stages import (
    INFO_FSAL,
    INFO_IMPLICIT,
    INFO_STAGES,
    JACOBIAN_REUSE,
    MethodArrays,
    all_finite,
    dense_point,
    error_norm,
    extend,
    jacobian,
    stages,
)

#: How a trial step went: evaluated; its state not finite; its model past its range.
TRIAL_OK, TRIAL_NON_FINITE, TRIAL_BROKE = range(3)
#: What ``take_step`` hands back: an accepted step inside the domain (possibly in a strip: its
#: least guard < 0, the landing's curve set); the run ended (``I_END`` set).
STEP_ACCEPTED, STEP_ENDED = range(2)
#: q on a landing step's curve is located to this share of the strip (it costs guard evaluations).
CROSSING_TOL = 1e-12


def trial(tab: Tables, vis: Visit, ws, method: MethodArrays, hk: float, t1: float) -> tuple[int, float]:
    """A trial step of length hk from the current point to t1, its guards into ws.g1: (how it
    went (``TRIAL_*``), the least guard there)."""
    n = vis.n
    ws.iv[I_BREAKDOWN] = 0
    if method.info[INFO_IMPLICIT] == 1 and not 0 <= ws.iv[I_JACOBIAN_AGE] < JACOBIAN_REUSE:
        jacobian(tab, vis, ws, ws.fs[F_T], ws.x[:n], ws.K[0, :n])
        ws.iv[I_JACOBIAN_AGE] = 0
    stages(tab, vis, ws, method, ws.fs[F_T], ws.x[:n], hk, ws.K, ws.XS, ws.x1)
    broke = ws.iv[I_BREAKDOWN] == 1
    if not all_finite(ws.x1[:n]):
        return (TRIAL_BROKE if broke or vis.nan_breaks else TRIAL_NON_FINITE), math.nan
    gmin = guards_at(tab, vis, ws, t1, ws.x1[:n], ws.g1)
    if ws.iv[I_BREAKDOWN] == 1 or (gmin != gmin and vis.nan_breaks):
        return TRIAL_BROKE, math.nan
    return TRIAL_OK, gmin


def judge(ws, method: MethodArrays, n: int, hk: float, rejected: bool) -> tuple[bool, float]:
    """Whether the trial passes the step-size rule, and the proposal for the next step (or, for
    a rejected one, the shorter step to retry)."""
    if ws.ci[S_ADAPTIVE] == 0:
        return True, ws.cf[S_H_MAX]
    err = error_norm(method, ws.K, hk, ws.x[:n], ws.x1[:n], ws.cf[S_RTOL], ws.cf[S_ATOL])
    if err > 1.0:
        return False, rejected_step(hk, err, ws.cf[S_EXPONENT])
    return True, proposed_step(hk, err, ws.cf[S_EXPONENT], rejected)


def keep(ws, proposal: float, shortened: int, rejected: bool, halvings: int, landed: bool) -> None:
    """Accept the trial (of length ws.fs[F_H_TRIED]; ``landed``: its end lies in a strip):
    carry the proposal to the next step and count the step."""
    if ws.ci[S_ADAPTIVE] == 1:
        ws.fs[F_H_PROP] = kept_proposal(ws.fs[F_H_PROP], proposal, shortened > 0, rejected)
    else:
        ws.fs[F_H_PROP] = fixed_proposal(ws.fs[F_H_PROP], ws.cf[S_H_MAX], ws.fs[F_H_TRIED], shortened > 0, landed)
    ws.iv[I_HALVINGS] += halvings
    ws.iv[I_STEPS] += 1
    ws.iv[I_JACOBIAN_AGE] += 1


def end_slope(tab: Tables, vis: Visit, ws, method: MethodArrays, t1: float) -> None:
    """f at the trial step's end into ws.k1: its last stage with FSAL, else one evaluation."""
    n = vis.n
    if method.info[INFO_FSAL] == 1:
        s = method.info[INFO_STAGES]
        for d in range(n):
            ws.k1[d] = ws.K[s - 1, d]
    else:
        field_at(tab, vis, ws, t1, ws.x1[:n], ws.k1)


def take_step(tab: Tables, vis: Visit, ws, method: MethodArrays, remaining: float) -> int:
    """One accepted step of at most ``remaining`` (s), its end in ws.x1 and its guards in ws.g1
    (``STEP_ACCEPTED``); a step ending in a strip has its landing curve set. ``STEP_ENDED`` when
    the run ends (``layout.END_*`` in ws.iv[I_END])."""
    t = ws.fs[F_T]
    hk = trial_length(ws.fs[F_H_PROP], ws.cf[S_H_MAX], remaining)
    reference = ws.cf[S_H_MAX] if ws.ci[S_ADAPTIVE] == 0 else hk  # for leaving the model's range
    last = hk == remaining
    shortened = 0
    aims = 0
    rejected = False
    dense = ws.ci[S_LANDING] == LAND_DENSE
    ws.iv[I_LAND_E] = -1
    while True:
        t1 = ws.cf[S_T_FINAL] if last else t + hk
        ws.fs[F_H_TRIED] = hk
        ws.fs[F_LAND_T1] = t1
        outcome, gmin = trial(tab, vis, ws, method, hk, t1)
        if outcome == TRIAL_OK:
            if gmin != gmin:
                return end_run(ws, END_GUARD_NAN, first_nan(ws.g1, vis.guards))
            inside = gmin >= -ws.cf[S_EPS]
            if inside or (dense and aims == 0):
                passed, proposal = judge(ws, method, vis.n, hk, rejected)
                if not passed:
                    ws.iv[I_REJECTIONS] += 1
                    ws.iv[I_JACOBIAN_AGE] = -1  # an old Jacobian may be why: a new one for the retry
                    rejected, hk, last = True, proposal, False
                    continue
                if inside:
                    keep(ws, proposal, shortened, rejected, shortened, gmin < 0.0)
                    if gmin < 0.0:
                        end_slope(tab, vis, ws, method, t1)
                        set_hermite(ws, t1)
                    return STEP_ACCEPTED
                landed, fraction = land_dense(tab, vis, ws, method, hk)
                if landed:
                    keep(ws, proposal, shortened, rejected, shortened + 1, True)
                    return STEP_ACCEPTED
                aims, shortened, hk, last = aims + 1, shortened + 1, fraction * hk, False
                continue
        if outcome == TRIAL_OK and vis.crosses_jumps and within_rounding(t, hk, ws.x, ws.x1, vis.n):
            return land_at_jump(tab, vis, ws, method, shortened)
        shortened += 1
        if outcome == TRIAL_OK and ws.ci[S_LANDING] != LAND_HALVE and aims < MAX_AIMS:
            hk = aim(tab, vis, ws, method, hk, t1)
            aims += 1
        else:
            hk *= 0.5
        last = False
        if shortening_exhausted(shortened, ws.ci[S_MAX_HALVINGS], t, hk, reference, outcome == TRIAL_BROKE):
            if outcome == TRIAL_OK and vis.crosses_jumps and t + hk <= t:
                return land_at_jump(tab, vis, ws, method, shortened)
            ws.iv[I_HALVINGS] += shortened
            ws.iv[I_END_COUNT] = shortened
            return exhausted(ws, outcome, vis.guards)


def land_at_jump(tab: Tables, vis: Visit, ws, method: MethodArrays, shortened: int) -> int:
    """The landing of a mode that crosses jumps (``ModeFunctions.crosses_jumps``) whose guard
    jumps past its strip within a rounding of the state (``rules.within_rounding``) or of the
    time (the step no longer moves t): no step lands in the strip, so the trial's end, just
    past the jump, is the landing and its deepest guard the one crossed there (its depth beyond
    eps marks the crossing as a jump; ``rules.strip_exit_time`` leaves it at once)."""
    t1 = ws.fs[F_LAND_T1]
    keep(ws, ws.fs[F_H_PROP], shortened, False, shortened, True)
    end_slope(tab, vis, ws, method, t1)
    set_hermite(ws, t1)
    ws.iv[I_LAND_E] = argleast(ws.g1, vis.guards)
    ws.fs[F_LAND_S] = 1.0
    ws.iv[I_LAND_CONVERGED] = 1
    return STEP_ACCEPTED


def end_run(ws, reason: int, index: int) -> int:
    """End the run for ``reason`` (``layout.END_*``), naming guard or transition ``index``."""
    ws.iv[I_END] = reason
    ws.iv[I_END_INDEX] = index
    return STEP_ENDED


def first_nan(values, count: int) -> int:
    """Index of the first nan of values[:count] (0 when there is none)."""
    for e in range(count):
        if values[e] != values[e]:
            return e
    return 0


def exhausted(ws, outcome: int, guards: int) -> int:
    """The end of a run whose step could not be shortened into the relaxed domain, by why the
    last trial left it."""
    if outcome == TRIAL_NON_FINITE:
        return end_run(ws, END_NON_FINITE_STEP, -1)
    if outcome == TRIAL_BROKE:
        return end_run(ws, END_BROKE_DOWN, -1)
    return end_run(ws, END_HALVING_EXHAUSTED, argleast(ws.g1, guards))


def aim(tab: Tables, vis: Visit, ws, method: MethodArrays, hk: float, t1: float) -> float:
    """The retry aimed at the middle (-eps/2) of the deepest strip the failed step crossed, on
    its Hermite interpolant (``rules.aimed_step``); half the step when the interpolant leaves the
    model's range."""
    e = argleast(ws.g1, vis.guards)
    g1 = ws.g1[e]
    end_slope(tab, vis, ws, method, t1)
    set_hermite(ws, t1)
    half = 0.5 * ws.cf[S_EPS]
    g0 = guard_on_landing(tab, vis, ws, method, e, 0.0, half)
    if g0 != g0:
        return 0.5 * hk
    s, converged = crossing_on_landing(tab, vis, ws, method, e, half, g0, g1 + half, 1e-3 * half)
    return aimed_step(hk, s, converged)


def land_dense(tab: Tables, vis: Visit, ws, method: MethodArrays, hk: float) -> tuple[bool, float]:
    """Land the trial step of length hk on its own continuous extension: (True, theta) with the
    landing set (its curve, end in ws.x1, guards in ws.g1, q located), or (False, the fraction
    of the step to retry as a real step) when no point of it lies in the relaxed domain."""
    t, n, eps = ws.fs[F_T], vis.n, ws.cf[S_EPS]
    extend(tab, vis, ws, method, t, ws.x[:n], hk, ws.K, ws.XS)
    set_dense(ws, hk, 1.0)
    e, s_q, converged = first_crossing(tab, vis, ws, method)
    if e < 0:
        return False, 0.5
    theta = middle_of_strip(tab, vis, ws, method, e, s_q, ws.g1[e])
    if s_q <= theta < 1.0:
        dense_point(method, ws.x[:n], hk, ws.K, theta, ws.w[:n])
        gmin = guards_at(tab, vis, ws, t + theta * hk, ws.w[:n], ws.g_w)
        if gmin == gmin and gmin >= -eps and ws.g_w[e] < 0.0 and all_finite(ws.w[:n]):
            for d in range(n):
                ws.x1[d] = ws.w[d]
            for f in range(vis.guards):
                ws.g1[f] = ws.g_w[f]
            set_dense(ws, hk, theta)
            ws.iv[I_LAND_E] = e
            ws.fs[F_LAND_S] = s_q / theta if theta > 0.0 else 0.0
            ws.iv[I_LAND_CONVERGED] = 1 if converged else 0
            return True, theta
    return False, (min(max(theta, s_q), 1.0) if s_q > 0.0 else 0.5)


def first_crossing(tab: Tables, vis: Visit, ws, method: MethodArrays) -> tuple[int, float, bool]:
    """q on the trial step's curve: the earliest of the crossed guards to reach zero, located to
    ``CROSSING_TOL`` of the strip from the guards at the step's start (ws.g_here): (guard, s,
    converged), guard -1 when the curve leaves the model's range."""
    best_e, best_s, best_converged = -1, 0.0, False
    for e in range(vis.guards):
        if ws.g1[e] < 0.0:
            s, converged = crossing_on_landing(
                tab, vis, ws, method, e, 0.0, ws.g_here[e], ws.g1[e], CROSSING_TOL * ws.cf[S_EPS]
            )
            if s != s:
                return -1, 0.0, False
            if best_e < 0 or s < best_s:
                best_e, best_s, best_converged = e, s, converged
    return best_e, best_s, best_converged


def middle_of_strip(tab: Tables, vis: Visit, ws, method: MethodArrays, e: int, s_q: float, g1: float) -> float:
    """The fraction of the step at which guard e is in the middle of its strip (-eps/2): by the
    secant from q (a guard is nearly linear across a strip), else, outside the strip's middle
    half (a kinked guard fools the secant, and a shallow landing would hold the state for almost
    no time), by a search on the rest of the step."""
    half = 0.5 * ws.cf[S_EPS]
    theta = s_q + half * (1.0 - s_q) / -g1
    gap = guard_on_landing(tab, vis, ws, method, e, theta, half)
    if abs(gap) <= 0.5 * half:
        return theta
    u, _ = crossing_on_landing(tab, vis, ws, method, e, half, half, g1 + half, 0.5 * half, s_q)
    return s_q + u * (1.0 - s_q)
