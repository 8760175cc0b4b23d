"""The compiled step loop, as plain Python that numba compiles (``generate`` copies these
functions, with the rules they call, into a module per set of twin functions).

It runs a system's modes as ``relaxed.integrate`` does: trial steps from the method's stages,
the guards at their ends, error control, shortening by halving or aiming, and the location of q
for a step that lands in a strip; then (``transit``) the crossing of the strip, the reset at q,
the Zeno continuation and the entry of the next mode, for every mode of the system's table
(``table``), recording the transitions for Python to turn into Execution pieces in batches.
What the kernel cannot take returns to Python with a code. Every numeric decision is a
function of ``legsim.relaxed.rules`` (or ``legsim.methods.stepper.error_norm``), the same the
Python loop calls. ``_twin_field``, ``_twin_guards`` and ``_twin_resets`` dispatch on the mode's
function set (``fid``) and are bound in the generated module.

Layout of the in/out arrays: ``fs`` (floats): t, h_prop, landing time, last trial step, end
time, time of a nan guard, crossing time, depth; ``iv`` (ints): steps, halvings, rejections,
field evaluations, guard evaluations, buffer size, guard index, halvings of a failed step,
resets, transitions recorded, current mode, length of the state handed back; ``cf``: t_final,
h_max, eps, rtol, atol, step exponent, Zeno window; ``ci``: adaptive, aim, max_halvings,
max_steps, transition budget, method id (straight-line stages of a built-in method, or -1),
continuation, joint resolution; ``cnt``: evaluations made by the transitions (field, guard,
reset). The mode table: ``mi`` (modes x MI_*), ``ti`` (transitions x TI_*), ``hist``
(transitions x H_*: the Zeno histories), ``P`` (every mode's parameters, spans in ``mi``).
Wide arrays (``*w``, of the largest state) hold the current mode's state in their first n.
"""

from __future__ import annotations

import math

from ..methods.stepper import error_scale, scaled_norm
from ..relaxed.rules import (
    CONVERGED,
    MAX_AIMS,
    RESULT,
    SEARCHING,
    STATUS,
    aimed_step,
    crossing_point,
    crossing_start,
    crossing_update,
    finish_tolerance,
    hermite_slope_weights,
    hermite_weights,
    kept_proposal,
    proposed_step,
    rejected_step,
    shortening_exhausted,
    trial_length,
)
from .transit import (  # noqa: F401
    CONTINUE,
    CROSS,
    I_ENTER,
    I_MODE,
    I_XLEN,
    MI_DIM,
    MI_FID,
    MI_NG,
    MI_P0,
    MI_P1,
    MI_SLOT,
    N_FIELD,
    N_GUARD,
    N_RESET,
    NEXT,
    TRANSIT_FUNCTIONS,
    TRANSIT_RULES,
    TRANSITION,
    _k_argmin,
    _k_finite,
    _twin_field,
    _twin_guards,
    single_crossing,
    transit,
)

# Return codes (TRANSITION, NEXT: ``transit``).
FINISHED = 0
NONFINITE_STEP = 2
GUARD_NAN = 3
EXHAUSTED = 4
BUFFER_FULL = 5
CHUNK = 6
RECORDS_FULL = 8

# Positions in fs and iv (I_MODE, I_XLEN: ``transit``).
F_T, F_HPROP, F_LAND, F_HTRIED, F_END, F_NAN_T, F_TC, F_TAU = range(8)
I_STEPS, I_HALVINGS, I_REJECTIONS, I_FIELD, I_GUARD, I_SIZE, I_GUARD_INDEX, I_FAILED_HALVINGS, I_RESETS, I_RECORDS = (
    range(10)
)


def _k_combine(x, K, row, n_groups, weights, n_members, members, h, out):
    # out = x + sum_g (h * w_g) * (k_{m0} + k_{m1} + ...), left to right like the generated
    # Python stepper (methods.stepper.stage_groups). Plain indexing: a row view would cost two
    # reference-count updates per call.
    for d in range(x.shape[0]):
        acc = x[d]
        for g in range(n_groups[row]):
            ssum = K[members[row, g, 0], d]
            for m in range(1, n_members[row, g]):
                ssum = ssum + K[members[row, g, m], d]
            acc = acc + (h * weights[row, g]) * ssum
        out[d] = acc


