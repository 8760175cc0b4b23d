"""Zeno cases: infinitely many transitions in finite time. The bouncing ball, the double
pendulum with a stop (paper 003 Fig. 2c), the two-tank system (paper 004 Sec. IV-D) and the
forced oscillator with a stop (paper 000 Table I Example 2): each runs through and past its Zeno
time, and must neither stall nor leave its closed form's bounds. The plain cases run the paper's
relaxed execution (``continuation=False``) and check that the run says where its transitions
accumulate; the ``_continued`` cases run the default, the continuation the model names
(``legsim.relaxed.zeno``), taken at the crossing that ends the first flight no longer than the
window h + eps.
"""

from __future__ import annotations

import math
import time
from itertools import pairwise

import numpy as np

from ...builders import Model
from ...execution import Execution, TransitionRecord
from ...hybrid import HybridSystem
from ...relaxed import simulate
from ...systems.oscillator import EXAMPLES, OscillatorReference
from ..framework import CaseResult, Check, case
from ..invariants import (
    check_accumulation,
    check_order,
    execution_checks,
    first_accumulating_crossing,
    transition_floor,
)
from ..models import build, double_pendulum, model_state, oscillator_ex2
from ..reference_checks import (
    ball_flight_checks,
    ball_rest_check,
    ball_rest_crossing,
    oscillator_stick_sequence,
    tank_level_rate,
    tank_switch_checks,
)

#: Paper 000 Table I Example 2, the oscillator cases' parameters.
EX2 = EXAMPLES["ex2"]

# ---------------------------------------------------------------------------------------------
# the bouncing ball
# ---------------------------------------------------------------------------------------------


def _zeno_ball(result: CaseResult, quick: bool, c: float) -> None:
    g, z0 = 9.81, 1.0
    model = build("bouncing_ball", {"g": g, "z0": z0}, {"floor": {"restitution": c}})
    ref = model.reference
    system = model.system
    T = 2.0 * ref.zeno_time
    h, eps = 1e-3, 1e-4
    floor = transition_floor(h, eps, accel=g)
    bound = (T - ref.first_impact) / floor + 1
    ex = simulate(system, [z0, 0.0], "flight", T, h, eps, max_transitions=int(2 * bound) + 10, continuation=False)
    result.main_run(ex)
    result.add(
        execution_checks(
            system,
            ex,
            eps,
            energy="dissipative",
            energy_tol=1e-9,
            bound=bound,
            bound_why=f"(T - t1)/{floor:.3g} s: a step or a strip per transition",
        )
    )
    result.add(ball_flight_checks(ex, g, eps, resolved=4 * h))
    result.add(ball_rest_check(ex, c, g, eps, 1.5 * ref.zeno_time, T))
    # The accumulation begins at the k-th impact, the first to end a flight no longer than
    # h + eps (closed form), which the relaxed run reaches late by the strips held before it.
    k_acc = ball_rest_crossing(ref.impact_speed, c, g, h + eps)
    t_acc = float(ref.impact_time(k_acc)) + sum(tr.exit_time - tr.time for tr in ex.transitions[: k_acc - 1])
    result.add(check_accumulation(ex, [("bounce", t_acc - 1e-9, t_acc + 1e-9)]))
    # Convergence: the relaxed impacts lag the exact ones by the strips they held; the lag of a
    # late impact before the Zeno time shrinks like h + eps.
    k = 6
    levels = [(2e-3, 2e-4), (1e-3, 1e-4), (5e-4, 5e-5)] + ([] if quick else [(2.5e-4, 2.5e-5), (1.25e-4, 1.25e-5)])
    lags = []
    t_k = float(ref.impact_time(k))
    for hh, ee in levels:
        run = simulate(system, [z0, 0.0], "flight", t_k + 0.5 * (ref.zeno_time - t_k), hh, ee, continuation=False)
        lags.append(run.transitions[k - 1].time - t_k)
    result.add(check_order(f"impact {k} lag -> 0", [lv[0] for lv in levels], lags, 0.7, 1.3, "h (eps = h/10)"))
    after = sum(tr.time > ref.zeno_time for tr in ex.transitions)
    result.numbers.update({"zeno_time": ref.zeno_time, "transitions_after_zeno": after, "lag_impact6_h1e-3": lags[1]})
    z_end = ex.final_state
    result.outcome = (
        f"{ex.status}; {len(ex.transitions) - after} impacts before t_zeno = {ref.zeno_time:.4g} s, "
        f"rests (z = {z_end[0]:.1g} m) to {T:.3g} s"
    )


