"""Crossing a strip (paper 000 Fig. 12, steps 10-14): a step that lands in a strip has its
crossing point q located on the step's own interpolant; the state is held at q for the rest of
the strip, eps - tau, and the reset is applied to q, not to the overshot landing point.

Bringing the state back along the flow keeps conserved quantities to the interpolant's accuracy,
whereas projecting the landing point along the guard's gradient would change a runner's energy
by O(tau) at every touchdown; resetting the overshot point instead would sink the state deeper at
every transition and stall a Zeno run in a stream of near-zero-time transitions. When a step
lands in several strips at once (simultaneous guards), the transition whose crossing comes first
on the interpolant is taken; the next mode then sees its own guard already crossed.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..errors import ModelBreakdown, ModelError
from ..execution import SegmentBuffer, Status, Strip, TransitionRecord
from ..hybrid import Continuation, check_reset_output
from .outcomes import Ended, Entered, Landing, Outcome
from .rules import (
    CONVERGED,
    RESULT,
    SEARCHING,
    STATUS,
    crossing_point,
    crossing_start,
    crossing_update,
    entered_in_strip,
    hermite_slope_weights,
    hermite_weights,
    strip_exit_time,
)
from .run import PROGRESS_STEPS, GuardAt, ModeVisit, Run
from .simultaneous import joint_crossing, joint_name

#: q is located to this share of the strip: it costs guard evaluations only.
CROSSING_TOL = 1e-12


def crossing_on_step(guard_at: Callable[[float], float], g0: float, g1: float, tol: float) -> tuple[float, int, bool]:
    """Where a step's interpolant meets a guard: (s, guard evaluations, converged), with
    ``guard_at(s)`` the guard at step fraction s, g0 = guard_at(0) >= 0 > g1 = guard_at(1).
    The search and the point it returns are ``rules.crossing_*``'s."""
    state = crossing_start(g0, g1, tol)
    evals = 0
    while state[STATUS] == SEARCHING:
        s = crossing_point(state)
        g = float(guard_at(s))
        evals += 1
        state = crossing_update(state, s, g)
    return state[RESULT], evals, state[STATUS] == CONVERGED


def hermite(x0: np.ndarray, d0: np.ndarray, x1: np.ndarray, d1: np.ndarray, dt: float, s: float) -> np.ndarray:
    """The cubic Hermite interpolant of a step of length dt (ends x0, x1, slopes d0, d1) at fraction s."""
    w0, w1, w2, w3 = hermite_weights(s, dt)
    return w0 * x0 + w1 * d0 + w2 * x1 + w3 * d1


def hermite_slope(x0: np.ndarray, d0: np.ndarray, x1: np.ndarray, d1: np.ndarray, dt: float, s: float) -> np.ndarray:
    """d/dt of ``hermite`` at fraction s."""
    v0, v1, v2, v3 = hermite_slope_weights(s)
    return v0 * x0 / dt + v1 * d0 + v2 * x1 / dt + v3 * d1


def hermite_landing(
    t: float, x: np.ndarray, k0: np.ndarray, t1: float, x1: np.ndarray, k1: np.ndarray, gvals: list[float]
) -> Landing:
    """A step landed in a strip, with the cubic Hermite interpolant of its ends as its curve."""
    dt = t1 - t
    return Landing(
        t, x, k0, t1, x1, gvals, lambda s: hermite(x, k0, x1, k1, dt, s), lambda s: hermite_slope(x, k0, x1, k1, dt, s)
    )


def locate(run: Run, visit: ModeVisit, landing: Landing) -> tuple[int, float, bool]:
    """(guard index, fraction s of q, converged): the earliest crossing on the step's
    interpolant among the guards the step ended past."""
    if landing.crossing is not None:
        return landing.crossing
    tol = CROSSING_TOL * run.eps
    t, dt, point = landing.t, landing.t1 - landing.t, landing.point
    best = None
    for e, g1 in enumerate(landing.gvals):
        if g1 < 0.0:
            guard = visit.guards[e]
            g0 = float(guard(t, landing.x))

            def on_step(s: float, guard: GuardAt = guard) -> float:
                return guard(t + s * dt, point(s))

            s, evals, converged = crossing_on_step(on_step, g0, g1, tol)
            run.guard_evals += 1 + evals
            if best is None or s < best[1]:
                best = (e, s, converged)
    assert best is not None, "a landing crosses at least one guard"
    return best