def _k_stages(fid, t, x, hk, K, XS, x_new, p, c, n_groups, weights, n_members, members, fsal):
    # The stages of any tableau from its arrays; the generated module replaces its call in the
    # step loop by straight-line code for each built-in method.
    n = x.shape[0]
    s_stages = c.shape[0]
    for i in range(1, s_stages):
        _k_combine(x, K, i, n_groups, weights, n_members, members, hk, XS)
        ki = _twin_field(fid, t + c[i] * hk, XS, p)
        for d in range(n):
            K[i, d] = ki[d]
    if fsal:  # the last stage is evaluated at the new point itself
        for d in range(n):
            x_new[d] = XS[d]
    else:
        _k_combine(x, K, s_stages, n_groups, weights, n_members, members, hk, x_new)


def _k_hermite(x0, d0, x1, d1, dt, s, out):
    w0, w1, w2, w3 = hermite_weights(s, dt)
    for d in range(x0.shape[0]):
        out[d] = w0 * x0[d] + w1 * d0[d] + w2 * x1[d] + w3 * d1[d]


def _k_hermite_slope(x0, d0, x1, d1, dt, s, out):
    v0, v1, v2, v3 = hermite_slope_weights(s)
    for d in range(x0.shape[0]):
        out[d] = v0 * x0[d] / dt + v1 * d0[d] + v2 * x1[d] / dt + v3 * d1[d]


def _k_crossing(fid, p, e, shift, x0, d0, x1, d1, dt, g0, g1, tol, work):
    # relaxed.strip.crossing_on_step on the compiled guard e, shifted by `shift`, along the
    # step's Hermite interpolant: returns (s, guard calls, converged).
    state = crossing_start(g0, g1, tol)
    evals = 0
    while state[STATUS] == SEARCHING:
        s = crossing_point(state)
        _k_hermite(x0, d0, x1, d1, dt, s, work)
        state = crossing_update(state, s, _twin_guards(fid, work, p)[e] + shift)
        evals += 1
    return state[RESULT], evals, state[STATUS] == CONVERGED


def _k_aim(fid, p, n_guards, x, K, x_new, k1, gv, work, t, hk, eps, fsal, s_stages):
    # rules.aimed_step on the failed step's Hermite interpolant: the step at which the deepest
    # crossed guard reaches the middle of its strip (landing.Aim). Returns (step, field
    # evaluations, guard evaluations).
    e = _k_argmin(gv, n_guards)
    n = x.shape[0]
    field_evals = 0
    if fsal:
        for d in range(n):
            k1[d] = K[s_stages - 1, d]
    else:
        kk = _twin_field(fid, t + hk, x_new, p)
        field_evals = 1
        for d in range(n):
            k1[d] = kk[d]
    half = 0.5 * eps
    g0 = _twin_guards(fid, x, p)[e] + half
    s, evals, converged = _k_crossing(fid, p, e, half, x, K[0], x_new, k1, hk, g0, gv[e] + half, 1e-3 * half, work)
    return aimed_step(hk, s, converged), field_evals, (1 + evals) * n_guards


def _k_locate(fid, p, n_guards, x, K, x_new, k1, gv, work, dt, eps):
    # q: the earliest crossing on the step's interpolant among the guards it ended past
    # (relaxed.strip.locate). Returns (guard index, fraction s, guard evaluations).
    best_e = -1
    best_s = 0.0
    guard_evals = 0
    for j in range(n_guards):
        if gv[j] < 0.0:
            g0 = _twin_guards(fid, x, p)[j]
            s, evals, _ = _k_crossing(fid, p, j, 0.0, x, K[0], x_new, k1, dt, g0, gv[j], 1e-12 * eps, work)
            guard_evals += n_guards * (1 + evals)
            if best_e < 0 or s < best_s:
                best_e = j
                best_s = s
    return best_e, best_s, guard_evals


def _k_store_crossing(x, K, x_new, k1, q, dq, work, t, dt, s, T, X, DX, size):
    # q and its time (relaxed.strip.cross_landing): the step's start when s = 0 or q is not
    # finite; a crossing that rounds to the step's start replaces that point instead of repeating
    # its time. Returns (crossing time, buffer size).
    n = x.shape[0]
    for d in range(n):
        q[d] = x[d]
    if s <= 0.0:
        return t, size
    _k_hermite(x, K[0], x_new, k1, dt, s, work)
    if not _k_finite(work):
        return t, size
    tc = t + s * dt
    for d in range(n):
        q[d] = work[d]
    _k_hermite_slope(x, K[0], x_new, k1, dt, s, dq)
    row = size
    if tc <= t:
        tc = t
        row = size - 1
    else:
        T[size] = tc
        size += 1
    for d in range(n):
        X[row, d] = q[d]
        DX[row, d] = dq[d]
    return tc, size