@case("zeno_ball_c0.5", "zeno", "bouncing ball, c = 0.5, plain relaxed, through and past its Zeno time (to twice it)")
def _zeno_ball_half(result: CaseResult, quick: bool) -> None:
    _zeno_ball(result, quick, 0.5)


@case("zeno_ball_c0.8", "zeno", "bouncing ball, c = 0.8, plain relaxed, through and past its Zeno time (to twice it)")
def _zeno_ball_08(result: CaseResult, quick: bool) -> None:
    _zeno_ball(result, quick, 0.8)


@case("zeno_ball_c0.8_continued", "zeno", "bouncing ball, c = 0.8, default continuation: the plain bounces, then rest")
def _zeno_ball_continued(result: CaseResult, quick: bool) -> None:
    g, z0, c, h, eps = 9.81, 1.0, 0.8, 1e-3, 1e-4
    window = h + eps
    model = build("bouncing_ball", {"g": g, "z0": z0}, {"floor": {"restitution": c}})
    ref = model.reference
    T = 2.0 * ref.zeno_time
    k = ball_rest_crossing(ref.impact_speed, c, g, window)
    start = time.perf_counter()
    ex = simulate(model.system, [z0, 0.0], "flight", T, h, eps, max_transitions=1000)
    cost = time.perf_counter() - start
    result.main_run(ex)
    result.add(
        execution_checks(
            model.system,
            ex,
            eps,
            energy="dissipative",
            energy_tol=1e-9,
            bound=k,
            bound_why="k - 1 bounces and the rest, k = 1 + ceil(log(2 v1/(g w))/log(1/c))",
        )
    )
    result.add(ball_flight_checks(ex, g, eps, resolved=4 * h))
    start = time.perf_counter()
    plain = simulate(model.system, [z0, 0.0], "flight", T, h, eps, max_transitions=10**6, continuation=False)
    plain_cost = time.perf_counter() - start
    kept = ex.transitions[:-1]
    same = [a.exit_time for a in kept] == [b.exit_time for b in plain.transitions[: len(kept)]]
    rests = ex.final_mode == "rest" and ex.transitions[-1].name == "rest" and len(ex.transitions) == k
    # The rest is the exact k-th impact delayed by the strips held before it, so at most the
    # exact flights still to come, window c / (1 - c), before the Zeno time.
    held = sum(tr.exit_time - tr.time for tr in kept)
    t_rest = ex.transitions[-1].time
    exact = float(ref.impact_time(k)) + held
    ok = (
        same
        and rests
        and abs(t_rest - exact) <= 1e-9
        and ex.warnings == []
        and ref.zeno_time - window * c / (1 - c) <= t_rest - held <= ref.zeno_time
    )
    result.add(
        Check(
            "plain bounces, then rest",
            ok,
            f"{len(kept)} bounces identical to the plain run's, rest at crossing {len(ex.transitions)} "
            f"(closed form {k}) at {t_rest:.9g} s = exact impact + held {held:.3g} s "
            f"(to {abs(t_rest - exact):.2g}); "
            f"t_zeno {ref.zeno_time:.5g} s, the tail after it {window * c / (1 - c):.2g} s",
        )
    )
    result.numbers.update({"transitions_plain": len(plain.transitions), "wall_s": cost, "wall_s_plain": plain_cost})
    result.outcome = (
        f"{ex.status} in '{ex.final_mode}'; {len(ex.transitions)} transitions vs "
        f"{len(plain.transitions)} plain ({cost:.2g} s vs {plain_cost:.2g} s)"
    )


