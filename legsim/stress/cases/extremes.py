"""Extreme cases: parameters at the ends of their ranges. eps from 1e-12 to 1e-1, steps longer
than the time between events, a leg stiff enough for omega h = 0.3, 1e3 s of a conservative
runner, initial states exactly on a guard, and starts within 1e-9 of the corner of two guards.
"""

from __future__ import annotations

import math

import numpy as np

from ...execution import Execution
from ...relaxed import simulate
from ..framework import CaseResult, Check, case
from ..invariants import check_order, energies, energy_of, execution_checks, transition_floor
from ..models import build, model_state, pronk
from ..reference_checks import (
    ball_flight_checks,
    ball_hold_check,
    ball_rest_check,
    ball_rest_crossing,
    tank_level_rate,
    tank_switch_checks,
)


@case(
    "extreme_eps", "extremes", "bouncing ball with eps = 1e-12 ... 1e-1 (plain to 0.95 t_zeno; by default to 2 t_zeno)"
)
def _extreme_eps(result: CaseResult, quick: bool) -> None:
    g, c, z0, h = 9.81, 0.5, 1.0, 1e-3
    model = build("bouncing_ball", {"g": g, "z0": z0}, {"floor": {"restitution": c}})
    ref = model.reference
    epss = [1e-12, 1e-9, 1e-6, 1e-3, 1e-1] if quick else [1e-12, 1e-11, 1e-10, 1e-9, 1e-8, 1e-6, 1e-4, 1e-3, 1e-2, 1e-1]
    lags, halvings, main = [], {}, None
    T1 = 0.95 * ref.zeno_time
    for eps in epss:
        # plain relaxed, short of the Zeno time (past it every bounce costs a step or a strip:
        # (t - t_zeno) / min(h, eps, sqrt(eps/g)) transitions, 1e7 at eps = 1e-12)
        n_max = int(T1 / transition_floor(h, eps, accel=g)) + 1
        ex = simulate(
            model.system, [z0, 0.0], "flight", T1, h, eps, max_transitions=min(n_max, 10**6), continuation=False
        )
        main = main or ex
        n_exact = int(ref.impact_count(T1))
        result.add(
            execution_checks(
                model.system,
                ex,
                eps,
                energy="dissipative",
                energy_tol=1e-9,
                bound=n_exact,
                bound_why=f"no more than the {n_exact} exact impacts before 0.95 t_zeno",
            )
        )
        if eps < 0.05:  # a 0.1 m strip delays the impacts past 0.95 t_zeno; the flights stay exact
            result.add(ball_flight_checks(ex, g, eps, resolved=0.0))
        result.add(ball_hold_check(ex, eps))
        lags.append(ex.transitions[0].exit_time - ref.first_impact)
        halvings[eps] = ex.halvings / max(len(ex.transitions), 1)
        # through the Zeno time by default: the bounce's continuation rests the ball at the
        # crossing that ends the first flight no longer than h + eps (its flights are exact)
        T2 = 2.0 * ref.zeno_time
        ex2 = simulate(model.system, [z0, 0.0], "flight", T2, h, eps, max_transitions=1000)
        k = ball_rest_crossing(ref.impact_speed, c, g, h + eps)
        result.add(
            execution_checks(
                model.system,
                ex2,
                eps,
                energy="dissipative",
                energy_tol=1e-9,
                bound=k,
                bound_why=f"k = 1 + ceil(log(2 v1/(g w))/log(1/c)) = {k} crossings to the rest",
            )
        )
        ok = ex2.final_mode == "rest" and len(ex2.transitions) == k and abs(float(ex2.final_state[0])) <= 1e-9
        result.add(
            Check(
                f"rests past t_zeno (eps={eps:g})",
                ok,
                f"final mode {ex2.final_mode} after "
                f"{len(ex2.transitions)} transitions (closed form "
                f"{k}), z = {ex2.final_state[0]:.2g} m",
            )
        )
    result.add(check_order("first impact's strip exit -> t1", epss[1:-1], lags[1:-1], 0.9, 1.1, "eps"))
    assert main is not None  # set by the loop above, which runs at least once
    result.main_run(main)
    result.numbers.update({f"halvings_per_impact_eps{e:g}": v for e, v in halvings.items()})
    result.outcome = (
        f"eps {epss[0]:g} .. {epss[-1]:g}: first impact held {lags[0]:.2g} .. {lags[-1]:.2g} s; "
        f"{halvings[epss[0]]:.0f} halvings per impact at eps = {epss[0]:g}"
    )