def cross_landing(run: Run, visit: ModeVisit, landing: Landing) -> Outcome:
    """The step of ``landing`` ended in one or more strips: store q, then cross the strip."""
    e, s, _ = locate(run, visit, landing)
    t, x = landing.t, landing.x
    q, tc = x.copy(), t
    if s > 0.0:
        candidate = landing.point(s)
        tc = t + s * (landing.t1 - t)
        if not np.all(np.isfinite(candidate)):
            tc = t
        elif tc <= t:
            # s so small that t + s dt rounds to t: q replaces the step's start (they differ by
            # rounding) rather than adding a second point at the same time.
            q = candidate
            visit.buf.x[visit.buf.size - 1] = q
            visit.buf.dx[visit.buf.size - 1] = landing.slope(s)
            tc = t
        else:
            q = candidate
            visit.buf.append(tc, q, landing.slope(s))
    crossed = [e] + [f for f, g in enumerate(landing.gvals) if g < 0.0 and f != e]
    return cross(run, visit, e, tc, q, landing.t1, -landing.gvals[e], crossed)


def cross(
    run: Run,
    visit: ModeVisit,
    e: int,
    tc: float,
    q: np.ndarray,
    t_land: float,
    tau: float,
    crossed: list[int] | None = None,
) -> Outcome:
    """Cross the strip of transition e entered at time tc at the guard point q by a step that
    landed at t_land, depth tau: hold q until t_land + eps - tau, then reset. With ``crossed``,
    the transitions whose guards the landing step crossed (e first): resolved together by the
    model's joint function when it has one (``simultaneous``). A transition whose crossings
    accumulate takes its continuation (``zeno``)."""
    data = visit.data
    tr = data.transitions[e]
    run.segments.append(visit.buf.freeze())
    if len(run.transitions) >= run.max_transitions:
        run.strips.append(Strip(visit.name, tr.name, tc, tc, q.copy(), t_land, tau))
        return Ended(
            Status.MAX_TRANSITIONS,
            f"transition budget max_transitions={run.max_transitions} used up at t={tc:.17g} "
            f"(next transition {tr.name} from mode '{visit.name}')",
            tc,
            True,
        )
    exit_time = strip_exit_time(t_land, run.eps, tau)
    if exit_time >= run.t_final:
        run.strips.append(Strip(visit.name, tr.name, tc, run.t_final, q.copy(), t_land, tau))
        run.strip_time += run.t_final - tc
        return Ended(Status.FINISHED, "", run.t_final, True)
    if crossed is not None and len(crossed) > 1:
        outcome = _cross_jointly(run, visit, crossed, tc, q, t_land, tau, exit_time)
        if outcome is not None:
            return outcome
        run.order.check(data, crossed, q, tc)
    accumulates = run.zeno.crossing(visit.name, tr.name, tc)
    continuation = data.continuations[e] if accumulates and run.zeno.continues else None
    if continuation is not None:
        image = _continued_image(run, visit, e, continuation, tc, q, exit_time)
        if image is not None:
            outcome = record_crossing(
                run, visit.name, e, continuation.name, continuation.target, tc, q, t_land, tau, exit_time, image
            )
            run.zeno.crossed(run, visit.name, tr.name, tc, exit_time, True, True)
            return outcome
    x_after = _reset(run, visit, e, tc, q)
    if isinstance(x_after, Ended):
        return x_after
    outcome = record_crossing(run, visit.name, e, tr.name, data.targets[e], tc, q, t_land, tau, exit_time, x_after)
    run.zeno.crossed(run, visit.name, tr.name, tc, exit_time, accumulates, False, tr.continuation is not None)
    return outcome