# ---------------------------------------------------------------------------------------------
# the double pendulum with a stop (paper 003 Fig. 2c)
# ---------------------------------------------------------------------------------------------


def flight_ratios(ex: Execution, n: int) -> list[float]:
    """Ratios of successive flights (strip exit to next crossing) of the first n+1 bounces."""
    flights = [b.time - a.exit_time for a, b in pairwise(ex.transitions) if a.source == a.target]
    # The first flight follows the first impact, before which the motion was not a bounce.
    return [b / a for a, b in pairwise(flights[1 : n + 2])]


def max_guard_accel(system: HybridSystem, ex: Execution, coordinate: int, stride: int = 1) -> float:
    """Largest |d^2 q/dt^2| of a coordinate (index in the state's velocity block) over the run."""
    best = 0.0
    for seg in ex.segments:
        field = system.mode(seg.mode).field
        for x, t in zip(seg.x[::stride], seg.t[::stride], strict=True):
            best = max(best, abs(float(np.asarray(field(t, x, None))[coordinate])))
    return best


@case(
    "zeno_double_pendulum_c0.5",
    "zeno",
    "double pendulum, stop c = 0.5 (paper 003 Fig. 2c), plain relaxed: impacts accumulate, the run carries on",
)
def _zeno_pendulum_plain(result: CaseResult, quick: bool) -> None:
    h, eps, c = 1e-3, 1e-3, 0.5
    T = 2.5 if quick else 5.0
    model, x0 = double_pendulum(c)
    system = model.system
    ex = simulate(system, x0, "unconstrained", T, h, eps, max_transitions=10**6, continuation=False)
    result.main_run(ex)
    a_max = 2.0 * max_guard_accel(system, ex, 3)  # theta2'' measured on the run, with a factor 2 of slack
    floor = transition_floor(h, eps, accel=a_max)
    bound = T / floor + 1
    result.add(
        execution_checks(
            system,
            ex,
            eps,
            energy="dissipative",
            energy_tol=1e-7,
            bound=bound,
            bound_why=f"T/{floor:.3g} s, |theta2''| <= {a_max:.3g} rad/s^2",
        )
    )
    ratios = flight_ratios(ex, 6)
    ok = len(ratios) == 6 and all(abs(r - c) <= 0.02 for r in ratios)
    result.add(Check("flights shrink by c", ok, "ratios " + ", ".join(f"{r:.3f}" for r in ratios)))
    # Where the flights are shorter than one step the stop chatters: theta2 stays in the strip's
    # band (the ball's bound with the largest acceleration).
    short = [tr.time for a, tr in pairwise(ex.transitions) if tr.time - a.exit_time < h]
    t_chatter = short[0] if short else T
    times = np.linspace(t_chatter, T, 300)
    th2 = np.array([s[1] for s in ex.sample(times).states])
    hi = eps * c * c / (1 - c * c)
    ok = short != [] and th2.min() >= -eps * (1 + 1e-9) and th2.max() <= hi * (1 + 1e-9)
    result.add(
        Check(
            "stop chatters in its strip",
            ok,
            f"from {t_chatter:.4g} s theta2 in [{th2.min():.2g}, {th2.max():.2g}] within [-eps, {hi:.2g}] rad",
        )
    )
    # The run says so: its impacts accumulate from the crossing that ends the first flight no
    # longer than h + eps, before the chatter (flights shorter than a step) begins.
    k = first_accumulating_crossing(ex, "bounce_stop", h + eps)
    t_acc = ex.transitions[k].time if k is not None else math.nan
    result.add(check_accumulation(ex, [("bounce_stop", t_acc, min(t_acc, t_chatter))]))
    # The finding: while the stop chatters every step crosses at its start, and the relaxed
    # algorithm holds the whole state at the strip point: link 1 stops swinging.
    th1 = np.array([s[0] for s in ex.sample(times).states])
    frozen = float(np.ptp(th1))
    result.numbers.update(
        {"chatter_from": t_chatter, "theta1_range_while_chattering": frozen, "transitions": len(ex.transitions)}
    )
    result.outcome = (
        f"{ex.status}; {len(ex.transitions) - len(short)} resolved impacts, chatters from "
        f"{t_chatter:.3g} s; whole state held (theta1 range {frozen:.1g} rad)"
    )