@case(
    "extreme_large_h",
    "extremes",
    "h longer than the time between events: ball (h = 0.25, 1 s), two tanks (h = 2 s), digital control (h = 1 s)",
)
def _extreme_large_h(result: CaseResult, quick: bool) -> None:
    g, c, z0, eps = 9.81, 0.5, 1.0, 1e-3
    model = build("bouncing_ball", {"g": g, "z0": z0}, {"floor": {"restitution": c}})
    ref = model.reference
    T = 2.0 * ref.zeno_time
    main = None
    for h in [0.25, 1.0] if quick else [0.1, 0.25, 0.5, 1.0]:
        floor = transition_floor(h, eps, accel=g)
        bound = (T - ref.first_impact) / floor + 1
        # the paper's relaxed execution: past t_zeno the ball chatters in the strip band
        ex = simulate(
            model.system, [z0, 0.0], "flight", T, h, eps, max_transitions=int(2 * bound) + 10, continuation=False
        )
        main = main or ex
        result.add(
            execution_checks(
                model.system,
                ex,
                eps,
                energy="dissipative",
                energy_tol=1e-9,
                bound=bound,
                bound_why=f"(T - t1)/{floor:.3g} s",
            )
        )
        # flights under 1 ms start at the guard's corner z = zd = 0, where the crossing tolerance
        # (1e-9 eps in guard units) is one on zd, not on time
        result.add(ball_flight_checks(ex, g, eps, resolved=1e-3))
        result.add(ball_rest_check(ex, c, g, eps, 1.5 * ref.zeno_time, T))
    # two tanks: dwell times 2, 1, 0.5, ... s against h = 2 s
    tanks = build("two_tanks")
    tref = tanks.reference
    x0 = model_state(tanks, "q1")
    for h in [2.0] if quick else [2.0, 5.0]:
        ex = simulate(tanks.system, x0, "q1", 10.0, h, eps, max_transitions=10**5)
        rate = tank_level_rate(tref)
        floor = transition_floor(h, eps, rate=rate)
        result.add(execution_checks(tanks.system, ex, eps, bound=10.0 / floor + 1, bound_why=f"T/{floor:.3g} s"))
        result.add(tank_switch_checks(ex, tref, x0, 20))
    # digital control: both thresholds at ln 2 inside the first step of 1 s
    dc = build("digital_control", {}, {"boost": {"setpoint": 2.0}})
    x0 = np.array([-1.0, -1.0])
    ex = simulate(dc.system, x0, "0", 3.0, 1.0, 1e-4)
    result.add(execution_checks(dc.system, ex, 1e-4, bound=2, bound_why="each threshold once"))
    held = sum(tr.exit_time - tr.time for tr in ex.transitions)
    warp = float(np.max(np.abs(ex.final_state - dc.reference.state(3.0 - held))))
    # RK4 on a relaxation at rate 1 with h = 1: |e^-1 - (1 - 1 + 1/2 - 1/6 + 1/24)| = 7.1e-3 per
    # step and unit amplitude; 3 steps, amplitudes <= 2
    result.add(
        Check(
            "digital control exact up to holds and RK4",
            warp <= 3 * 2 * 7.2e-3,
            f"|x(T) - x_exact(T - held)| = {warp:.2g} <= {3 * 2 * 7.2e-3:.2g}; path {'->'.join(ex.mode_sequence)}",
        )
    )
    assert main is not None  # set by the loop above, which runs at least once
    result.main_run(main)
    result.outcome = "ball rests after t_zeno; tank switches exact; digital path " + "->".join(ex.mode_sequence)


def hop_period(g: float, k: float, m: float, length: float, apex: float) -> tuple[float, float]:
    """(stance time, hop period) of a vertical hopper (SLIP with psi = 0) from apex height z0:
    ballistic flights and a harmonic stance about z_eq = length - m g / k at omega = sqrt(k/m)."""
    v = math.sqrt(2.0 * g * (apex - length))
    omega = math.sqrt(k / m)
    d = m * g / k  # the spring's static compression: the touchdown point is d above z_eq
    stance = (math.pi + 2.0 * math.atan(d * omega / v)) / omega
    return stance, 2.0 * v / g + stance