def _cross_jointly(
    run: Run,
    visit: ModeVisit,
    crossed: list[int],
    tc: float,
    q: np.ndarray,
    t_land: float,
    tau: float,
    exit_time: float,
) -> Outcome | None:
    """The model's joint resolution of the transitions ``crossed`` together (their continuation,
    every striker plastic, when these joint crossings accumulate), recorded; None when the model
    has none."""
    key = joint_name(visit.data, crossed)
    accumulates = run.zeno.crossing(visit.name, key, tc)
    rest = accumulates and run.zeno.continues
    joint = joint_crossing(run.system, visit.data, crossed, q, rest)
    if joint is None:
        return None
    run.reset_evals += 1
    image = np.asarray(joint.state, dtype=float)
    target_dim = run.system.mode(joint.target).dim
    if image.shape != (target_dim,):
        raise ModelError(
            f"{run.system.name}: joint crossing {joint.name} returned shape {image.shape}, expected "
            f"({target_dim},) for mode '{joint.target}'"
        )
    outcome = record_crossing(
        run, visit.name, crossed[0], joint.name, joint.target, tc, q, t_land, tau, exit_time, image
    )
    run.zeno.crossed(run, visit.name, key, tc, exit_time, accumulates, rest)
    return outcome


def _reset(run: Run, visit: ModeVisit, e: int, tc: float, q: np.ndarray) -> np.ndarray | Ended:
    """R_e(q), checked against the target's dimension; a reset leaving the model's range ends
    the run here (the segment is already stored)."""
    data = visit.data
    tr = data.transitions[e]
    run.reset_evals += 1
    try:
        x_after = np.asarray(data.resets[e](q), dtype=float)
    except ModelBreakdown as exc:
        return Ended(
            Status.MODEL_BREAKDOWN, f"{exc} (reset of transition {tr.name} from mode '{visit.name}', t={tc:.17g})", tc
        )
    except Exception as exc:
        raise ModelError(
            f"{run.system.name}: reset of transition {tr.name} failed at t={tc:.17g}, "
            f"q={q.tolist()}: {type(exc).__name__}: {exc}"
        ) from exc
    target_dim = run.system.mode(data.targets[e]).dim
    if x_after.shape != (target_dim,):
        check_reset_output(run.system.name, tr, target_dim, q)  # raises with the shapes named
    return x_after


def _continued_image(
    run: Run, visit: ModeVisit, e: int, continuation: Continuation, tc: float, q: np.ndarray, exit_time: float
) -> np.ndarray | None:
    """The continuation's image of q, or None when it does not lie in its target's domain (the
    constraint it enters would pull at once): then the ordinary transition is taken."""
    run.reset_evals += 1
    try:
        image = q.copy() if continuation.reset is None else np.asarray(continuation.reset(q), dtype=float)
    except ModelBreakdown:
        return None
    except Exception as exc:
        raise ModelError(
            f"{run.system.name}: reset of continuation {continuation.name} failed at t={tc:.17g}, "
            f"q={q.tolist()}: {type(exc).__name__}: {exc}"
        ) from exc
    target = run.system.mode_data(continuation.target)
    if image.shape != (target.mode.dim,):
        raise ModelError(
            f"{run.system.name}: reset of continuation {continuation.name} returned shape {image.shape}, "
            f"expected ({target.mode.dim},) for mode '{continuation.target}'"
        )
    gvals = [g(exit_time, image) for g in run.guard_fns(target)]
    run.guard_evals += len(gvals)
    if not np.all(np.isfinite(image)) or (gvals and entered_in_strip(min(gvals), run.eps)):
        return None
    return image


def record_crossing(
    run: Run,
    mode: str,
    e: int,
    name: str,
    target: str,
    tc: float,
    q: np.ndarray,
    t_land: float,
    tau: float,
    exit_time: float,
    x_after: np.ndarray,
) -> Outcome:
    """Store the strip and the transition ``name`` (index e of ``mode``) into ``target``;
    continue there unless the image is not finite."""
    run.strips.append(Strip(mode, name, tc, exit_time, q.copy(), t_land, tau))
    run.strip_time += exit_time - tc
    run.transitions.append(
        TransitionRecord(name, mode, target, e, tc, t_land, exit_time, q.copy(), x_after.copy(), tau)
    )
    if not len(run.transitions) & (PROGRESS_STEPS - 1):  # a Zeno run may cross many strips per step
        run.tick(exit_time)
    if not np.all(np.isfinite(x_after)):
        seg = SegmentBuffer(target, len(x_after), capacity=1)
        seg.append(exit_time, x_after, np.zeros(len(x_after)))
        run.segments.append(seg.freeze())
        return Ended(
            Status.NON_FINITE,
            f"reset of transition {name} at t={exit_time:.17g} gives a non-finite "
            f"state {x_after.tolist()} from q={q.tolist()}",
            exit_time,
        )
    return Entered(target, x_after, exit_time)
