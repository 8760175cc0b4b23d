"""The relaxed integrator's decision rules, written once.

Plain functions of numbers (and, for the error norm, of sequences indexed by position) that the
Python step loop calls and that the compiled kernel compiles with numba from this same source
(``legsim.compiled`` copies this module's functions and constants into each kernel it
generates). A rule changed here changes both paths; the parity tests check that they agree to
the bit.

Units: times and step sizes in s, guard values in the guard's units (the strip width eps is in
the same units), step fractions s in [0, 1].
"""

from __future__ import annotations

import math

# -- step-size control (Hairer, Norsett and Wanner I, Sec. II.4; the names scipy's RK uses) ------
#: Safety factor on the step the error estimate asks for.
SAFETY = 0.9
#: Least factor by which one step may shrink the next.
MIN_FACTOR = 0.2
#: Most factor by which one accepted step may grow the next.
MAX_FACTOR = 5.0


def rejected_step(hk: float, err: float, exponent: float) -> float:
    """The retry after a step of size hk failed the error test (err > 1)."""
    return hk * max(MIN_FACTOR, SAFETY * err**exponent)


def proposed_step(hk: float, err: float, exponent: float, rejected: bool) -> float:
    """The next step after a step of size hk passed the error test with norm err; no growth
    right after a rejection (Hairer's codes and scipy alike)."""
    proposal = hk * min(MAX_FACTOR, max(MIN_FACTOR, SAFETY * err**exponent)) if err > 0.0 else MAX_FACTOR * hk
    if rejected and proposal > hk:
        proposal = hk
    return proposal


def kept_proposal(h_prop: float, proposal: float, shortened: bool, rejected: bool) -> float:
    """The proposal carried to the next step. A step shortened only to land in the relaxed
    domain says nothing about the step the error allows: its tiny error must not shrink the next
    proposal (after a landing the next mode would restart near eps and creep back up)."""
    if shortened and not rejected:
        return max(h_prop, proposal)
    return proposal


def fixed_proposal(h_prop: float, h: float, hk: float, shortened: bool, landed: bool) -> float:
    """Under fixed steps h, the first trial of the next step. After a step shortened (to hk) and
    still short of every strip, hk: the flow is nearing a guard faster than its strip allows, and
    a next trial of h would repeat the halvings that hk took (each approach step one more). After
    a step that was not shortened, twice the proposal, up to h; after a landing in a strip, h.
    Every step stays at most h, the step the method's bounds are stated in."""
    if landed:
        return h
    if shortened:
        return hk
    return min(2.0 * h_prop, h)


def restarted_step(h_prop: float, start: float) -> float:
    """The proposal carried into a newly entered mode: the smaller of the one carried and the
    new flow's starting step (``starting_step``)."""
    return min(h_prop, start)


# -- a new flow's starting step (Hairer, Norsett and Wanner I, Sec. II.4) ------------------------
def scaled_rms(values, reference, rtol: float, atol: float) -> float:
    """RMS of values[d] / (atol + rtol |reference[d]|), summed in index order (sequences of
    equal length n), as both loops sum it."""
    total = 0.0
    for d in range(len(values)):
        r = values[d] / (atol + rtol * abs(reference[d]))
        total += r * r
    return math.sqrt(total / len(values))


def starting_guess(d0: float, d1: float, h_max: float) -> float:
    """The first trial h0 (s) of the starting-step estimate from the scaled norms of x (d0) and
    of f(t, x) (d1, 1/s), capped by h_max."""
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    return min(h0, h_max)


def starting_step(h0: float, d1: float, d2: float, exponent: float) -> float:
    """The starting step (s): local error about 1% of the tolerance, from d1 and the scaled
    rate of change of f over h0 (d2, 1/s^2); ``exponent`` is the controller's, -1/(order + 1)."""
    worst = max(d1, d2)
    h1 = max(1e-6, 1e-3 * h0) if worst <= 1e-15 else (0.01 / worst) ** -exponent
    return min(100.0 * h0, h1)


# -- the step's length ------------------------------------------------------------------------
#: The float64 spacing at 1 (machine epsilon), written out: the rules compile without numpy.
FLOAT_SPACING = 2.220446049250313e-16
#: Finished once t_final is this many float spacings away (relative to |t_final|): an absolute
#: test, since a relative one would call a run near t = 1e15 finished before its first step.
FINISH_SPACINGS = 8.0


def finish_tolerance(t_final: float) -> float:
    """How close to t_final (s) a run counts as finished."""
    return FINISH_SPACINGS * FLOAT_SPACING * abs(t_final)


def trial_length(h_prop: float, h_max: float, remaining: float) -> float:
    """The first trial step from the proposal, capped by h and by what remains to t_final."""
    hk = h_prop if h_prop < h_max else h_max
    return remaining if hk >= remaining else hk


#: A trial step that still leaves the model's range (ModelBreakdown) once shortened below
#: 1 / 2**BREAKDOWN_HALVINGS of its step's reference length ends the run: a long trial step
#: through the ground needs a few halvings; a step that short still through it means the
#: boundary is at hand.
BREAKDOWN_HALVINGS = 10