@case(
    "zeno_double_pendulum_c0.5_continued",
    "zeno",
    "double pendulum, stop c = 0.5, default continuation: rests in the constrained mode, "
    "released where eq. (31) changes sign",
)
def _zeno_pendulum_continued(result: CaseResult, quick: bool) -> None:
    h, eps, c = 1e-3, 1e-3, 0.5
    T = 2.5 if quick else 5.0
    model, x0 = double_pendulum(c)
    system = model.system
    ex = simulate(system, x0, "unconstrained", T, h, eps, max_transitions=1000)
    result.main_run(ex)
    rests = [tr for tr in ex.transitions if tr.name == "rest_stop"]
    releases = [tr for tr in ex.transitions if tr.name == "release_stop"]
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
    # The stop torque of the straight rigid pendulum (theta2 = 0) is m2 L2 g sin(theta1) (1 - L (m1 L1 +
    # m2 L)/(m1 L1^2 + m2 L^2)) with L = L1 + L2: with unit masses and lengths -0.2 g sin(theta1), so
    # the release is exactly where theta1 crosses zero.
    th1 = [abs(float(tr.state_before[0])) for tr in releases]
    ok = len(releases) >= 1 and max(th1) <= 1e-6
    result.add(
        Check(
            "released where eq. (31) changes sign",
            ok,
            f"{len(releases)} release(s) at |theta1| <= {max(th1, default=math.nan):.2g} rad (closed form 0)",
        )
    )
    # Between each rest and the next release the pendulum is in its constrained mode.
    ends = [tr.time for tr in rests]
    spans = [(r.exit_time, next((q.time for q in releases if q.time > r.time), ex.t_end)) for r in rests]
    modes = [set(ex.sample(np.linspace(a, b, 50, endpoint=False)).modes) for a, b in spans if b > a]
    ok = bool(rests) and all(m == {"constrained"} for m in modes)
    result.add(
        Check(
            "rests in the constrained mode",
            ok,
            "constrained on " + ", ".join(f"[{a:.4g}, {b:.4g}]" for a, b in spans) + " s",
        )
    )
    # Cost and agreement with the plain relaxed run up to the accumulation.
    plain = simulate(system, x0, "unconstrained", ends[0] - 0.05, h, eps, max_transitions=10**6, continuation=False)
    gap = float(np.max(np.abs(plain.final_state - ex.sample([plain.t_end]).states[0])))
    result.add(
        Check(
            "agrees with plain run before resting",
            gap <= 1e-9,
            f"|x_plain - x_continued| = {gap:.2g} at t = {plain.t_end:.4g} s",
        )
    )
    result.add(_release_time_converges(c, x0, quick))
    result.numbers.update({"rest_time": ends[0], "release_times": ", ".join(f"{tr.time:.6g}" for tr in releases)})
    result.outcome = (
        f"{ex.status} in '{ex.final_mode}'; rests at {ends[0]:.4g} s, released at "
        f"{', '.join(f'{tr.time:.4g}' for tr in releases)} s"
    )


