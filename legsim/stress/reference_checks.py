"""Checks of a run against what the closed form of its model says, shared by several case
families: the bouncing ball's flights, rest and holds, and the two tanks' switches."""

from __future__ import annotations

import math
from itertools import pairwise
from typing import Any

import numpy as np

from ..execution import Execution
from .framework import Check


def ball_flight_checks(ex: Execution, g: float, eps: float, resolved: float) -> Check:
    """Free fall is a cubic in time, which RK4 and the Hermite crossing reproduce to rounding:
    every flight of the relaxed execution (from a strip exit to the next crossing) must last
    exactly 2 w / g for its take-off speed w, whatever the holds in the strips. Flights shorter
    than ``resolved`` (s) are skipped: they start from a strip point whose height (|z| <= 1e-9
    eps) is comparable to the flight itself."""
    worst, count = 0.0, 0
    for a, b in pairwise(ex.transitions):
        z0, w = a.state_after
        flight = b.time - a.exit_time
        expected = (w + math.sqrt(max(w * w + 2.0 * g * z0, 0.0))) / g
        if expected < resolved or w <= 0:
            continue
        count += 1
        # the crossing is located to 1e-9 eps in height, i.e. to 1e-9 eps / w in time, at each end
        worst = max(worst, abs(flight - expected) / (1e-9 + 4e-9 * eps / w))
    ok = count > 0 and worst <= 1.0
    return Check(
        "flights exact",
        ok,
        f"{count} flights equal 2 w/g to the crossing tolerance (worst ratio {worst:.2g})"
        if ok
        else f"{count} flights checked, worst error {worst:.3g} x (1e-9 s + 4e-9 eps/w)",
    )


def ball_rest_check(ex: Execution, c: float, g: float, eps: float, t_from: float, t_to: float) -> Check:
    """After its Zeno time the ball rests on the floor: between t_from and t_to its height stays
    in [-eps, eps c^2/(1 - c^2)] and its speed below sqrt(2 g eps/(1 - c^2)). (Resting, every
    cycle takes off from the strip point with w = c v, v^2 <= w^2 + 2 g eps: the fixed point of
    w^2 = c^2 (w^2 + 2 g eps) bounds the apex w^2/(2 g) and the speed.)"""
    times = np.linspace(t_from, t_to, 400)
    states = np.array(ex.sample(times).states)
    z_hi = eps * c * c / (1.0 - c * c) if c < 1 else math.inf
    v_hi = math.sqrt(2.0 * g * eps / (1.0 - c * c)) if c < 1 else math.inf
    slack = 1e-9 * eps
    z_min, z_max, v_max = float(states[:, 0].min()), float(states[:, 0].max()), float(np.abs(states[:, 1]).max())
    ok = z_min >= -eps - slack and z_max <= z_hi + slack and v_max <= v_hi + slack
    return Check(
        "rests on the floor",
        ok,
        f"t in [{t_from:.3g}, {t_to:.3g}] s: z in [{z_min:.2g}, {z_max:.2g}] within [-eps, {z_hi:.2g}] m, "
        f"|zd| <= {v_max:.2g} <= {v_hi:.2g} m/s"
        if ok
        else f"t in [{t_from:.3g}, {t_to:.3g}] s: z in [{z_min:.3g}, {z_max:.3g}] vs [-eps, {z_hi:.3g}] m, "
        f"|zd| up to {v_max:.3g} vs {v_hi:.3g} m/s",
    )


def ball_hold_check(ex: Execution, eps: float) -> Check:
    """Each bounce's strip lasts at most eps (1 + 1/v): the landing point lies at most eps past the
    floor, reached in at most eps/v after the crossing at speed v (gravity only speeds it up), and
    the strip itself is eps - depth."""
    worst = 0.0
    for tr in ex.transitions:
        v = abs(float(tr.state_before[1]))
        if v > 0:
            worst = max(worst, (tr.exit_time - tr.time) / (eps * (1.0 + 1.0 / v)))
    ok = worst <= 1.0 + 1e-9
    return Check("holds <= eps (1 + 1/v)", ok, f"worst hold / bound = {worst:.3g}")