def shortening_exhausted(shortened: int, max_halvings: int, t: float, hk: float, reference: float, broke: bool) -> bool:
    """True when a step shortened ``shortened`` times, now to hk, may not be shortened again: the
    budget is spent, t + hk no longer moves, or its last trial (``broke``) left the model's
    range at a length below reference / 2**BREAKDOWN_HALVINGS. The reference is h under fixed
    steps, whose first trial may start shorter (``fixed_proposal``), and the step's first trial
    under error control."""
    return shortened > max_halvings or t + hk <= t or (broke and hk < reference * 0.5**BREAKDOWN_HALVINGS)


#: Float spacings within which a trial step is no step: its length relative to t, its end
#: relative to its start's largest entry. A guard past its strip over such a step has jumped,
#: since a continuous one moves by less than eps there.
ROUNDING_SPACINGS = 8.0


def within_rounding(t: float, hk: float, x0, x1, n: int) -> bool:
    """Whether the trial step of length hk from (t, x0[:n]) to x1[:n] moves t and x by
    rounding only: hk within ``ROUNDING_SPACINGS`` float spacings of t, and every entry of x1
    within as many spacings of the largest entry of either state."""
    spacing = ROUNDING_SPACINGS * FLOAT_SPACING
    if hk > spacing * abs(t):
        return False
    largest, difference = 0.0, 0.0
    for d in range(n):
        largest = max(largest, abs(x0[d]), abs(x1[d]))
        difference = max(difference, abs(x1[d] - x0[d]))
    return difference <= spacing * largest


#: Aimed retries of one step before falling back to halving.
MAX_AIMS = 3


def aimed_step(hk: float, s: float, converged: bool) -> float:
    """The retry aimed at the strip's middle, found at fraction s of the failed step hk; half
    the step when the search failed or fell outside the step."""
    if not converged or not (0.0 < s < 1.0):
        return 0.5 * hk
    return s * hk


# -- where a step's interpolant meets a guard -------------------------------------------------
# A bracketed search for the root of g(s) on [0, 1], g(0) = g0 >= 0 > g1 = g(1): Illinois regula
# falsi safeguarded as in Brent's method. The caller drives it, so that the Python loop (guard
# callables) and the kernel (compiled guards) run the same iterates:
#
#     state = crossing_start(g0, g1, tol)
#     while state[STATUS] == SEARCHING:
#         s = crossing_point(state)
#         state = crossing_update(state, s, g(s))
#     s, converged = state[RESULT], state[STATUS] == CONVERGED
#
# The point returned is the end of the final bracket *past* the guard (-tol <= g <= 0): a strip
# point on the domain side, however close, would put the reset image past a complementary guard
# (leave through x = 1, come back through x = 1) and make the next mode cross again at once.
# When the guard is discontinuous along the interpolant (no root in the bracket), the domain-side
# end is returned, not converged: it is never past the guard.

#: Positions in the search state (a tuple of floats).
LO, HI, G_LO, G_HI, G_HI_TRUE, SIDE, WIDTH, STALLED, TOL, ITERATION, STATUS, RESULT = range(12)
SEARCHING = 0.0
CONVERGED = 1.0
NOT_CONVERGED = 2.0
#: Iterates without the bracket halving before the search bisects (so that a kink or a jump
#: cannot stall Illinois' steps).
STALL = 3.0
#: Closest an iterate comes to an end of its bracket (step fractions): a few float spacings at 1,
#: so that an end already at the root, to rounding, is straddled at once instead of approached
#: from one side forever.
MIN_STEP = 4e-16
#: Bracket width at which the search stops.
COLLAPSED = 4e-16
#: Most guard evaluations of one search.
MAX_ITERATIONS = 200.0
#: The guard's own rounding, relative to its change over the step: a finer tolerance would only
#: be met by collapsing the bracket by bisection. A guard is a difference of terms larger than
#: its change over one step (a foot's height: link lengths times cosines, of order 1 m, changing
#: by 0.1 m), so its rounding is a few float spacings of those terms: about 1e-15 m, 1e-14 of
#: the change. Below that the search only chases rounding noise, at 4-6 extra evaluations.
GUARD_ROUNDING = 1e-13


def crossing_start(g0: float, g1: float, tol: float):
    """The search state for a guard going from g0 >= 0 (s = 0) to g1 < 0 (s = 1), to be located
    within ``tol`` guard units (raised to the guard's own rounding)."""
    if g0 <= 0.0:
        return (0.0, 1.0, g0, g1, g1, 0.0, 1.0, 0.0, tol, 0.0, CONVERGED, 0.0)
    floor = GUARD_ROUNDING * (g0 - g1)
    if floor > tol:
        tol = floor
    status = CONVERGED if -g1 <= tol else SEARCHING
    return (0.0, 1.0, g0, g1, g1, 0.0, 1.0, 0.0, tol, 0.0, status, 1.0)