@case(
    "extreme_stiff_legs",
    "extremes",
    "stiff leg (k = 1e5 N/m, stance 10 ms): vertical hopping SLIP, RK4 at omega h = 0.3 ... 0.08",
)
def _extreme_stiff(result: CaseResult, quick: bool) -> None:
    k, m, length, g, z0 = 1e5, 1.0, 1.0, 9.81, 1.1
    model = build("slip", {"k": k, "m": m, "l": length, "g": g, "psi": 0.0})
    x0 = model_state(model, "flight", {"x": 0.0, "z": z0, "xd": 0.0, "zd": 0.0})
    stance, period = hop_period(g, k, m, length, z0)
    T = 2.0 if quick else 10.0
    eps = 1e-7  # m: the leg compresses by v/omega = 4.4 mm
    hs = [1e-3, 5e-4, 2.5e-4]
    drifts, period_errs, main = [], [], None
    for h in hs:
        ex = simulate(model.system, x0, "flight", T, h, eps, max_transitions=1000)
        main = main or ex
        hops = T / period
        result.add(
            execution_checks(
                model.system,
                ex,
                eps,
                energy="conservative",
                energy_tol=1e-2,
                bound=2 * hops + 2,
                bound_why=f"two per hop, hop {period:.4g} s (closed form)",
            )
        )
        E = energies(model.system, ex)[1]
        drifts.append(float(np.max(np.abs(E - E[0]))))
        lifts = [tr.time for tr in ex.transitions if tr.name.startswith("liftoff")]
        # lifts are one period apart, up to the holds (h + eps each, two per hop)
        spacing = np.diff(lifts)
        period_errs.append(float(np.max(np.abs(spacing - period))) if len(spacing) else math.inf)
        ok = len(spacing) >= 1 and period_errs[-1] <= 2 * (h + eps) + 1e-6
        result.add(
            Check(
                f"hop period (h={h:g})",
                ok,
                f"liftoffs {period:.6g} s apart (closed form) to {period_errs[-1]:.2g} s <= 2 (h + eps)",
            )
        )
    # RK4 on a harmonic stance: |R(i omega h)| = 1 - (omega h)^6/144, an energy loss of (omega h)^6/72
    # per step, so (omega h)^5 per stance: order 5 (the flights are exact)
    result.add(check_order("energy drift order", hs, drifts, 4.5, 5.5, "h"))
    assert main is not None  # set by the loop above, which runs at least once
    result.main_run(main)
    result.numbers.update(
        {
            "stance_s": stance,
            "period_s": period,
            "energy_drift": ", ".join(f"h={h:g}: {d:.2g} J" for h, d in zip(hs, drifts, strict=True)),
        }
    )
    result.outcome = (
        f"{main.status}; {len(main.transitions)} transitions, stance {stance * 1e3:.3g} ms, "
        f"drift {drifts[0]:.2g} J at h = 1e-3"
    )


#: The stable pronking gait used for the long horizon: k = 200 N/m per leg (dimensionless leg
#: stiffness k l/(m g) = 41 for the pair), apex z = 1 m, xd = 6 m/s, and the touchdown angle that
#: makes it periodic, found with
#: ``legsim orbit pronk_orbit --set robot.parameters.k=200 --set initial.state.xd=6
#: --set initial.state.z=1.0 --set robot.parameters.psi=0.36`` (multipliers 1 (energy),
#: 0.50 and 0.79 (pitch): stable). The paper's gait (k = 30, z = 1.1 m, xd = 3.4 m/s) has the
#: multiplier 5.86 per stride: it falls after some fifteen strides whatever the integrator.
STABLE_PRONK = {"params": {"k": 200.0, "psi": 0.36039485704763646}, "apex": {"z": 1.0, "xd": 6.0}}
PAPER_SLIP_PSI = 0.6251999313731675  # `legsim orbit slip_orbit`: the paper's apex made periodic, multiplier 5.86


