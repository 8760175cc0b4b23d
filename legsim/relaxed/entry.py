"""Entering a mode (at the start of a run or at a strip's exit).

* The field and guards are evaluated on the entering state; a non-finite value ends the run.
* A state that enters a mode already inside one of its strips (a reset image at a guard
  intersection, or an initial state in a strip) crosses that strip at once, with q = x; one past
  a guard by more than eps ends the run (``reset_outside_domain``).
* With error control the new mode restarts at the standard starting step, and with dense landing
  a mode entered a hair before another guard's strip (the second foot of a symmetric touchdown)
  takes one short step to that strip instead of a full step (``short_first_step``).
"""

from __future__ import annotations

import math

import numpy as np

from ..control import Bound
from ..execution import Status
from ..hybrid import check_field_output
from . import messages
from .outcomes import Ended, Landing, Outcome
from .rules import entered_in_strip, past_strip
from .run import ModeVisit, Run
from .step_size import rms
from .strip import cross, cross_landing


def enter_mode(run: Run, mode: str, x: np.ndarray, t: float) -> ModeVisit | Outcome:
    """The visit of ``mode`` from (t, x), ready to step; or the outcome when the entering state
    crosses a strip at once or ends the run."""
    data = run.system.mode_data(mode)
    if isinstance(run.control, Bound):
        run.control.enter(mode, t, x)
    visit = ModeVisit(data, run.guard_fns(data), t, x)
    run.note_mode(data)
    if mode not in run.checked_modes:
        control = run.control
        check_field_output(run.system.name, mode, data.mode, t, x, None if control is None else control(t, x))
        run.checked_modes.add(mode)
    k0 = run.f(visit.field, t, x)
    if not np.all(np.isfinite(k0)):
        visit.buf.append(t, x, np.zeros_like(x))
        return run.end_visit(visit, Ended(Status.NON_FINITE, messages.non_finite_field(mode, t, x, k0), t))
    visit.k0 = k0
    visit.buf.append(t, x, k0)
    gvals = visit.guard_values(t, x)
    run.guard_evals += len(gvals)
    bad = messages.first_nonfinite(gvals)
    if bad is not None:
        message = messages.non_finite_guard(mode, t, x, data.transitions[bad].name, gvals[bad])
        return run.end_visit(visit, Ended(Status.NON_FINITE, message, t))
    if gvals and entered_in_strip(min(gvals), run.eps):
        return _cross_at_once(run, visit, gvals)
    visit.g_entry = gvals
    if run.step_size.adaptive and run.transitions and run.transitions[-1].source != mode:
        # Not after a self-transition: the same field (the compiled kernel crosses those in place).
        run.step_size.restart(lambda t1, x1: run.f(visit.field, t1, x1), t, x, k0)
        if run.landing.lands_on_extension and gvals:
            crossed = short_first_step(run, visit)
            if crossed is not None:
                return crossed
    return visit


def _cross_at_once(run: Run, visit: ModeVisit, gvals: list[float]) -> Outcome:
    e = min(range(len(gvals)), key=gvals.__getitem__)
    t, x = visit.t, visit.x
    if past_strip(gvals[e], run.eps):
        message = (
            f"state entering mode '{visit.name}' at t={t:.17g} lies past the guard of transition "
            f"{visit.data.transitions[e].name} by {-gvals[e]:.3g} > eps={run.eps:g}: x={x.tolist()}"
        )
        return run.end_visit(visit, Ended(Status.RESET_OUTSIDE_DOMAIN, message, t))
    return cross(run, visit, e, t, x, t, -gvals[e])


#: A simultaneous event: a guard's strip is reached within this share of the next step.
SIMULTANEOUS = 1e-3


def short_first_step(run: Run, visit: ModeVisit) -> Outcome | None:
    """The first step of a newly entered mode when the flow reaches the middle of some guard's
    strip within ``SIMULTANEOUS`` of the step it would take (a simultaneous event): a step of
    exactly that length by Heun's method, whose Euler estimate must pass the error test (its
    local error is O(tau^3), tau ~ eps / speed). It is an ordinary relaxed step: accepted only if
    it lands in the relaxed domain, the crossing then found on its own quadratic interpolant. One
    field evaluation instead of a full step of the pair (12 for DOP853, and the same for the
    mode's neighbours in the initial state, so the execution stays continuous in it). Returns the
    transition's outcome, or None to step as usual."""
    tau = _time_to_simultaneous_strip(run, visit)
    t, x, k0, step_size = visit.t, visit.x, visit.k0, run.step_size
    if tau is None or not t + tau > t or t + tau >= run.t_final:
        return None  # (a strip reached only after t_final is for the ordinary last step)
    try:
        k1 = run.f(visit.field, t + tau, x + tau * k0)
        x1 = x + (0.5 * tau) * (k0 + k1)
        scale = step_size.atol + step_size.rtol * np.maximum(np.abs(x), np.abs(x1))
        if not rms((0.5 * tau) * (k1 - k0) / scale) <= 1.0:
            return None
        g1 = visit.guard_values(t + tau, x1)
    except Exception:  # the ordinary first step will meet it and report it properly
        return None
    run.guard_evals += len(g1)
    if not (all(map(math.isfinite, g1)) and -run.eps <= min(g1) < 0.0 and all(map(math.isfinite, x1.tolist()))):
        return None
    run.steps += 1
    return cross_landing(
        run,
        visit,
        Landing(
            t,
            x,
            k0,
            t + tau,
            x1,
            g1,
            lambda s: x + tau * (s * k0 + (0.5 * s * s) * (k1 - k0)),
            lambda s: k0 + s * (k1 - k0),
        ),
    )


def _time_to_simultaneous_strip(run: Run, visit: ModeVisit) -> float | None:
    """The time for the flow to reach the middle of the nearest strip of a guard that is within
    eps ahead and closing (guards leading straight back to the mode just left are not
    considered: a shallow graze must be stepped over, not crossed back and forth); None when
    none is reached within SIMULTANEOUS of the next step."""
    eps, t, x, k0 = run.eps, visit.t, visit.x, visit.k0
    h_next = min(run.step_size.h_prop, run.step_size.h_max)
    came_from = run.transitions[-1].source
    speed = float(np.sqrt(np.dot(k0, k0)))
    if not (math.isfinite(speed) and speed > 0.0):
        return None
    dt = 1e-7 / max(1.0, speed)
    tau = None
    for e, g in enumerate(visit.g_here):
        if visit.data.targets[e] == came_from or not 0.0 <= g <= eps:
            continue
        try:
            g_ahead = float(visit.guards[e](t + dt, x + dt * k0))
        except Exception:  # the ordinary first step will meet it and report it properly
            continue
        run.guard_evals += 1
        rate = (g_ahead - g) / dt
        if not rate < 0.0:
            continue
        reach = (g + 0.5 * eps) / -rate
        if reach <= SIMULTANEOUS * h_next and (tau is None or reach < tau):
            tau = reach
    return tau
