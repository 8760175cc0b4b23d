"""Compiled step loops: a mode's flow between guards run by a numba kernel.

A mode may carry a *compiled twin* (``Mode(..., compiled=CompiledMode(...))``): numba-jitted
functions computing the same field and guards as its Python callables,

* ``field(t, x, p) -> dx/dt``, shape (n,),
* ``guards(x, p) -> values``, shape (n_guards,), in the order of the mode's outgoing
  transitions (the same values as their Python guards),

with ``p`` a float64 parameter array. Parameters travel as data rather than as closure
constants so that one compilation of the kernel serves every parameter set of a model (numba
treats closure variables as constants and would compile the kernel again for each).

and optionally ``resets(x, p, e) -> x'`` (the reset of outgoing transition e).

When the run has no control (compiled twins take none) and no guard depends on (t, u),
``relaxed._Integrator._run_mode`` hands the step loop to ``run_mode_compiled``: the kernel
takes the steps, shortens a step that would leave the relaxed domain (halving, or aiming with
the step's interpolant), controls the local error of embedded pairs, stores the points in the
segment buffer, and locates the strip point of a step that lands in a strip (the same root
search as ``relaxed.crossing_on_step``). When the twin has resets and every outgoing transition
returns to the same mode (impacts, bounces), the kernel also holds, resets and re-enters, so a
run with thousands of transitions (chattering, Zeno) stays compiled and Python only turns the
recorded transitions into ``Execution`` pieces in batches. Everything else (transitions to
other modes, the budget, a run ending in a strip, non-finite reset images, a reset image inside
a strip) goes through the shared Python code (``_transition``, ``_run_mode``).

The kernel does the same floating-point operations in the same order as the Python stepper
(stage combinations grouped as ``methods.make_stepper`` groups them, unrolled per built-in
method, the same Hermite interpolant, root search and error norm), so both paths give the same
execution, in practice to the bit (tests/test_compiled.py) for the built-in methods. A tableau
whose long rows the Python stepper combines by one matrix product (DOP853, see
``methods._DOT_TERMS``) agrees to rounding instead: the same steps and transitions, step sizes
within ~1e-8. The kernel never lands on dense output: ``landing="dense"`` runs the Python loop.
Difference: a kernel evaluates all
guards of a mode at once, and counts ``n_guards`` guard evaluations per call where the Python
loop counts one per guard it calls (the same count for one guard).

The kernel's source is the ``_k_*`` functions below, plain Python; ``get_kernel`` writes, per
pair of module-level twin functions, a module that imports them as globals into
``cache_dir()``, and numba caches its machine code there (first use ~5 s, then milliseconds).
"""

from __future__ import annotations

import gc
import hashlib
import importlib
import importlib.util
import inspect
import math
import os
import sys
import tempfile
import time as _time
from dataclasses import dataclass, field as _dc_field
from pathlib import Path
from typing import Any

import numba
import numpy as np

from .errors import ModelError
from .execution import Segment, SegmentBuffer, Strip, TransitionRecord
from .methods import METHODS, Tableau

# Kernel return codes.
FINISHED = 0
TRANSITION = 1
NONFINITE_STEP = 2
GUARD_NAN = 3
EXHAUSTED = 4
BUFFER_FULL = 5
CHUNK = 6
NEXT = 7
RECORDS_FULL = 8

#: Transitions the kernel records per call before Python turns them into Execution pieces.
RECORD_CHUNK = 4096

#: Steps per kernel call when a progress callback wants reports (about 1 ms of work).
PROGRESS_CHUNK = 8192
_NO_LIMIT = 1 << 62


@dataclass(frozen=True)
class CompiledMode:
    """The compiled twin of a mode.

    Attributes
    ----------
    field: numba-jitted ``field(t, x, p) -> (n,)``, no control.
    guards: numba-jitted ``guards(x, p) -> (n_guards,)``, ordered like the mode's outgoing
        transitions, >= 0 inside the domain (same values as the Python guards).
    n_guards: number of guards (the mode's outgoing transitions).
    params: float64 parameter array ``p`` passed to all three.
    resets: optional numba-jitted ``resets(x, p, e) -> x'`` (the reset of outgoing transition e,
        same values as the Python reset). With it, and when every outgoing transition returns to
        this same mode (impacts, bounces), the kernel also crosses the strips, so a run with
        many transitions (chattering, Zeno) stays compiled; Python then only turns the
        recorded transitions into Execution pieces.
    """

    field: Any
    guards: Any
    n_guards: int
    params: np.ndarray = _dc_field(default_factory=lambda: np.zeros(0))
    resets: Any = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "params", np.ascontiguousarray(self.params, dtype=np.float64).reshape(-1))
        if isinstance(self.n_guards, bool) or not isinstance(self.n_guards, (int, np.integer)) or self.n_guards < 0:
            raise ModelError(f"CompiledMode n_guards must be an integer >= 0, got {self.n_guards!r}")
        object.__setattr__(self, "n_guards", int(self.n_guards))