def pressing_impact_bound(system: HybridSystem, ex: Execution, c: float, window: float) -> tuple[float, list[int]]:
    """(bound on the transitions, pressing impacts per accumulation) of the double pendulum
    continued at its accumulations (window ``window`` in s).

    In each accumulation (the impacts since the last release) the impacts that press link 2 onto
    the stop (free theta2'' < 0, acceleration a_n = -theta2'') leave with speeds w falling by c
    from w1 = c max|theta2'|, and fly 2 w / a_n. The rest comes at the crossing that ends the
    first flight no longer than the window, after the first bounce with w <= w_th = a_n window / 2
    at the least a_n: at most log(w1/w_th)/log(1/c) + 2 bounces. Impacts pulling away end long
    flights and are counted as they come, as are the rests and releases."""
    free = system.mode("unconstrained").field
    groups: list[list[TransitionRecord]] = [[]]
    bound, pressing = 0.0, []
    for tr in ex.transitions:
        if tr.name == "bounce_stop" and -float(free(tr.time, tr.state_before, None)[3]) > 0:
            groups[-1].append(tr)
        else:
            bound += 1
        if tr.name == "release_stop":
            groups.append([])
    for grp in groups:
        if grp:
            w1 = c * max(abs(float(tr.state_before[3])) for tr in grp)
            a_n = min(-float(free(tr.time, tr.state_before, None)[3]) for tr in grp)
            bound += math.log(max(w1 / (0.5 * a_n * window), 1.0)) / math.log(1.0 / c) + 2
            pressing.append(len(grp))
    return bound, pressing


def _release_time_converges(c: float, x0: np.ndarray, quick: bool) -> Check:
    """The release time converges as h = eps shrinks (successive differences shrink at least like
    h^0.5; the number of resolved flights grows like log(1/h))."""
    levels = [4e-3, 2e-3, 1e-3] if quick else [4e-3, 2e-3, 1e-3, 5e-4, 2.5e-4]
    times = []
    model, _ = double_pendulum(c)
    for hh in levels:
        run = simulate(model.system, x0, "unconstrained", 2.5, hh, hh, max_transitions=1000)
        times.append(next(tr.time for tr in run.transitions if tr.name == "release_stop"))
    diffs = [abs(a - b) for a, b in pairwise(times)]
    return check_order("release time converges", levels[:-1], diffs, 0.5, 1.5, "h = eps")


# ---------------------------------------------------------------------------------------------
# the two-tank system (paper 004 Sec. IV-D)
# ---------------------------------------------------------------------------------------------


def _two_tanks_run(h: float, eps: float, T: float, method: str = "rk4"):
    """The two tanks from the model's initial state in q1 to T, with their transition bound:
    (model, reference, x0, execution, bound, floor, the levels' largest rate)."""
    model = build("two_tanks")
    ref = model.reference
    x0 = model_state(model, "q1")
    rate = tank_level_rate(ref)
    floor = transition_floor(h, eps, rate=rate)
    bound = T / floor + 1
    ex = simulate(model.system, x0, "q1", T, h, eps, method=method, max_transitions=int(2 * bound) + 10)
    return model, ref, x0, ex, bound, floor, rate