def ball_rest_crossing(v1: float, c: float, g: float, window: float) -> int:
    """The crossing (counted from 1, the first impact at speed v1 m/s) at which the accumulation
    rule rests a ball of restitution c: the k-th impact ends the flight 2 c^(k-1) v1 / g, and the
    rule fires at the first one no longer than ``window`` (s),
    k = 1 + ceil(log(2 v1 / (g window)) / log(1/c)), never before the second crossing."""
    return 1 + max(1, math.ceil(math.log(2.0 * v1 / (g * window)) / math.log(1.0 / c)))


def oscillator_stick_sequence(ref: Any, t_end: float, window: float) -> list[str]:
    """The transitions of the oscillator's run to ``t_end`` under the accumulation rule with
    ``window`` (s), from its exact execution ``ref`` (an ``OscillatorReference`` starting at rest
    on the stop, as Example 2 does, with ``t_end`` inside a sticking phase): ``impact`` then
    ``stick`` (a flight of zero) for the first sticking phase; after each release the exact
    impacts bounce until the first that ends a flight no longer than the window, which sticks."""
    impacts = ref.impact_times(t_end)
    phases = ref.sticking_intervals(t_end)
    if not phases or phases[0][0] != ref.t0 or phases[-1][1] < t_end:
        raise ValueError("the exact execution must start and end stuck on the stop")
    names = ["impact", "stick"]
    for (_, released), (stuck, _) in pairwise(phases):
        flights = np.diff(impacts[(impacts > released) & (impacts <= stuck)])
        if not np.any(flights <= window):
            raise ValueError(f"no exact flight before the stick at {stuck:.6g} s is as short as {window:g} s")
        names += ["release"] + ["impact"] * (int(np.argmax(flights <= window)) + 1) + ["stick"]
    return names


def tank_switch_checks(ex: Execution, ref: Any, x0: np.ndarray, count: int) -> Check:
    """Constant fields are integrated exactly and the guards are linear, so the relaxed execution
    is the exact one with pauses: its k-th strip point is the exact k-th switching state, and its
    k-th crossing time the exact one plus the strip time held before it."""
    times, _ = ref.switching_times("q1", x0, count)
    worst_x, worst_t, held = 0.0, 0.0, 0.0
    x = np.array(x0, dtype=float)
    flows = {"q1": np.array([ref.w - ref.v1, -ref.v2]), "q2": np.array([-ref.v1, ref.w - ref.v2])}
    t_prev, mode = 0.0, "q1"
    n = min(count, len(ex.transitions))
    for k in range(n):
        x = x + (times[k] - t_prev) * flows[mode]
        if mode == "q1":
            x[1] = ref.r2
        else:
            x[0] = ref.r1
        tr = ex.transitions[k]
        worst_x = max(worst_x, float(np.max(np.abs(tr.state_before - x))))
        worst_t = max(worst_t, abs(tr.time - (times[k] + held)))
        held += tr.exit_time - tr.time
        t_prev, mode = times[k], tr.target
    ok = n == count and worst_x <= 1e-9 and worst_t <= 1e-9
    return Check(
        "switches exact",
        ok,
        f"first {n} strip points = exact switching states to {worst_x:.2g} m, "
        f"crossing times = exact + held strips to {worst_t:.2g} s",
    )


def tank_level_rate(ref: Any) -> float:
    """The fastest either tank level moves (m/s) in either mode (q1: w - v1 and -v2; q2: -v1 and
    w - v2), the rate ``transition_floor`` needs for the two tanks' guards."""
    return max(abs(ref.w - ref.v1), ref.v1, ref.v2, abs(ref.w - ref.v2))