def crossing_point(state) -> float:
    """The next step fraction at which to evaluate the guard."""
    lo = state[LO]
    hi = state[HI]
    if state[STALLED] >= STALL:
        s = 0.5 * (lo + hi)
    else:
        s = lo + (hi - lo) * state[G_LO] / (state[G_LO] - state[G_HI])
        if not (lo < s < hi):
            s = 0.5 * (lo + hi)
    if hi - lo > 2.0 * MIN_STEP:
        if s - lo < MIN_STEP:
            s = lo + MIN_STEP
        elif hi - s < MIN_STEP:
            s = hi - MIN_STEP
    return s


def crossing_update(state, s: float, g: float):
    """The search state after the guard took the value g at fraction s."""
    lo, hi, glo, ghi, g_hi, side, width, stalled, tol, it, _, _ = state
    it += 1.0
    if not math.isfinite(g):
        return (lo, hi, glo, ghi, g_hi, side, width, stalled, tol, it, NOT_CONVERGED, lo)
    if g == 0.0:
        return (lo, hi, glo, ghi, g_hi, side, width, stalled, tol, it, CONVERGED, s)
    if g > 0.0:
        lo = s
        glo = g
        if side == 1.0:
            ghi *= 0.5
        side = 1.0
    else:
        hi = s
        ghi = g
        g_hi = g
        if -g <= tol:
            return (lo, hi, glo, ghi, g_hi, side, width, stalled, tol, it, CONVERGED, hi)
        if side == -1.0:
            glo *= 0.5
        side = -1.0
    if hi - lo <= 0.5 * width:
        width = hi - lo
        stalled = 0.0
    else:
        stalled += 1.0
    status = SEARCHING
    result = 0.0
    if hi - lo <= COLLAPSED or it >= MAX_ITERATIONS:
        # A collapsed bracket is a root up to rounding unless the guard jumps there by more than
        # a millionth of what the caller tolerates as a strip (tol is a millionth of that again).
        if hi - lo <= COLLAPSED and -g_hi <= 1e6 * tol:
            status, result = CONVERGED, hi
        else:
            status, result = NOT_CONVERGED, lo
    return (lo, hi, glo, ghi, g_hi, side, width, stalled, tol, it, status, result)


# -- accumulating transitions ------------------------------------------------------------------
def accumulating(previous_flight: float, flight: float, window: float) -> bool:
    """True when the crossings of a transition accumulate (a Zeno point ahead): the flight (s)
    since its previous crossing is shorter than the window and than the flight before it."""
    return flight <= window and flight < previous_flight


def flight_since(has_history: bool, last_exit: float, tc: float) -> float:
    """The flight (s) of a transition crossed at tc since its previous crossing left its strip
    at ``last_exit``; infinite for its first crossing (or the first after a continuation)."""
    return tc - last_exit if has_history else math.inf


# -- the strip -----------------------------------------------------------------------------------
#: A guard within this share of eps below zero at a mode's entry counts as *on* the guard, not
#: past it: the first step decides (a constrained mode released onto the guard it lives on, an
#: identity reset between complementary guards). If the flow leaves, that step lands in the strip
#: and the crossing is found at its start; if it goes inward, no spurious transition happens.
ON_GUARD = 1e-9
#: ... and never less than a guard's rounding (guard units): a foot's height at its liftoff is 0
#: to about 1e-14 m, which a strip of eps = 1e-10 m would otherwise take as a strike at once (a
#: graze decided by rounding, and a return map that jumps with it).
ON_GUARD_FLOOR = 1e-12


def on_guard_depth(eps: float) -> float:
    """How far past its guard (guard units) a state entering a mode still counts as on it."""
    return max(ON_GUARD * eps, ON_GUARD_FLOOR)


def entered_in_strip(gmin: float, eps: float) -> bool:
    """True when a state entering a mode with least guard value gmin must cross at once."""
    return gmin < -on_guard_depth(eps)


def past_strip(g: float, eps: float) -> bool:
    """True when a state entering a mode lies past a guard by more than the strip (its run then
    ends: the reset left the relaxed domain)."""
    return g < -eps


def strip_exit_time(t_land: float, eps: float, tau: float) -> float:
    """When the held state leaves the strip (paper 000 Fig. 12, step 12): the landing step
    ended at depth tau inside it, and the strip coordinate grows at unit rate to eps. A guard
    that jumped past its strip (tau > eps) is left at once."""
    return t_land + max(eps - tau, 0.0)


def crossing_on_step(guard_at, g0: float, g1: float, tol: float):
    """Where ``guard_at(s)`` (g0 at s = 0, g1 < 0 at s = 1) crosses zero, by the search above:
    (s, guard evaluations, converged). For tools that search along their own curves; the loop
    drives the search itself (``curve.crossing_on_landing``)."""
    state = crossing_start(g0, g1, tol)
    evals = 0
    while state[STATUS] == SEARCHING:
        s = crossing_point(state)
        state = crossing_update(state, s, float(guard_at(s)))
        evals += 1
    return state[RESULT], evals, state[STATUS] == CONVERGED