# --------------------------------------------------------------------------------------------
# The tableau as arrays, grouped like methods.make_stepper so the arithmetic is the same.
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Plan:
    c: np.ndarray  # (s,)
    n_groups: np.ndarray  # (s + 1,) row s is the output combination
    weights: np.ndarray  # (s + 1, G)
    n_members: np.ndarray  # (s + 1, G)
    members: np.ndarray  # (s + 1, G, s)
    b_err: np.ndarray  # (2, s): b_err and b_err_low, zeros where the method has none
    fsal: bool
    stages: int


# By id, holding the tableau itself too, so that an id cannot be reused by another tableau.
_PLANS: dict[int, tuple[Tableau, _Plan]] = {}


def _groups(weights: np.ndarray) -> list[tuple[float, list[int]]]:
    groups: dict[float, list[int]] = {}
    for j, w in enumerate(weights):
        if w != 0.0:
            groups.setdefault(float(w), []).append(j)
    return list(groups.items())


def plan_for(tableau: Tableau) -> _Plan:
    """The tableau as the kernel's arrays (cached per tableau object)."""
    entry = _PLANS.get(id(tableau))
    if entry is not None and entry[0] is tableau:
        return entry[1]
    s = tableau.stages
    rows = [_groups(tableau.A[i, :i]) if i > 0 else [] for i in range(s)] + [_groups(tableau.b)]
    width = max(1, max(len(r) for r in rows))
    n_groups = np.zeros(s + 1, dtype=np.int64)
    weights = np.zeros((s + 1, width))
    n_members = np.zeros((s + 1, width), dtype=np.int64)
    members = np.zeros((s + 1, width, s), dtype=np.int64)
    for i, row in enumerate(rows):
        n_groups[i] = len(row)
        for g, (w, js) in enumerate(row):
            weights[i, g] = w
            n_members[i, g] = len(js)
            members[i, g, : len(js)] = js
    b_err = np.zeros((2, s))
    if tableau.b_err is not None:
        b_err[0] = tableau.b_err
    if tableau.b_err_low is not None:
        b_err[1] = tableau.b_err_low
    plan = _Plan(np.asarray(tableau.c, dtype=float), n_groups, weights, n_members, members, b_err,
                 bool(tableau.fsal), s)
    _PLANS[id(tableau)] = (tableau, plan)
    return plan


# --------------------------------------------------------------------------------------------
# The kernel, as plain Python. numba compiles a copy of these functions per compiled twin, in a
# generated module whose globals ``_twin_field`` and ``_twin_guards`` are the twin's functions:
# a module-level global is a compile-time constant numba can inline and cache on disk, whereas
# passing the functions as arguments would recompile the whole loop in every process (5 s).
# --------------------------------------------------------------------------------------------
def _twin_field(t, x, p):  # placeholder, bound per twin in the generated module
    raise NotImplementedError


def _twin_guards(x, p):  # placeholder, bound per twin in the generated module
    raise NotImplementedError


def _twin_resets(x, p, e):  # placeholder, bound per twin in the generated module
    raise NotImplementedError


def _k_combine(x, K, row, n_groups, weights, n_members, members, h, out):
    # out = x + sum_g (h * w_g) * (k_{m0} + k_{m1} + ...), evaluated left to right like
    # the generated Python stepper. Plain indexing only: a row view would cost two reference
    # count updates per call.
    n = x.shape[0]
    for d in range(n):
        acc = x[d]
        for g in range(n_groups[row]):
            ssum = K[members[row, g, 0], d]
            for m in range(1, n_members[row, g]):
                ssum = ssum + K[members[row, g, m], d]
            acc = acc + (h * weights[row, g]) * ssum
        out[d] = acc


def _k_hermite(x0, d0, x1, d1, dt, s, out):
    s2 = s * s
    s3 = s2 * s
    c00 = 2 * s3 - 3 * s2 + 1
    c10 = (s3 - 2 * s2 + s) * dt
    c01 = -2 * s3 + 3 * s2
    c11 = (s3 - s2) * dt
    for d in range(x0.shape[0]):
        out[d] = c00 * x0[d] + c10 * d0[d] + c01 * x1[d] + c11 * d1[d]

def _k_crossing(p, e, shift, x0, d0, x1, d1, dt, g0, g1, tol, work):
    # relaxed.crossing_on_step on the compiled guard e shifted by `shift` (the same iterates, the
    # same safeguards and the same choice of the past-side end); returns (s, guard calls, converged).
    if g0 <= 0.0:
        return 0.0, 0, True
    floor = 1e-15 * (g0 - g1)  # relaxed.crossing_on_step: no finer than the guard's rounding
    if floor > tol:
        tol = floor
    if -g1 <= tol:
        return 1.0, 0, True
    lo = 0.0
    hi = 1.0
    glo = g0
    ghi = g1
    g_hi = g1
    evals = 0
    side = 0
    width = 1.0
    stalled = 0
    for _ in range(200):
        if stalled >= 3:  # relaxed._STALL (literals: this source is copied into each twin's module)
            s = 0.5 * (lo + hi)
        else:
            s = lo + (hi - lo) * glo / (glo - ghi)
            if not (lo < s < hi):
                s = 0.5 * (lo + hi)
        if hi - lo > 8e-16:  # 2 relaxed._MIN_STEP
            if s - lo < 4e-16:
                s = lo + 4e-16
            elif hi - s < 4e-16:
                s = hi - 4e-16
        _k_hermite(x0, d0, x1, d1, dt, s, work)
        g = _twin_guards(work, p)[e] + shift
        evals += 1
        if not math.isfinite(g):
            return lo, evals, False
        if g == 0.0:
            return s, evals, True
        if g > 0:
            lo = s
            glo = g
            if side == 1:
                ghi *= 0.5
            side = 1
        else:
            hi = s
            ghi = g
            g_hi = g
            if -g <= tol:
                return hi, evals, True
            if side == -1:
                glo *= 0.5
            side = -1
        if hi - lo <= 0.5 * width:
            width = hi - lo
            stalled = 0
        else:
            stalled += 1
        if hi - lo <= 4e-16:
            break
    if hi - lo <= 4e-16 and -g_hi <= 1e6 * tol:
        return hi, evals, True
    return lo, evals, False