def _k_landed(fid, p, n_guards, x, K, x_new, k1, gv, work, q, dq, T, X, DX, fsal, t, t_new, eps, size):
    """A step that landed in a strip: q located and stored (relaxed.strip.cross_landing).
    Returns (guard index, crossing time, depth, buffer size, field evaluations, guard evaluations)."""
    n = x.shape[0]
    field_evals = 0
    if fsal:
        for d in range(n):
            k1[d] = K[K.shape[0] - 1, d]
    else:
        kk = _twin_field(fid, t_new, x_new, p)
        field_evals = 1
        for d in range(n):
            k1[d] = kk[d]
    dt = t_new - t
    e, s, guard_evals = _k_locate(fid, p, n_guards, x, K, x_new, k1, gv, work, dt, eps)
    tc, size = _k_store_crossing(x, K, x_new, k1, q, dq, work, t, dt, s, T, X, DX, size)
    return e, tc, -gv[e], size, field_evals, guard_evals


def _k_views(P, mi, m, s_stages, xw, Kw, XSw, x_neww, k1w, workw, qw, dqw):
    # Mode m's function set, dimension, guard count and parameters, and its first n entries of
    # the wide arrays (K as (stages, n)).
    n = mi[m, MI_DIM]
    return (
        mi[m, MI_FID],
        n,
        mi[m, MI_NG],
        P[mi[m, MI_P0] : mi[m, MI_P1]],
        xw[:n],
        Kw[: s_stages * n].reshape((s_stages, n)),
        XSw[:n],
        x_neww[:n],
        k1w[:n],
        workw[:n],
        qw[:n],
        dqw[:n],
    )


def _k_step_loop(
    P,
    mi,
    ti,
    hist,
    c,
    n_groups,
    weights,
    n_members,
    members,
    b_err,
    fsal,
    xw,
    Kw,
    XSw,
    x_neww,
    k1w,
    gv,
    workw,
    qw,
    dqw,
    raw,
    T,
    X,
    DX,
    fs,
    iv,
    cf,
    ci,
    cnt,
    r_i,
    r_f,
    r_q,
    r_after,
):
    """The step loop of relaxed.integrate (see the module docstring for the arrays) from mode
    iv[I_MODE] at (fs[F_T], xw, Kw[:n] = k0), through the transitions ``transit`` takes;
    in/out: iv[I_MODE], xw, Kw, fs[F_T] = t, fs[F_HPROP] = h_prop, iv[I_SIZE] = buffer size.
    Transitions crossed here are recorded in r_* (source, index, target, continued, end of the
    segment before it, image length; (time, landing time, exit time, depth); q; the image).
    Returns the code of why it stopped; counts and the stopping point are written to fs and iv.

    Each visit's steps run in ``_k_mode_loop`` on that mode's views of the wide arrays: as its
    arguments they stay fixed through its loop, which keeps the step as fast as a single mode's."""
    iv[I_STEPS] = iv[I_HALVINGS] = iv[I_REJECTIONS] = iv[I_FIELD] = iv[I_GUARD] = iv[I_RECORDS] = 0
    cnt[N_FIELD] = cnt[N_GUARD] = cnt[N_RESET] = 0
    s_stages = c.shape[0]
    code = CONTINUE
    if iv[I_ENTER] != CROSS:  # Python hands over the entry of mode iv[I_MODE] from (t, xw)
        t = fs[F_T]
        code, m, t, size, n_rec, h_prop = transit(
            P, mi, ti, hist, xw, Kw, workw, qw, raw, T, X, DX, iv, cf, ci, cnt, r_i, r_f, r_q, r_after,
            iv[I_MODE], -1, t, t, 0.0, t, iv[I_SIZE], 0, fs[F_HPROP], iv[I_ENTER],
        )  # fmt: skip
        iv[I_ENTER] = CROSS
        fs[F_T], fs[F_HPROP] = t, h_prop
        iv[I_SIZE], iv[I_RECORDS], iv[I_MODE] = size, n_rec, m
    while code == CONTINUE:
        fid, _n, n_guards, p, x, K, XS, x_new, k1, work, q, dq = _k_views(
            P, mi, iv[I_MODE], s_stages, xw, Kw, XSw, x_neww, k1w, workw, qw, dqw
        )
        code = _k_mode_loop(
            P,
            mi,
            ti,
            hist,
            c,
            n_groups,
            weights,
            n_members,
            members,
            b_err,
            fsal,
            fid,
            n_guards,
            p,
            x,
            K,
            XS,
            x_new,
            k1,
            work,
            q,
            dq,
            xw,
            Kw,
            workw,
            qw,
            gv,
            raw,
            T,
            X,
            DX,
            fs,
            iv,
            cf,
            ci,
            cnt,
            r_i,
            r_f,
            r_q,
            r_after,
        )
    iv[I_FIELD] += cnt[N_FIELD]
    iv[I_GUARD] += cnt[N_GUARD]
    iv[I_RESETS] = cnt[N_RESET]
    return code