@case(
    "zeno_two_tanks", "zeno", "two tanks, one switched inflow (paper 004 Sec. IV-D): through its Zeno time 8 s to 10 s"
)
def _zeno_two_tanks(result: CaseResult, quick: bool) -> None:
    h, eps, T = 0.01, 1e-3, 10.0
    model, ref, x0, ex, bound, floor, rate = _two_tanks_run(h, eps, T)
    result.main_run(ex)
    result.add(
        execution_checks(
            model.system,
            ex,
            eps,
            bound=bound,
            bound_why=f"T/{floor:.3g} s: each transition costs a step, the levels move at <= {rate:g} m/s",
        )
    )
    result.add(tank_switch_checks(ex, ref, x0, 24))
    # The total excess level falls at v1 + v2 - w while the flow runs and is frozen in the strips,
    # so the relaxed excess never falls below the exact one, which reaches zero at the Zeno time.
    t_zeno = ref.zeno_time(x0)
    times = np.linspace(0.0, T, 501)
    states = np.array(ex.sample(times).states)
    excess = states.sum(axis=1) - ref.r1 - ref.r2
    exact = np.maximum((x0.sum() - ref.r1 - ref.r2) - (ref.v1 + ref.v2 - ref.w) * times, 0.0)
    late = times >= t_zeno + 0.5 * (T - t_zeno)
    lo = float(states[late].min() - min(ref.r1, ref.r2))
    hi = float(np.abs(excess[late]).max())
    ok = bool(np.all(excess >= exact - 1e-9)) and lo >= -eps * (1 + 1e-9) and hi <= 2 * eps
    result.add(
        Check(
            "levels at their thresholds after t_zeno",
            ok,
            f"excess >= exact everywhere; for t >= {times[late][0]:.3g} s levels >= threshold - {-lo:.2g} m, "
            f"|excess| <= {hi:.2g} m <= 2 eps",
        )
    )
    # Convergence: the excess left at the Zeno time is the flow lost while held in strips, O(eps).
    levels = [4e-3, 2e-3, 1e-3] if quick else [4e-3, 2e-3, 1e-3, 5e-4, 2.5e-4]
    left = []
    for ee in levels:
        _, _, _, run, _, _, _ = _two_tanks_run(h, ee, t_zeno)
        left.append(float(run.final_state.sum() - ref.r1 - ref.r2))
    result.add(check_order("excess at t_zeno -> 0", levels, left, 0.8, 1.2, "eps"))
    result.add(_held_and_says_so(ex, t_zeno))
    after = sum(tr.time > t_zeno for tr in ex.transitions)
    result.numbers.update({"zeno_time": t_zeno, "transitions_after_zeno": after})
    result.outcome = (
        f"{ex.status}; {len(ex.transitions) - after} switches before t_zeno = {t_zeno:g} s, levels held "
        f"at the thresholds to {T:g} s"
    )


def _held_and_says_so(ex: Execution, t_zeno: float) -> Check:
    """Past their Zeno time the tanks are held in the strips of two alternating transitions; the
    run must say so, by one accumulation warning naming both transitions of the cycle, which
    begins before the relaxed Zeno time (the exact one delayed by the strips held)."""
    held = sum(strip.exit_time - strip.time for strip in ex.strips)
    before = sum(strip.exit_time - strip.time for strip in ex.strips if strip.time < t_zeno)
    says = [w for w in ex.warnings if w.kind in ("accumulation", "strip_hold")]
    ok = (
        len(says) == 1
        and says[0].kind == "accumulation"
        and says[0].time <= t_zeno + before
        and sorted(says[0].details["transitions"]) == ["q1->q2", "q2->q1"]
    )
    return Check(
        "says it is held",
        ok,
        f"warnings {[(w.kind, round(w.time, 6)) for w in ex.warnings]}; {held:.3g} s held in strips",
    )


# ---------------------------------------------------------------------------------------------
# the forced oscillator with a stop (paper 000 Table I Example 2)
# ---------------------------------------------------------------------------------------------


@case(
    "zeno_oscillator_ex2",
    "zeno",
    "forced oscillator with a stop, paper 000 Table I Example 2, plain relaxed: sticks, leaves, "
    "chatters (Zeno), sticks again",
)
def _zeno_oscillator(result: CaseResult, quick: bool) -> None:
    _oscillator_ex2(result, quick, continued=False)


@case(
    "zeno_oscillator_ex2_continued",
    "zeno",
    "Example 2, default continuation: sticks and releases as the exact execution does, at a fraction of the cost",
)
def _zeno_oscillator_continued(result: CaseResult, quick: bool) -> None:
    _oscillator_ex2(result, quick, continued=True)


def rho_hat(ex: Execution, ref: OscillatorReference) -> float:
    """Paper 000 eq. (30): the largest position error (m) at the run's step points against the
    exact execution."""
    ts = ex.step_times()
    xs = np.concatenate([s.x[:, 0] for s in ex.segments])
    return float(np.max(np.abs(xs - ref.position(ts))))