def _k_error_norm(b_err, hk, K, x, x_new, rtol, atol):
    n = x.shape[0]
    blended = False
    for j in range(b_err.shape[1]):
        if b_err[1, j] != 0.0:
            blended = True
    total = 0.0
    first = 0.0
    low = 0.0
    for d in range(n):
        scale = atol + rtol * max(abs(x[d]), abs(x_new[d]))
        acc = 0.0
        started = False
        for j in range(b_err.shape[1]):
            if b_err[0, j] != 0.0:
                if started:
                    acc = acc + b_err[0, j] * K[j, d]
                else:
                    acc = b_err[0, j] * K[j, d]
                    started = True
        r = (hk * acc) / scale
        if d == 0:
            first = r * r
        else:
            total += r * r
        if blended:
            acc = 0.0
            for j in range(b_err.shape[1]):
                acc += b_err[1, j] * K[j, d]
            r = (hk * acc) / scale
            low += r * r
    if blended:
        # Hairer's DOP853 norm (methods.make_error_norm), to rounding.
        high = first + total
        if high == 0.0 and low == 0.0:
            return 0.0
        return high / math.sqrt((high + 0.01 * low) * n)
    # numpy's mean: the first element plus the (sequential, n < 9) sum of the rest.
    return math.sqrt((first + total) / n)

def _k_hermite_derivative(x0, d0, x1, d1, dt, s, out):
    s2 = s * s
    c0 = 6 * s2 - 6 * s
    c1 = 3 * s2 - 4 * s + 1
    c2 = -6 * s2 + 6 * s
    c3 = 3 * s2 - 2 * s
    for d in range(x0.shape[0]):
        out[d] = c0 * x0[d] / dt + c1 * d0[d] + c2 * x1[d] / dt + c3 * d1[d]


def _k_finite(v):
    for d in range(v.shape[0]):
        if not math.isfinite(v[d]):
            return False
    return True


def _k_stages(t, x, hk, K, XS, x_new, p, c, n_groups, weights, n_members, members, fsal):
    # The stages of any tableau from its arrays. The generated module replaces the call of this
    # function in the step loop by straight-line code for each built-in method (see
    # _stage_source), which is twice as fast for RK4; this stays for other tableaux.
    n = x.shape[0]
    s_stages = c.shape[0]
    for i in range(1, s_stages):
        _k_combine(x, K, i, n_groups, weights, n_members, members, hk, XS)
        ki = _twin_field(t + c[i] * hk, XS, p)
        for d in range(n):
            K[i, d] = ki[d]
    if fsal:  # the last stage is evaluated at the new point itself
        for d in range(n):
            x_new[d] = XS[d]
    else:
        _k_combine(x, K, s_stages, n_groups, weights, n_members, members, hk, x_new)