def apex_heights(ex: Execution) -> list[tuple[float, float]]:
    """(time, z) of the apexes (zd changing sign from + to -) in the aerial segments of a runner
    whose coordinates are (x, z, ..., xd, zd, ...) with zd at index n + 1 (n = half the q, v block)."""
    out = []
    for seg in ex.segments:
        if seg.mode not in ("aerial", "flight") or len(seg.t) < 3:
            continue
        n = seg.x.shape[1] // 2
        zd = seg.x[:, n + 1]
        for i in np.nonzero((zd[:-1] > 0) & (zd[1:] <= 0))[0]:
            # the apex on the step's Hermite interpolant, to first order in the step
            s = zd[i] / (zd[i] - zd[i + 1])
            out.append(
                (
                    float(seg.t[i] + s * (seg.t[i + 1] - seg.t[i])),
                    float(seg.x[i, 1] + s * (seg.x[i + 1, 1] - seg.x[i, 1])),
                )
            )
    return out


@case(
    "extreme_long_horizon",
    "extremes",
    "conservative runner for 1e3 s (20 s quick): a stable passive pronk; the paper's unstable gait falls after ~15 s",
)
def _extreme_long(result: CaseResult, quick: bool) -> None:
    h, eps = 1e-3, 1e-4
    T = 20.0 if quick else 1000.0
    model = pronk(STABLE_PRONK["params"])
    x0 = model_state(model, "aerial", STABLE_PRONK["apex"])
    stride = 1 if quick else 20  # checks on every 20th point over 1e6 steps keep the case to minutes
    # energy drift over the first 5 s, extrapolated linearly (RK4 drifts, it is not symplectic)
    short = simulate(model.system, x0, "aerial", 5.0, h, eps)
    E5 = energies(model.system, short)[1]
    d5 = float(np.max(np.abs(E5 - E5[0])))
    period = 0.34892597063684405  # the orbit's period from the same `legsim orbit` run
    bound_e = 2.0 * d5 * T / 5.0 + 1e-12
    ex = simulate(model.system, x0, "aerial", T, h, eps, max_transitions=int(5 * T / period) + 10)
    result.main_run(ex)
    result.add(
        execution_checks(
            model.system,
            ex,
            eps,
            energy="conservative",
            energy_tol=bound_e,
            bound=4 * (T / period + 1),
            bound_why=f"4 per stride of {period:.4g} s",
            stride=stride,
        )
    )
    energy = energy_of(model.system)
    jumps = max(abs(energy(tr.target, tr.state_after) - energy(tr.source, tr.state_before)) for tr in ex.transitions)
    result.add(Check("energy kept by every transition", jumps <= 1e-9, f"largest change at a transition {jumps:.2g} J"))
    apexes = apex_heights(ex)
    last_z = apexes[-1][1] if apexes else math.nan
    # every stride holds four strips of at most h + eps each: the relaxed strides are that much longer
    least = T / (period + 4 * (h + eps)) - 2
    ok = len(apexes) >= least and abs(last_z - STABLE_PRONK["apex"]["z"]) <= 1e-3
    result.add(
        Check(
            "stays on the gait",
            ok,
            f"{len(apexes)} apexes (>= {least:.0f}), the last at z = {last_z:.6f} m (start 1 m)",
        )
    )
    _ts, es = energies(model.system, ex, stride)
    drift = float(np.max(np.abs(es - es[0])))
    result.numbers.update({"energy_drift_J": drift, "energy_drift_bound_J": bound_e, "strides": len(apexes)})
    # The paper's gait: unstable, multiplier 5.86 per stride of 0.916 s. A perturbation of the
    # size of one stride's integration error (< 1e-6 at h = 1e-3, eps = 1e-2) needs
    # ln(1e5)/ln(5.86) = 6.5 strides to reach 0.1: it must survive at least 6 strides, then fall
    # with an honest status.
    slip = build("slip", {"psi": PAPER_SLIP_PSI})
    paper = simulate(
        slip.system,
        model_state(slip, "flight"),
        "flight",
        1000.0 if not quick else 60.0,
        h,
        1e-2,
        max_transitions=10**5,
    )
    falls = ("model_breakdown", "halving_exhausted", "reset_outside_domain")
    result.add(execution_checks(slip.system, paper, 1e-2, status=falls, energy="conservative", energy_tol=1e-6))
    strides = sum(tr.name.startswith("liftoff") for tr in paper.transitions)
    result.add(
        Check(
            "paper gait survives >= 6 strides",
            strides >= 6,
            f"{strides} strides, fell at t = {paper.t_end:.4g} s ({paper.status})",
        )
    )
    result.numbers.update({"paper_gait_survives_s": paper.t_end, "paper_gait_end": paper.status})
    result.outcome = (
        f"stable pronk {ex.status} at {ex.t_end:g} s, {len(apexes)} strides, |dE| <= {drift:.2g} J; "
        f"paper SLIP gait falls at {paper.t_end:.3g} s"
    )