def _k_mode_loop(
    P,
    mi,
    ti,
    hist,
    c,
    n_groups,
    weights,
    n_members,
    members,
    b_err,
    fsal,
    fid,
    n_guards,
    p,
    x,
    K,
    XS,
    x_new,
    k1,
    work,
    q,
    dq,
    xw,
    Kw,
    workw,
    qw,
    gv,
    raw,
    T,
    X,
    DX,
    fs,
    iv,
    cf,
    ci,
    cnt,
    r_i,
    r_f,
    r_q,
    r_after,
):
    """The steps of one visit of mode iv[I_MODE] (x, K, ...: its views), until it ends or
    ``transit`` enters a mode (CONTINUE: the caller goes on there). The work of every step
    (stages, guards, error test, storing the point) is written out here rather than in helpers:
    in compiled code every array that crosses a call, inlined or not, costs reference-count
    updates, which at this loop's ~20 arrays would double the cost of a step. Landings, aims and
    transitions are rare and are calls."""
    t_final, h_max, eps, rtol, atol, err_exp = cf[0], cf[1], cf[2], cf[3], cf[4], cf[5]
    adaptive, aim, max_halvings, max_steps = ci[0] != 0, ci[1] != 0, ci[2], ci[3]
    method_id, joint = ci[5], ci[7] != 0  # noqa: F841 - method_id: read by the unrolled stages
    s_stages = c.shape[0]
    n = x.shape[0]
    m = iv[I_MODE]
    blended = False
    for j in range(s_stages):
        if b_err[1, j] != 0.0:
            blended = True
    finish_tol = finish_tolerance(t_final)
    t, h_prop, size = fs[F_T], fs[F_HPROP], iv[I_SIZE]
    steps, halvings, rejections = iv[I_STEPS], iv[I_HALVINGS], iv[I_REJECTIONS]
    field_evals, guard_evals, n_rec = iv[I_FIELD], iv[I_GUARD], iv[I_RECORDS]
    code = -1
    while True:
        remaining = t_final - t
        if remaining <= finish_tol:
            fs[F_END] = t_final if remaining > 0 else t
            code = FINISHED
            break
        if size + 2 > T.shape[0]:  # room for a point, or a crossing point and the next segment's first
            code = BUFFER_FULL
            break
        if steps >= max_steps or n_rec == r_i.shape[0]:
            code = CHUNK if steps >= max_steps else RECORDS_FULL
            break
        # -- trial steps until one lands in the relaxed domain (relaxed.integrate.take_step) ----
        hk = trial_length(h_prop, h_max, remaining)
        last = hk == remaining
        shortened = 0
        aimed = 0
        rejected = False
        gmin = 0.0
        while True:
            _k_stages(fid, t, x, hk, K, XS, x_new, p, c, n_groups, weights, n_members, members, fsal)  # STAGES
            field_evals += s_stages - 1
            past = False
            finite = True
            for d in range(n):
                if not math.isfinite(x_new[d]):
                    finite = False
            if finite:
                if n_guards > 0:
                    g = _twin_guards(fid, x_new, p)
                    guard_evals += n_guards
                    gmin = g[0]
                    has_nan = g[0] != g[0]
                    gv[0] = g[0]
                    for j in range(1, n_guards):
                        gv[j] = g[j]
                        if g[j] != g[j]:
                            has_nan = True
                        elif g[j] < gmin:
                            gmin = g[j]
                    if has_nan:
                        gmin = math.nan
                if gmin >= -eps:
                    if adaptive:
                        # The estimate in stage order (methods.stepper.error_estimator) and its norm.
                        high = 0.0
                        low = 0.0
                        for d in range(n):
                            acc = 0.0
                            acc_low = 0.0
                            started = False
                            for j in range(s_stages):
                                if b_err[0, j] != 0.0:
                                    acc = acc + b_err[0, j] * K[j, d] if started else b_err[0, j] * K[j, d]
                                    started = True
                                if blended:
                                    acc_low += b_err[1, j] * K[j, d]
                            scale = error_scale(x[d], x_new[d], rtol, atol)
                            r = (hk * acc) / scale
                            high += r * r
                            if blended:
                                r_low = (hk * acc_low) / scale
                                low += r_low * r_low
                        error = scaled_norm(high, low, n, blended)
                        if error > 1.0:
                            rejections += 1
                            rejected = True
                            hk = rejected_step(hk, error, err_exp)
                            last = False
                            continue
                        h_prop = kept_proposal(
                            h_prop, proposed_step(hk, error, err_exp, rejected), shortened > 0, rejected
                        )
                    break
                if gmin != gmin:
                    iv[I_GUARD_INDEX] = _k_first_nan(gv, n_guards)
                    fs[F_NAN_T] = t + hk
                    code = GUARD_NAN
                    break
                past = True
            shortened += 1
            hk_tried = hk
            if aim and past and aimed < MAX_AIMS:
                hk, fe, ge = _k_aim(fid, p, n_guards, x, K, x_new, k1, gv, work, t, hk, eps, fsal, s_stages)
                field_evals += fe
                guard_evals += ge
                aimed += 1
            else:
                hk *= 0.5
            last = False
            if shortening_exhausted(shortened, max_halvings, t, hk, 0):
                fs[F_HTRIED] = hk_tried
                code = NONFINITE_STEP
                if past:
                    iv[I_GUARD_INDEX] = _k_argmin(gv, n_guards)
                    iv[I_FAILED_HALVINGS] = shortened - 1
                    code = EXHAUSTED
                break
        halvings += shortened
        if code >= 0:
            break
        t_new = t_final if last else t + hk
        steps += 1
        if n_guards == 0 or gmin >= 0.0:
            # -- the step's end becomes the current point --------------------------------------
            t = t_new
            for d in range(n):
                x[d] = x_new[d]
            if fsal:
                for d in range(n):
                    K[0, d] = K[s_stages - 1, d]
            else:
                kk = _twin_field(fid, t, x, p)
                field_evals += 1
                for d in range(n):
                    K[0, d] = kk[d]
            T[size] = t
            for d in range(n):
                X[size, d] = x[d]
                DX[size, d] = K[0, d]
            size += 1
            continue
        # -- the step landed in one or more strips (relaxed.strip.cross_landing) ------------------
        e, tc, tau, size, fe, ge = _k_landed(
            fid, p, n_guards, x, K, x_new, k1, gv, work, q, dq, T, X, DX, fsal, t, t_new, eps, size
        )
        field_evals += fe
        guard_evals += ge
        fs[F_LAND], fs[F_TC], fs[F_TAU], iv[I_GUARD_INDEX] = t_new, tc, tau, e
        code = TRANSITION
        if not single_crossing(ti, mi[m, MI_SLOT], gv, n_guards, joint):
            break
        code, m, t, size, n_rec, h_prop = transit(
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
            t_new,
            tau,
            t,
            size,
            n_rec,
            h_prop,
            CROSS,
        )
        break  # CONTINUE: the caller goes on in mode m
    fs[F_T], fs[F_HPROP] = t, h_prop
    iv[I_STEPS], iv[I_HALVINGS], iv[I_REJECTIONS] = steps, halvings, rejections
    iv[I_FIELD], iv[I_GUARD] = field_evals, guard_evals
    iv[I_SIZE], iv[I_RECORDS], iv[I_MODE] = size, n_rec, m
    return code