def _k_step_loop(p, n_guards, c, n_groups, weights, n_members, members, b_err, fsal,
                 x, K, XS, x_new, k1, gv, work, q, dq, T, X, DX, fs, iv, cf, ci,
                 r_e, r_f, r_q, r_after, seg_end):
    """The step loop of relaxed._Integrator._run_mode, and the strip crossings of its
    self-transitions when the twin has compiled resets.

    In/out: x, K[0] (= k0), fs[0] = t, fs[1] = h_prop, iv[5] = buffer size.
    Settings: cf = (t_final, h_max, eps, rtol, atol, err_exp), ci = (adaptive, aim, max_halvings,
    max_steps, in_kernel_transitions, transition budget).
    Out: counters iv[0:5] (steps, halvings, error rejections, field and guard evaluations),
    iv[8] resets, iv[9] transitions recorded in r_* (guard index, (time, landing time, exit
    time, depth), q, reset image; the segment before record k ends at buffer index seg_end[k]);
    for code 1 the crossing: guard iv[6], fs[6] = time, q, fs[2] = landing time, fs[7] = depth;
    fs[3] = last step tried, fs[4] = end time, fs[5] = time of a nan guard, iv[7] = halvings
    of a failed step."""
    t_final = cf[0]
    h_max = cf[1]
    eps = cf[2]
    rtol = cf[3]
    atol = cf[4]
    err_exp = cf[5]
    adaptive = ci[0] != 0
    aim = ci[1] != 0
    max_halvings = ci[2]
    max_steps = ci[3]
    in_kernel = ci[4] != 0
    budget = ci[5]
    method_id = ci[6]
    s_stages = c.shape[0]
    n = x.shape[0]
    finish_tol = 8.0 * 2.220446049250313e-16 * abs(t_final)  # as relaxed._run_mode
    t = fs[0]
    h_prop = fs[1]
    size = iv[5]
    cap = T.shape[0]
    rec_cap = r_e.shape[0]
    steps = 0
    halvings = 0
    rejections = 0
    field_evals = 0
    guard_evals = 0
    resets = 0
    n_rec = 0
    code = -1
    gmin = 0.0
    while True:
        remaining = t_final - t
        if remaining <= finish_tol:
            fs[4] = t_final if remaining > 0 else t
            code = 0
            break
        if size + 2 > cap:  # room for a point, or a crossing point and the next segment's first
            code = 5
            break
        if steps >= max_steps:
            code = 6
            break
        if n_rec == rec_cap:
            code = 8
            break
        hk = h_prop if h_prop < h_max else h_max
        last = hk >= remaining
        if last:
            hk = remaining
        shortened = 0
        aimed = 0
        rejected = False
        outcome = -1
        while True:
            _k_stages(t, x, hk, K, XS, x_new, p, c, n_groups, weights, n_members, members, fsal)  # STAGES
            field_evals += s_stages - 1
            # Component-wise, like the Python loop's confirmed check: a sum of squares would
            # overflow for finite states above ~1e154 and call them non-finite.
            past = False
            if not _k_finite(x_new):
                past = False  # non-finite: halve
            else:
                if n_guards > 0:
                    g = _twin_guards(x_new, p)
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
                else:
                    gmin = 0.0
                if gmin >= -eps:
                    if adaptive:
                        err = _k_error_norm(b_err, hk, K, x, x_new, rtol, atol)
                        if err > 1.0:
                            rejections += 1
                            rejected = True
                            hk *= max(0.2, 0.9 * err ** err_exp)
                            last = False
                            continue
                        if err > 0:
                            proposal = hk * min(5.0, max(0.2, 0.9 * err ** err_exp))
                        else:
                            proposal = 5.0 * hk
                        if rejected and proposal > hk:
                            proposal = hk
                        # As relaxed._run_mode: a step shortened to land keeps the proposal.
                        if shortened > 0 and not rejected:
                            h_prop = max(h_prop, proposal)
                        else:
                            h_prop = proposal
                    break
                if gmin != gmin:
                    for j in range(n_guards):
                        if gv[j] != gv[j]:
                            iv[6] = j
                            break
                    fs[5] = t + hk
                    outcome = 3
                    break
                past = True
            shortened += 1
            hk_old = hk
            if aim and past and aimed < 3:
                e = 0
                for j in range(1, n_guards):
                    if gv[j] < gv[e]:
                        e = j
                if fsal:
                    for d in range(n):
                        k1[d] = K[s_stages - 1, d]
                else:
                    kk = _twin_field(t + hk, x_new, p)
                    field_evals += 1
                    for d in range(n):
                        k1[d] = kk[d]
                half = 0.5 * eps
                g0 = _twin_guards(x, p)[e] + half
                guard_evals += n_guards
                s, n_evals, converged = _k_crossing(p, e, half, x, K[0], x_new, k1, hk, g0,
                                                    gv[e] + half, 1e-3 * half, work)
                guard_evals += n_evals * n_guards
                if not converged or not (0.0 < s < 1.0):
                    hk = 0.5 * hk
                else:
                    hk = s * hk
                aimed += 1
            else:
                hk *= 0.5
            last = False
            if shortened > max_halvings or t + hk <= t:
                fs[3] = hk_old
                if not past:
                    outcome = 2
                else:
                    e = 0
                    for j in range(1, n_guards):
                        if gv[j] < gv[e]:
                            e = j
                    iv[6] = e
                    iv[7] = shortened - 1
                    outcome = 4
                break
        halvings += shortened
        if outcome >= 0:
            code = outcome
            break
        t_new = t_final if last else t + hk
        steps += 1
        if n_guards > 0 and gmin < 0.0:
            # The step landed in one or more strips (relaxed._Integrator._step_transition):
            # q is where the step's interpolant first meets a crossed guard.
            if fsal:
                for d in range(n):
                    k1[d] = K[s_stages - 1, d]
            else:
                kk = _twin_field(t_new, x_new, p)
                field_evals += 1
                for d in range(n):
                    k1[d] = kk[d]
            dt = t_new - t
            best_e = -1
            best_s = 0.0
            for j in range(n_guards):
                if gv[j] < 0.0:
                    g0 = _twin_guards(x, p)[j]
                    s, n_evals, converged = _k_crossing(p, j, 0.0, x, K[0], x_new, k1, dt, g0, gv[j], 1e-12 * eps,
                                                        work)
                    guard_evals += n_guards * (1 + n_evals)
                    if best_e < 0 or s < best_s:
                        best_e = j
                        best_s = s
            e = best_e
            s = best_s
            tc = t
            for d in range(n):
                q[d] = x[d]
            if s > 0.0:
                _k_hermite(x, K[0], x_new, k1, dt, s, work)
                if _k_finite(work):
                    tc = t + s * dt
                    for d in range(n):
                        q[d] = work[d]
                    _k_hermite_derivative(x, K[0], x_new, k1, dt, s, dq)
                    # As in relaxed._step_transition: a crossing that rounds to the step's start
                    # replaces that point instead of repeating its time.
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
            tau = -gv[e]
            fs[2] = t_new
            fs[6] = tc
            fs[7] = tau
            iv[6] = e
            # The strip (relaxed._Integrator._transition) stays here only for the ordinary case:
            # a reset to this same mode with a finite image, inside the budget and before t_final.
            exit_time = t_new + (eps - tau)
            if not in_kernel or n_rec >= budget or exit_time >= t_final:
                code = 1
                break
            ra = _twin_resets(q, p, e)
            if not _k_finite(ra):
                code = 1
                break
            resets += 1
            r_e[n_rec] = e
            r_f[n_rec, 0] = tc
            r_f[n_rec, 1] = t_new
            r_f[n_rec, 2] = exit_time
            r_f[n_rec, 3] = tau
            for d in range(n):
                r_q[n_rec, d] = q[d]
                r_after[n_rec, d] = ra[d]
            seg_end[n_rec] = size
            n_rec += 1
            # Entering the mode again at the strip's exit (relaxed._Integrator._run_mode); any
            # state needing the entry's special cases goes back to Python.
            t = exit_time
            for d in range(n):
                x[d] = ra[d]
            kk = _twin_field(t, x, p)
            entry_ok = _k_finite(kk)
            if entry_ok and n_guards > 0:
                g = _twin_guards(x, p)
                for j in range(n_guards):
                    if not (g[j] >= 0.0):
                        entry_ok = False
            if not entry_ok:
                code = 7
                break
            field_evals += 1
            guard_evals += n_guards
            for d in range(n):
                K[0, d] = kk[d]
            T[size] = t
            for d in range(n):
                X[size, d] = x[d]
                DX[size, d] = kk[d]
            size += 1
            continue
        t = t_new
        for d in range(n):
            x[d] = x_new[d]
        if fsal:
            for d in range(n):
                K[0, d] = K[s_stages - 1, d]
        else:
            kk = _twin_field(t, x, p)
            field_evals += 1
            for d in range(n):
                K[0, d] = kk[d]
        T[size] = t
        for d in range(n):
            X[size, d] = x[d]
            DX[size, d] = K[0, d]
        size += 1
    fs[0] = t
    fs[1] = h_prop
    iv[0] = steps
    iv[1] = halvings
    iv[2] = rejections
    iv[3] = field_evals
    iv[4] = guard_evals
    iv[5] = size
    iv[8] = resets
    iv[9] = n_rec
    return code


