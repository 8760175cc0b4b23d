"""Zeno cases about what follows an accumulation point (``legsim.relaxed.zeno``). A user system
that names no continuation (a ball sliding along a curved floor, written with the core API) keeps
the relaxed semantics, which hold its state in the strip while it should slide on, and the run
must say so; the double pendulum, whose stop names its continuation, must converge past its
accumulations as eps and h shrink, link 1 swinging on.
"""

from __future__ import annotations

import math
from itertools import pairwise

import numpy as np

from ...relaxed import simulate
from ..framework import CaseResult, Check, case
from ..invariants import check_accumulation, execution_checks, first_accumulating_crossing, transition_floor
from ..models import curved_floor_ball, double_pendulum, tangential_speed
from .zeno import pressing_impact_bound

# ---------------------------------------------------------------------------------------------
# a ball on a curved floor, no continuation
# ---------------------------------------------------------------------------------------------

RADIUS, RESTITUTION = 2.0, 0.8  # m, the valley z = x^2 / (2 R)


@case(
    "zeno_curved_floor",
    "zeno",
    "ball sliding in a valley (core API, c = 0.8, no continuation): bounces accumulate while it slides; the run warns",
)
def _curved_floor(result: CaseResult, quick: bool) -> None:
    g, h, eps = 9.81, 1e-3, 1e-4
    T = 3.0 if quick else 6.0
    system = curved_floor_ball(RESTITUTION, RADIUS, g)
    x0 = np.array([1.0, 0.5 + 1.0 / (2.0 * RADIUS), 0.0, 0.0])  # 0.5 m above the floor, at rest
    ex = simulate(system, x0, "fly", T, h, eps, max_transitions=10**6)
    result.main_run(ex)
    # The gap z - x^2/(2R) accelerates at -g - xd^2/R (x'' = 0); |xd| <= sqrt(2 g z0) by energy.
    accel = g + 2.0 * g * float(x0[1]) / RADIUS
    floor = transition_floor(h, eps, accel=accel)
    result.add(
        execution_checks(
            system,
            ex,
            eps,
            energy="dissipative",
            energy_tol=1e-9,
            bound=T / floor + 1,
            bound_why=f"T/{floor:.3g} s, |gap''| <= g + 2 g z0/R = {accel:.3g} m/s^2",
        )
    )
    k = first_accumulating_crossing(ex, "bounce", h + eps)
    t_acc = ex.transitions[k].time if k is not None else math.nan
    result.add(check_accumulation(ex, [("bounce", t_acc, t_acc)]))
    result.add(_estimate_check(ex, k))
    # What the warning is about: past the accumulation the state is held while its own velocity
    # says it slides along the floor.
    w = ex.warnings[0] if ex.warnings else None
    t_from = (w.details["accumulation_time"] if w else T) + 0.1
    xs = np.array(ex.sample(np.linspace(t_from, T, 100)).states)[:, 0]
    speed = tangential_speed(ex.final_state, RADIUS)
    ok = t_from < T and float(np.ptp(xs)) < 1e-3 and speed > 1.0
    result.add(
        Check(
            "held while sliding",
            ok,
            f"x moves by {np.ptp(xs):.2g} m on [{t_from:.4g}, {T:g}] s at a tangential speed of {speed:.3g} m/s",
        )
    )
    result.numbers.update(
        {
            "accumulation_from": t_acc,
            "tangential_speed_m_s": speed,
            "transitions_since": w.details["transitions_since"] if w else 0,
        }
    )
    result.outcome = (
        f"{ex.status}; accumulates from {t_acc:.4g} s, then held ({len(ex.transitions) - (k or 0)} "
        f"transitions) at {speed:.2g} m/s along the floor; warned"
    )


def _estimate_check(ex, k: int | None) -> Check:
    """The warning's accumulation time, extrapolated from the last two flights, is the start's
    strip exit plus the flights the relaxed run still resolves after it (a geometric tail), to
    the 1% the flights' ratio drifts by."""
    w = next((w for w in ex.warnings if w.kind == "accumulation"), None)
    if w is None or k is None:
        return Check("accumulation time estimated", False, "no accumulation warning")
    trs = ex.transitions
    to_come = sum(b.time - a.exit_time for a, b in pairwise(trs[k:]))
    estimate = w.details["accumulation_time"] - trs[k].exit_time
    ok = abs(estimate - to_come) <= 0.01 * to_come
    return Check(
        "accumulation time estimated",
        ok,
        f"{w.details['accumulation_time']:.9g} s: the start's exit + {estimate:.4g} s; the flights after "
        f"it sum to {to_come:.4g} s",
    )