def _k_first_nan(values, n):
    for j in range(n):
        if values[j] != values[j]:
            return j
    return 0


#: The kernel's functions, in the order the generated module defines them.
KERNEL_FUNCTIONS = (
    _k_combine,
    _k_stages,
    _k_hermite,
    _k_hermite_slope,
    _k_first_nan,
    _k_crossing,
    _k_aim,
    _k_locate,
    _k_store_crossing,
    _k_landed,
    _k_views,
    _k_mode_loop,
    _k_step_loop,
    *TRANSIT_FUNCTIONS,
)
#: The functions every step runs (inlined into the loop by the generator).
EVERY_STEP = (
    _k_stages,
    _k_combine,
    trial_length,
    finish_tolerance,
    rejected_step,
    proposed_step,
    kept_proposal,
    error_scale,
    scaled_norm,
)
#: The rules the kernel calls, compiled from their own source.
RULES = (
    trial_length,
    finish_tolerance,
    rejected_step,
    proposed_step,
    kept_proposal,
    shortening_exhausted,
    aimed_step,
    crossing_start,
    crossing_point,
    crossing_update,
    hermite_weights,
    hermite_slope_weights,
    error_scale,
    scaled_norm,
    *TRANSIT_RULES,
)
#: The placeholder call of _k_stages in _k_mode_loop that the generator unrolls per method.
STAGES_CALL = "_k_stages(fid, t, x, hk, K, XS, x_new, p, c, n_groups, weights, n_members, members, fsal)  # STAGES"