_KERNEL_FUNCTIONS = (_k_combine, _k_hermite, _k_hermite_derivative, _k_finite, _k_crossing, _k_error_norm,
                     _k_stages, _k_step_loop)
#: The methods with straight-line stage code in the kernel, by method id (ci[6]).
_BUILTIN = tuple(METHODS.values())
_STAGES_CALL = "_k_stages(t, x, hk, K, XS, x_new, p, c, n_groups, weights, n_members, members, fsal)  # STAGES"


def _sum_source(base: str, weights: np.ndarray) -> str:
    """``base + (hk * w) * (K[j, d] + ...) + ...`` grouped exactly as methods._combination
    groups the Python stepper's terms, so both give the same rounding."""
    out = base
    for w, js in _groups(weights):
        terms = " + ".join(f"K[{j}, d]" for j in js)
        out += f" + (hk * {w!r}) * " + (f"({terms})" if len(js) > 1 else terms)
    return out


def _stage_source(tableau: Tableau, indent: str) -> list[str]:
    """Straight-line stage code of one tableau (the body of _k_stages, unrolled)."""
    s = tableau.stages
    lines = []
    for i in range(1, s):
        lines += [f"for d in range(n):", f"    XS[d] = {_sum_source('x[d]', tableau.A[i, :i])}",
                  f"ki = _twin_field(t + {float(tableau.c[i])!r} * hk, XS, p)",
                  "for d in range(n):", f"    K[{i}, d] = ki[d]"]
    if tableau.fsal:
        lines += ["for d in range(n):", "    x_new[d] = XS[d]"]
    else:
        lines += ["for d in range(n):", f"    x_new[d] = {_sum_source('x[d]', tableau.b)}"]
    return [indent + line for line in lines]


def _unrolled_stages(indent: str) -> str:
    lines = []
    for mid, tableau in enumerate(_BUILTIN):
        lines.append(f"{indent}{'if' if mid == 0 else 'elif'} method_id == {mid}:  # {tableau.name}")
        lines += _stage_source(tableau, indent + "    ")
    lines += [f"{indent}else:", f"{indent}    {_STAGES_CALL}"]
    return "\n".join(lines)
_KERNELS: dict[tuple[int, int, int], Any] = {}


@numba.njit(cache=True)
def no_resets(x, p, e):
    """The kernel's reset for twins without compiled resets (never called: such twins hand
    every transition to Python)."""
    return x.copy()