@case("extreme_on_guard", "extremes", "initial states exactly on a guard (and one inside a strip)")
def _extreme_on_guard(result: CaseResult, quick: bool) -> None:
    g, c, h, eps = 9.81, 0.5, 1e-3, 1e-4
    ball = build("bouncing_ball", {"g": g}, {"floor": {"restitution": c}})

    def run(system, x0, mode, T, *, eps=eps, bound, why, control=None, energy=None):
        # the paper's relaxed execution at the guard (the ball's continuation would end its
        # resting chatter at once: checked below)
        ex = simulate(
            system, x0, mode, T, h, eps, control=control, max_transitions=int(2 * bound) + 10, continuation=False
        )
        result.add(
            execution_checks(
                system, ex, eps, control=control, bound=bound, bound_why=why, energy=energy, energy_tol=1e-9
            )
        )
        return ex

    floor = transition_floor(h, eps, accel=g)
    # at rest exactly on the floor: the corner z = zd = 0 of the guard max(z, zd); stays at rest
    ex = run(
        ball.system, [0.0, 0.0], "flight", 0.5, bound=0.5 / floor + 1, why=f"T/{floor:.3g} s", energy="dissipative"
    )
    result.add(ball_rest_check(ex, c, g, eps, 0.0, 0.5))
    main = ex
    # by default the ball at rest on the floor crosses at t0 and, the next crossing ending a
    # flight of one landing step and strip (<= h + eps), rests there
    rest = simulate(ball.system, [0.0, 0.0], "flight", 0.5, h, eps)
    names = [tr.name for tr in rest.transitions]
    ok = names == ["bounce", "rest"] and rest.transitions[0].time == 0.0 and bool(np.all(rest.final_state == 0.0))
    result.add(
        Check(
            "rests at once by default", ok, f"transitions {names}, final {rest.final_mode} {rest.final_state.tolist()}"
        )
    )
    # on the floor moving down: bounces at t = 0 exactly, then flies 2 c v / g
    ex = run(ball.system, [0.0, -1.0], "flight", 0.15, bound=3, why="a bounce at 0, one at 2 c/g", energy="dissipative")
    first = ex.transitions[0] if ex.transitions else None
    ok = first is not None and first.time == 0.0 and np.allclose(first.state_after, [0.0, c], atol=1e-15)
    result.add(
        Check(
            "bounces at t0",
            ok,
            f"first transition at {first.time if first else math.nan} s -> "
            f"{first.state_after.tolist() if first else None}",
        )
    )
    result.add(ball_flight_checks(ex, g, eps, resolved=0.0))
    # on the floor moving up: no transition at t = 0, lands at 2 v / g exactly
    ex = run(ball.system, [0.0, 1.0], "flight", 0.25, bound=1, why="one landing", energy="dissipative")
    ok = len(ex.transitions) == 1 and abs(ex.transitions[0].time - 2.0 / g) <= 1e-12
    landed = ex.transitions[0].time if ex.transitions else math.nan
    result.add(Check("leaves the guard", ok, f"lands at {landed:.15g} s, 2 v/g = {2 / g:.15g}"))
    # inside the strip (half of eps below the floor, moving down): crosses at t0, held eps/2
    ex = run(ball.system, [-0.5 * eps, -1.0], "flight", 0.15, bound=3, why="a bounce at 0, one at 2 c/g")
    first = ex.transitions[0] if ex.transitions else None
    ok = first is not None and first.time == 0.0 and abs(first.exit_time - 0.5 * eps) <= 1e-15
    result.add(
        Check(
            "starts in the strip",
            ok,
            f"crossed at {first.time if first else math.nan}, held to "
            f"{first.exit_time if first else math.nan:.3g} s (eps/2 = {eps / 2:g})",
        )
    )
    # two tanks with tank 2 exactly at its threshold: switches at once, then exact
    tanks = build("two_tanks")
    x0 = np.array([1.0, 0.0])
    ex = run(tanks.system, x0, "q1", 3.0, bound=3.0 / transition_floor(h, eps, rate=0.5) + 1, why="T/floor")
    ok = bool(ex.transitions) and ex.transitions[0].time == 0.0 and ex.transitions[0].target == "q2"
    result.add(
        Check("tank switches at t0", ok, f"first switch at {ex.transitions[0].time if ex.transitions else None}")
    )
    result.add(tank_switch_checks(ex, tanks.reference, x0, 2))
    # the circle started on the plane, tangent to it: never crosses
    circle = build("circular_flow")
    ex = run(circle.system, [1.0, 0.0], "inside", 3.0, bound=0, why="tangent at t0, inside after")
    err = float(np.max(np.abs(ex.final_state - circle.reference.state(np.array([1.0, 0.0]), 3.0))))
    result.add(Check("circle from the plane", err <= 1e-9, f"no switch, |x(3) - exact| = {err:.2g}"))
    # the digital controller at the corner (0, 0) of its two guards: both crossed at t0
    dc = build("digital_control", {}, {"boost": {"setpoint": 2.0}})
    ex = run(dc.system, [0.0, 0.0], "0", 1.0, bound=2, why="each threshold once")
    held = sum(tr.exit_time - tr.time for tr in ex.transitions)
    warp = float(np.max(np.abs(ex.final_state - dc.reference.with_initial("0", [0.0, 0.0]).state(1.0 - held))))
    ok = ex.mode_sequence == ["0", "1", "3"] and ex.transitions[0].time == 0.0 and warp <= 1e-9
    result.add(
        Check(
            "corner at t0",
            ok,
            f"path {'->'.join(ex.mode_sequence)}, first at {ex.transitions[0].time} s, exact up to holds to {warp:.2g}",
        )
    )
    result.main_run(main)
    result.outcome = "ball at rest / moving in / out / inside the strip; tanks; circle; digital corner"