def _oscillator_ex2(result: CaseResult, quick: bool, continued: bool) -> None:
    h, eps = 1e-2, 1e-5
    T = 4.0 * math.pi
    model = oscillator_ex2()
    ref = model.reference
    ex, cost = _timed_ex2(model, T, h, eps, continued)
    result.main_run(ex)
    sequence = oscillator_stick_sequence(ref, T, h + eps)
    bound, why = (
        (len(sequence), "the rule's sticks on the exact impacts, and the releases")
        if continued
        else _plain_bound(ex, T, h, eps)
    )
    result.add(execution_checks(model.system, ex, eps, control=model.control, bound=bound, bound_why=why))
    rho = rho_hat(ex, ref)
    result.add(_on_the_stop_check(ex, ref, T, eps))
    result.numbers.update({"rho_hat": rho, "wall_s": cost, "transitions": len(ex.transitions)})
    if continued:
        result.add(_sticks_and_releases_checks(ex, ref, T, h, eps, sequence))
        _compare_with_plain(result, model, ex, rho, cost, T, h, eps)
    else:
        result.add(_chatter_reported(ex, ref, T, h))
    levels = [(1e-2, 1e-3), (1e-2, 1e-4), (1e-2, 1e-5)] + ([] if quick else [(1e-2, 1e-6)])
    errs = []
    for hh, ee in levels:
        run = simulate(
            model.system,
            [EX2["x_max"], 0.0],
            "free",
            T,
            hh,
            ee,
            control=model.control,
            max_transitions=10**6,
            continuation=continued,
        )
        errs.append(rho_hat(run, ref))
    result.add(check_order("rho_hat -> 0", [lv[1] for lv in levels], errs, 0.5, 1.2, "eps (h = 1e-2)"))
    result.outcome = f"{ex.status}; {len(ex.transitions)} transitions, rho_hat = {rho:.2g} m, {cost:.2g} s"


def _timed_ex2(model: Model, T: float, h: float, eps: float, continued: bool) -> tuple[Execution, float]:
    """Example 2 from rest on the stop to T (s), with or without the continuation, and its wall
    time (s)."""
    start = time.perf_counter()
    ex = simulate(
        model.system,
        [EX2["x_max"], 0.0],
        "free",
        T,
        h,
        eps,
        control=model.control,
        max_transitions=10**6,
        continuation=continued,
    )
    return ex, time.perf_counter() - start


def _plain_bound(ex: Execution, T: float, h: float, eps: float) -> tuple[float, str]:
    """The transition bound of the plain run: the stop's guard accelerates at most at
    |U|/m + omega^2 max|x| + 2 a max|xd|."""
    xs = np.concatenate([s.x for s in ex.segments])
    acc = (
        EX2["amplitude"]
        + EX2["omega"] ** 2 * float(np.max(np.abs(xs[:, 0])))
        + 2 * EX2["a"] * float(np.max(np.abs(xs[:, 1])))
    )
    floor = transition_floor(h, eps, accel=acc)
    return T / floor + 1, f"T/{floor:.3g} s, guard acceleration <= {acc:.3g} m/s^2"


def _chatter_reported(ex: Execution, ref: OscillatorReference, T: float, h: float) -> Check:
    """The plain run chatters where the exact mass sticks, and says so: one accumulation warning
    per sticking phase, naming the impact, its estimated Zeno time within a step h of the
    phase's start (where the exact impacts accumulate)."""
    phases = ref.sticking_intervals(T)
    found = [
        (w.details.get("transition"), w.details.get("accumulation_time", math.nan))
        for w in ex.warnings
        if w.kind == "accumulation"
    ]
    ok = len(found) == len(phases) and all(
        name == "impact" and abs(t - s0) <= h for (name, t), (s0, _) in zip(found, phases, strict=True)
    )
    return Check(
        "accumulation reported",
        ok,
        f"warnings' Zeno times {', '.join(f'{t:.6g}' for _, t in found) or 'none'} s; exact sticking phases "
        f"{', '.join(f'[{a:.6g}, {b:.4g}]' for a, b in phases)}",
    )