def _importable(fn) -> str | None:
    """``module:qualname`` of a module-level jitted function, or None (closures, __main__)."""
    py = getattr(fn, "py_func", None)
    module, qualname = getattr(py, "__module__", None), getattr(py, "__qualname__", "")
    if py is None or module in (None, "__main__") or "<" in qualname or "." in qualname:
        return None
    try:
        if getattr(importlib.import_module(module), qualname) is fn:
            return f"{module}:{qualname}"
    except Exception:
        return None
    return None


def cache_dir() -> Path:
    """Where generated kernel modules and numba's compiled code for them live:
    ``$LEGSIM_CACHE_DIR``, else ``$XDG_CACHE_HOME/legsim/kernels`` (``~/.cache/legsim/kernels``)."""
    env = os.environ.get("LEGSIM_CACHE_DIR")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "legsim" / "kernels"


def _kernel_source(imports: list[str]) -> str:
    lines = ["# Generated by legsim.compiled from the functions _k_* there; edit those, not this file.",
             "import math", "", "import numba", "import numpy as np", ""]
    lines += imports
    lines += ["", "_njit = numba.njit(cache=CACHE, fastmath=False, nogil=True)", ""]
    for fn in _KERNEL_FUNCTIONS:
        source = inspect.getsource(fn).rstrip()
        if fn is _k_step_loop:
            marker = source.index(_STAGES_CALL)
            indent = source[source.rindex("\n", 0, marker) + 1: marker]
            source = source[: marker - len(indent)] + _unrolled_stages(indent) + source[marker + len(_STAGES_CALL):]
        lines += ["", "@_njit", source, ""]
    return "\n".join(lines) + "\n"


def get_kernel(twin: CompiledMode):
    """The jitted step loop bound to ``twin``'s field and guards.

    For twins defined at module level the kernel is generated once into ``cache_dir()`` and
    numba caches its machine code there, so later processes load it in milliseconds; other
    twins (closures) get a kernel compiled in this process only.
    """
    resets = no_resets if twin.resets is None else twin.resets
    key = (id(twin.field), id(twin.guards), id(resets))
    kernel = _KERNELS.get(key)
    if kernel is not None:
        return kernel
    names = (_importable(twin.field), _importable(twin.guards), _importable(resets))
    kernel = None
    if None not in names:
        imports = []
        for alias, name in zip(("_twin_field", "_twin_guards", "_twin_resets"), names):
            module, qualname = name.split(":")
            imports.append(f"from {module} import {qualname} as {alias}")
        text = _kernel_source(imports).replace("cache=CACHE", "cache=True")
        digest = hashlib.sha256((text + numba.__version__).encode()).hexdigest()[:20]
        try:
            directory = cache_dir()
            directory.mkdir(parents=True, exist_ok=True)
            path = directory / f"legsim_kernel_{digest}.py"
            if not path.exists() or path.read_text() != text:
                fd, tmp = tempfile.mkstemp(prefix=path.name, suffix=".tmp", dir=directory)
                with os.fdopen(fd, "w") as fh:
                    fh.write(text)
                os.replace(tmp, path)
            spec = importlib.util.spec_from_file_location(f"legsim_kernel_{digest}", path)
            module = importlib.util.module_from_spec(spec)
            # numba's cache finds a function's module by name when it loads compiled code.
            sys.modules[spec.name] = module
            spec.loader.exec_module(module)
            kernel = module._k_step_loop
        except OSError:
            kernel = None  # no writable cache: compile in memory below
    if kernel is None:
        namespace: dict[str, Any] = {"_twin_field": twin.field, "_twin_guards": twin.guards, "_twin_resets": resets}
        text = _kernel_source([]).replace("cache=CACHE", "cache=False")
        exec(compile(text, "<legsim kernel>", "exec"), namespace)  # noqa: S102 - our own functions' source
        kernel = namespace["_k_step_loop"]
    _KERNELS[key] = kernel
    return kernel


# --------------------------------------------------------------------------------------------
# The Python side: called by relaxed._Integrator._run_mode.
# --------------------------------------------------------------------------------------------
def _check_twin(integrator, data, t: float, x: np.ndarray, k0: np.ndarray) -> bool:
    """Once per mode and run: the twin must return the Python callables' shapes and values.
    Returns whether the kernel may cross this mode's strips itself."""
    checked = integrator.__dict__.setdefault("_compiled_checked", {})
    if data.name in checked:
        return checked[data.name]
    cm = data.mode.compiled
    name = integrator.system.name
    if not isinstance(cm, CompiledMode):
        raise ModelError(f"{name}: mode '{data.name}'.compiled must be a legsim.compiled.CompiledMode, "
                         f"got {type(cm).__name__}")
    if cm.n_guards != len(data.guards):
        raise ModelError(f"{name}: compiled twin of mode '{data.name}' declares {cm.n_guards} guards, the mode "
                         f"has {len(data.guards)} outgoing transitions")
    xc = np.ascontiguousarray(x, dtype=float)
    try:
        f = np.asarray(cm.field(float(t), xc, cm.params), dtype=float)
        g = np.asarray(cm.guards(xc, cm.params), dtype=float)
        r = [np.asarray(cm.resets(xc, cm.params, e), dtype=float) for e in range(cm.n_guards)] \
            if cm.resets is not None else []
    except Exception as exc:
        raise ModelError(f"{name}: compiled twin of mode '{data.name}' failed at t={t}: "
                         f"{type(exc).__name__}: {exc}") from exc
    if f.shape != (data.mode.dim,) or g.shape != (cm.n_guards,):
        raise ModelError(f"{name}: compiled twin of mode '{data.name}' returned field shape {f.shape} and guards "
                         f"shape {g.shape}, expected ({data.mode.dim},) and ({cm.n_guards},)")
    g_py = np.array([float(gd(x)) for gd in data.guards])
    scale = 1e-9 * (1.0 + np.abs(k0))
    if not (np.all(np.abs(f - k0) <= scale) and np.allclose(g, g_py, rtol=1e-9, atol=1e-12)):
        raise ModelError(f"{name}: compiled twin of mode '{data.name}' disagrees with the Python callables at "
                         f"t={t}, x={x.tolist()}: field {f.tolist()} vs {k0.tolist()}, guards {g.tolist()} vs "
                         f"{g_py.tolist()}")
    for e, (tr, reset, image) in enumerate(zip(data.transitions, data.resets, r)):
        expected = np.asarray(reset(x.copy()), dtype=float)
        if image.shape != expected.shape or not np.allclose(image, expected, rtol=1e-9, atol=1e-12, equal_nan=True):
            raise ModelError(f"{name}: compiled reset {e} of mode '{data.name}' disagrees with the reset of "
                             f"transition {tr.name} at x={x.tolist()}: {image.tolist()} vs {expected.tolist()}")
    in_kernel = cm.resets is not None and all(target == data.name for target in data.targets)
    checked[data.name] = in_kernel
    return in_kernel