@case("extreme_corner", "extremes", "states near the corner of two guards: digital control within 1e-9 of the corner")
def _extreme_corner(result: CaseResult, quick: bool) -> None:
    dc = build("digital_control", {}, {"boost": {"setpoint": 2.0}})
    rng = np.random.default_rng(3)
    n = 6 if quick else 40
    h, eps, T = 1e-2, 1e-6, 1.5
    finals, main, agree = [], None, 0
    for k in range(n):
        d = rng.uniform(0.0, 1e-9, 2)
        x0 = np.array([-1.0, -1.0]) - d
        ex = simulate(dc.system, x0, "0", T, h, eps, max_transitions=10)
        main = main or ex
        result.add(execution_checks(dc.system, ex, eps, bound=2, bound_why="each threshold once"))
        ref = dc.reference.with_initial("0", x0)
        held = sum(tr.exit_time - tr.time for tr in ex.transitions)
        warp = float(np.max(np.abs(ex.final_state - ref.state(T - held))))
        # the quantity with the smaller offset crosses first: xi1 first means 0 -> 1 -> 3
        expected = ["0", "1", "3"] if d[0] < d[1] else ["0", "2", "3"]
        agree += ex.mode_sequence == expected
        result.add(Check(f"exact up to holds (#{k})", warp <= 1e-9, f"|x(T) - x_exact(T - held)| = {warp:.2g}"))
        finals.append(ex.final_state)
    result.add(Check("first crossing = the closer threshold", agree == n, f"{agree}/{n} paths as the offsets say"))
    spread = float(np.max(np.ptp(np.array(finals), axis=0)))
    # every execution is the exact one paused for its two strips (eps - depth + the landing step
    # each, < 2 (h + eps)), so the final states differ by at most the speed times that
    ok = spread <= 2 * (h + eps) * 2.0
    result.add(
        Check("paths meet again", ok, f"final states within {spread:.2g} of each other (<= 2 (h + eps) x speed 2)")
    )
    assert main is not None  # set by the loop above, which runs at least once
    result.main_run(main)
    result.outcome = f"{n} starts within 1e-9 of the corner: both paths, final spread {spread:.2g}"