# ---------------------------------------------------------------------------------------------
# the double pendulum past its accumulations, by default
# ---------------------------------------------------------------------------------------------


@case(
    "zeno_double_pendulum_c0.5_converges",
    "zeno",
    "double pendulum, stop c = 0.5, default continuation, to 6 s: converges as eps and h shrink, link 1 swinging on",
)
def _pendulum_converges(result: CaseResult, quick: bool) -> None:
    c, T = 0.5, 6.0
    model, x0 = double_pendulum(c)
    system = model.system
    levels = [(1e-3, 1e-3), (5e-4, 1e-4), (2.5e-4, 1e-5)] + ([] if quick else [(1.25e-4, 1e-6)])
    finals: list[np.ndarray] = []
    releases, swings = [], []
    last = np.linspace(T - 0.5, T, 101)
    for h, eps in levels:
        ex = simulate(system, x0, "unconstrained", T, h, eps, max_transitions=1000)
        if not finals:
            result.main_run(ex)
            bound, pressing = pressing_impact_bound(system, ex, c, h + eps)
            result.add(
                execution_checks(
                    system,
                    ex,
                    eps,
                    energy="dissipative",
                    energy_tol=1e-7,
                    bound=bound,
                    bound_why=f"pressing impacts per accumulation {pressing} <= log(w1/w_th)/log(1/c) + 2",
                )
            )
        finals.append(ex.final_state)
        releases += [abs(float(tr.state_before[0])) for tr in ex.transitions if tr.name == "release_stop"]
        swings.append(float(np.ptp(np.array(ex.sample(last).states)[:, 0])))
        result.add(
            Check(
                f"warns of nothing (h={h:g}, eps={eps:g})",
                ex.warnings == [],
                f"warnings {[w.kind for w in ex.warnings]}",
            )
        )
    # Each difference between successive levels at most half the previous one: at least linear
    # in h (the default window h + eps about halves from one level to the next).
    diffs = [float(np.max(np.abs(a - b))) for a, b in pairwise(finals)]
    ok = all(b <= 0.5 * a for a, b in pairwise(diffs))
    result.add(Check("final state converges", ok, "max |x_k(6) - x_(k+1)(6)|: " + ", ".join(f"{d:.3g}" for d in diffs)))
    # Released where eq. (31) changes sign, at theta1 = 0 (the straight pendulum, unit masses and
    # lengths), twice at every level; link 1 still swinging at 6 s.
    ok = len(releases) == 2 * len(levels) and max(releases) < 1e-8
    result.add(
        Check(
            "released where eq. (31) changes sign",
            ok,
            f"{len(releases)} releases at |theta1| <= {max(releases, default=math.nan):.2g} rad",
        )
    )
    # Link 1 swings through the last half second (0.4 rad); the paper's relaxed execution holds it
    # in the chattering stop's strip from 1.42 s on, its velocity frozen with it.
    plain = simulate(system, x0, "unconstrained", T, *levels[0], max_transitions=10**5, continuation=False)
    held = float(np.ptp(np.array(plain.sample(last).states)[:, 0]))
    ok = min(swings) > 0.1 and held < 1e-9
    result.add(
        Check(
            "link 1 swings at 6 s",
            ok,
            f"theta1 moves by {', '.join(f'{r:.3g}' for r in swings)} rad over "
            f"[{T - 0.5:g}, {T:g}] s; by {held:.2g} rad without continuation",
        )
    )
    result.numbers.update(
        {
            "theta1_swing_last_0.5s": swings[-1],
            "theta1_swing_plain": held,
            "theta1d_6s": float(finals[-1][2]),
            "differences": ", ".join(f"{d:.3g}" for d in diffs),
        }
    )
    result.outcome = (
        f"{len(levels)} levels to eps = {levels[-1][1]:g}: differences "
        f"{', '.join(f'{d:.2g}' for d in diffs)}; theta1 swings {swings[-1]:.2g} rad in the last "
        f"0.5 s (plain: held)"
    )