def _grow(buf) -> None:
    new = 4 * len(buf.t)  # every return from the kernel costs microseconds: grow fast
    buf.t = np.resize(buf.t, new)
    buf.x = np.resize(buf.x, (new, buf.x.shape[1]))
    buf.dx = np.resize(buf.dx, (new, buf.dx.shape[1]))


class _Workspace:
    """Per-run scratch arrays of the kernel for one mode (reused across visits)."""

    def __init__(self, n: int, stages: int, n_guards: int) -> None:
        self.K = np.zeros((stages, n))
        self.XS = np.zeros(n)
        self.x_new = np.zeros(n)
        self.k1 = np.zeros(n)
        self.gv = np.zeros(max(1, n_guards))
        self.work = np.zeros(n)
        self.q = np.zeros(n)
        self.dq = np.zeros(n)
        self.fs = np.zeros(8)
        self.iv = np.zeros(10, dtype=np.int64)
        self.cf = np.zeros(6)
        self.ci = np.zeros(7, dtype=np.int64)
        self.r_e = np.zeros(RECORD_CHUNK, dtype=np.int64)
        self.r_f = np.zeros((RECORD_CHUNK, 4))
        self.r_q = np.zeros((RECORD_CHUNK, n))
        self.r_after = np.zeros((RECORD_CHUNK, n))
        self.seg_end = np.zeros(RECORD_CHUNK, dtype=np.int64)


def _build_pieces(mode, trs, T, X, DX, r_e, r_f, qs, afters, ends, segments, strips, records) -> None:
    start = 0
    q_rows = list(qs)  # row views, made in one go
    after_rows = list(afters)
    for k, end in enumerate(ends):
        # Views of this buffer: it is never written again once the tail moves out.
        segments.append(Segment(mode, T[start:end], X[start:end], DX[start:end]))
        e = r_e[k]
        tc, t_land, exit_time, tau = r_f[k]
        tr = trs[e]
        q = q_rows[k]
        strips.append(Strip(mode, tr.name, tc, exit_time, q, t_land, tau))
        records.append(TransitionRecord(tr.name, mode, mode, e, tc, t_land, exit_time, q, after_rows[k], tau))
        start = end


def _commit_records(integrator, data, buf, ws: _Workspace, n_rec: int):
    """Turn the transitions the kernel crossed into Execution pieces (what ``_transition`` and
    the next visit's ``SegmentBuffer`` would have built), and move the current segment into a
    fresh buffer. Returns that buffer."""
    mode = data.name
    T, X, DX = buf.t, buf.x, buf.dx
    # One copy of the records, shared by the pieces as views.
    r_e = ws.r_e[:n_rec].tolist()
    r_f = ws.r_f[:n_rec].tolist()
    qs = ws.r_q[:n_rec].copy()
    afters = ws.r_after[:n_rec].copy()
    ends = ws.seg_end[:n_rec].tolist()
    segments, strips, records = integrator.segments, integrator.strips, integrator.transitions
    # Thousands of small acyclic objects at once: the cyclic collector would scan the whole
    # growing execution again and again while they are made (it doubled the time per transition
    # at 2e4 transitions), and could free none of them.
    gc_was_enabled = gc.isenabled()
    gc.disable()
    try:
        _build_pieces(mode, data.transitions, T, X, DX, r_e, r_f, qs, afters, ends, segments, strips, records)
    finally:
        if gc_was_enabled:
            gc.enable()
    strip_time = integrator.strip_time
    for tc, _, exit_time, _ in r_f:  # summed in the order the Python path sums them
        strip_time += exit_time - tc
    integrator.strip_time = strip_time
    start = ends[-1]
    size = buf.size
    # As large as the old buffer: the steps to come will need it again.
    fresh = SegmentBuffer(mode, X.shape[1], capacity=max(len(T), 2 * (size - start)))
    m = size - start
    fresh.t[:m] = T[start:size]
    fresh.x[:m] = X[start:size]
    fresh.dx[:m] = DX[start:size]
    fresh.size = m
    return fresh