def _on_the_stop_check(ex: Execution, ref: OscillatorReference, T: float, eps: float) -> Check:
    """During the exact sticking phases the relaxed mass stays on the stop: within the strip past
    it and below eps c^2/(1 - c^2) off it once the chatter has settled (the ball's bound)."""
    x_max, c = EX2["x_max"], EX2["c"]
    band = eps * c * c / (1 - c * c)
    worst = 0.0
    for s0, s1 in ref.sticking_intervals(T):
        lo = s0 + (0.0 if s0 == 0.0 else 0.05)
        tt = np.linspace(lo, min(s1, T) - 0.05, 200)
        xx = np.array([st[0] for st in ex.sample(tt).states])
        worst = max(worst, float(np.max(xx - x_max)) / eps, float(np.max(x_max - xx)) / band)
    return Check(
        "on the stop while the exact mass sticks",
        worst <= 1.0 + 1e-9,
        f"x within [x_max - eps c^2/(1-c^2), x_max + eps] on the exact sticking phases (worst ratio {worst:.3g})",
    )


def _sticks_and_releases_checks(
    ex: Execution, ref: OscillatorReference, T: float, h: float, eps: float, sequence: list[str]
) -> list[Check]:
    """The default continuation sticks and releases as the reference does: the transitions the
    rule takes on the exact impacts (``sequence``), the releases where F = u/m - omega^2 x_max
    changes sign (closed form), and each stick at the crossing that ends a flight no longer than
    the window: at most the exact flights still to come, window c / (1 - c), before the exact
    start (F grows through Example 2's accumulations, so the flights shrink faster than by c),
    and at most the strips held since the chain began after it."""
    window, c = h + eps, EX2["c"]
    names = [tr.name for tr in ex.transitions]
    ends = [s1 for _, s1 in ref.sticking_intervals(T) if s1 < T]
    releases = [tr.time for tr in ex.transitions if tr.name == "release"]
    rel_err = max((abs(a - b) for a, b in zip(releases, ends, strict=False)), default=math.inf)
    ok = names == sequence and len(releases) == len(ends) and rel_err <= 1e-9
    released = Check(
        "released where F changes sign",
        ok,
        f"transitions as the rule takes them on the exact impacts: {names == sequence}; "
        f"{len(releases)} releases at the exact times {', '.join(f'{e:.9g}' for e in ends)} "
        f"to {rel_err:.2g} s",
    )
    errs, ok, chain = [], True, 0
    for k, tr in enumerate(ex.transitions):
        if tr.name == "release":
            chain = k + 1
        elif tr.name == "stick":
            s0 = min(ref.sticking_intervals(T), key=lambda iv: abs(iv[0] - tr.time))[0]
            held = sum(t.exit_time - t.time for t in ex.transitions[chain:k])
            errs.append((tr.time - s0, held))
            ok = ok and -window * c / (1 - c) <= tr.time - s0 <= held + 1e-9
    stuck = Check(
        "sticks where the impacts accumulate",
        ok and bool(errs),
        f"stick times - exact: {', '.join(f'{e:+.3g} (held {hd:.2g})' for e, hd in errs)} s, from "
        f"-{window * c / (1 - c):.3g} to the time held",
    )
    return [released, stuck]


def _compare_with_plain(
    result: CaseResult, model: Model, ex: Execution, rho: float, cost: float, T: float, h: float, eps: float
) -> None:
    """The continued run is as accurate as the plain one (rho_hat at most twice) with at most a
    tenth of its transitions; adds that check and the plain run's numbers."""
    plain, plain_cost = _timed_ex2(model, T, h, eps, False)
    rho_plain = rho_hat(plain, model.reference)
    ok = rho <= 2.0 * rho_plain and 10 * len(ex.transitions) <= len(plain.transitions)
    result.add(
        Check(
            "as accurate at a fraction of the cost",
            ok,
            f"rho_hat {rho:.3g} m vs {rho_plain:.3g} m without; transitions {len(ex.transitions)} vs "
            f"{len(plain.transitions)}; {cost:.3g} s vs {plain_cost:.3g} s",
        )
    )
    result.numbers.update(
        {"rho_hat_plain": rho_plain, "wall_s_plain": plain_cost, "transitions_plain": len(plain.transitions)}
    )