def run_mode_compiled(integrator, data, buf, t: float, x: np.ndarray, k0: np.ndarray, t_final: float):
    """The step loop of one mode visit, compiled; returns what ``_Integrator._run_mode`` returns:
    ``("next", mode, x, t)`` after a transition or ``("end", status, message, t, in_strip, pair)``.
    With in-kernel transitions one call covers many visits of the same mode."""
    in_kernel = _check_twin(integrator, data, t, x, k0)
    cm = data.mode.compiled
    kernel = get_kernel(cm)
    plan = plan_for(integrator.tableau)
    mode = data.name
    n = data.mode.dim
    spaces = integrator.__dict__.setdefault("_compiled_spaces", {})
    ws = spaces.get(mode)
    if ws is None:
        ws = spaces[mode] = _Workspace(n, plan.stages, cm.n_guards)
    x = np.array(x, dtype=float)
    ws.K[0] = k0
    fs, iv, cf, ci = ws.fs, ws.iv, ws.cf, ws.ci
    fs[0] = t
    fs[1] = integrator.h_prop
    progress = integrator.progress
    cf[:] = (t_final, integrator.h, integrator.eps, integrator.rtol, integrator.atol,
             integrator.err_exponent if integrator.adaptive else 0.0)
    ci[:5] = (integrator.adaptive, integrator.aim, integrator.max_halvings,
              PROGRESS_CHUNK if progress is not None else _NO_LIMIT, in_kernel)
    ci[6] = next((i for i, tab in enumerate(_BUILTIN) if tab is integrator.tableau), -1)
    while True:
        ci[5] = max(0, integrator.max_transitions - len(integrator.transitions))
        iv[5] = buf.size
        code = kernel(cm.params, cm.n_guards, plan.c, plan.n_groups, plan.weights, plan.n_members, plan.members,
                      plan.b_err, plan.fsal, x, ws.K, ws.XS, ws.x_new, ws.k1, ws.gv, ws.work, ws.q, ws.dq,
                      buf.t, buf.x, buf.dx, fs, iv, cf, ci, ws.r_e, ws.r_f, ws.r_q, ws.r_after, ws.seg_end)
        buf.size = int(iv[5])
        integrator._flush(int(iv[0]), int(iv[1]), int(iv[2]), int(iv[3]), int(iv[4]), float(fs[1]))
        integrator.reset_evals += int(iv[8])
        n_rec = int(iv[9])
        if n_rec:
            buf = _commit_records(integrator, data, buf, ws, n_rec)
        t = float(fs[0])
        if code == BUFFER_FULL:
            _grow(buf)
            continue
        if code == RECORDS_FULL:
            continue
        if code == CHUNK:
            now = _time.perf_counter()
            if now - integrator._last_report > 0.2:
                integrator._last_report = now
                progress(t, integrator.t_start, t_final)
            continue
        break
    if code == TRANSITION:
        return integrator._transition(buf, data, int(iv[6]), float(fs[6]), ws.q.copy(), float(fs[2]),
                                      float(fs[7]), t_final)
    if code == NEXT:
        # The state entering the mode again needs the entry's special cases (in a strip, or a
        # non-finite field or guard): Python's _run_mode takes it from here. The segment before
        # it was committed with its transition; nothing of the next one is stored yet.
        return ("next", mode, x.copy(), t)
    if code == FINISHED:
        return integrator._end_segment(buf, "finished", "", float(fs[4]))
    if code == GUARD_NAN:
        bad = int(iv[6])
        message = (f"guard of transition {data.transitions[bad].name} is nan at t={float(fs[5]):.17g} in mode "
                   f"'{mode}', x={ws.x_new.tolist()}")
        return integrator._end_segment(buf, "non_finite", message, t)
    if code == NONFINITE_STEP:
        message = (f"the step from t={t:.17g} in mode '{mode}' gives a non-finite state even at "
                   f"h={float(fs[3]):.3g}: x={x.tolist()}")
        return integrator._end_segment(buf, "non_finite", message, t)
    if code == EXHAUSTED:
        e = int(iv[6])
        message = (f"no step from t={t:.17g} in mode '{mode}' lands in the relaxed domain after {int(iv[7])} "
                   f"halvings: the flow leaves through the guard of transition {data.transitions[e].name} "
                   f"without entering its strip (x={x.tolist()})")
        return integrator._end_segment(buf, "halving_exhausted", message, t)
    raise RuntimeError(f"compiled kernel returned unknown code {code}")  # pragma: no cover


def without_compiled(system):
    """The same system with its modes' compiled twins removed, so ``simulate`` runs the Python
    step loop (for comparisons of the two paths). Eagerly built systems only."""
    import dataclasses

    from .hybrid import HybridSystem

    modes = {name: dataclasses.replace(mode, compiled=None) for name, mode in system.modes.items()}
    return HybridSystem(modes, system.transitions, name=system.name, energy=system.energy)
