"""Property-based: the bouncing ball from random states, restitutions, gravities, steps and strip
widths keeps the stress suite's invariants (legsim.stress): finite states, time never going back,
states within eps of the floor's guard, reset images in the domain, energy never rising, a
derived bound on the number of transitions, exact flights, and rest after the Zeno time (the
paper's relaxed execution, and by default resting where the bounces accumulate).

CI runs a dozen examples per property; LEGSIM_FULL=1 runs 200."""

import math
import os

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from legsim import simulate, stress
from legsim.systems.bouncing_ball import BouncingBallReference, make_system

FULL = os.environ.get("LEGSIM_FULL") == "1"
SETTINGS = settings(max_examples=200 if FULL else 12, deadline=None, derandomize=not FULL)


def log_uniform(lo, hi):
    return st.floats(math.log10(lo), math.log10(hi)).map(lambda e: 10.0**e)


@SETTINGS
@given(
    z0=st.floats(0.0, 3.0),
    zd0=st.floats(-5.0, 5.0),
    c=st.floats(0.0, 0.95),
    g=st.floats(1.0, 20.0),
    h=log_uniform(1e-4, 5e-2),
    eps=log_uniform(1e-9, 1e-1),
)
def test_ball_keeps_the_invariants_through_and_past_its_zeno_time(z0, zd0, c, g, h, eps):
    system = make_system(g, c)
    ref = BouncingBallReference(g, c, z0, zd0)
    floor = min(stress.step_floor(h, eps, accel=g), eps * (1 - 1e-9))
    # past the Zeno time every transition costs at least `floor`: cap that part at 300 of them
    T = ref.zeno_time + min(ref.zeno_time - ref.first_impact + 0.1, 300 * floor)
    bound = (T - ref.first_impact) / floor + 1 if ref.first_impact < T else 0
    # The paper's relaxed execution (continuation=False): the bound and the rest band below are
    # its own; the default continuation is the next property.
    ex = simulate(system, [z0, zd0], "flight", T, h, eps, max_transitions=int(2 * bound) + 10, continuation=False)
    E0 = system.energy("flight", np.array([z0, zd0]))
    checks = stress.execution_checks(
        system, ex, eps, energy="dissipative", energy_tol=1e-9 * max(1.0, E0), bound=bound, bound_why="(T - t1)/floor"
    )
    checks.append(stress.ball_hold_check(ex, eps))
    if len(ex.transitions) >= 2:
        checks.append(stress.ball_flight_checks(ex, g, eps, resolved=1e-3))
    failed = [
        f"{c.name}: {c.detail}"
        for c in checks
        if not c.passed and not (c.name == "flights exact" and "0 flights" in c.detail)
    ]
    assert not failed, failed
    # past its Zeno time the ball rests: it never climbs above the rest band again
    if c < 1.0 and T - ref.zeno_time > 10 * (h + eps):
        late = ref.zeno_time + 0.5 * (T - ref.zeno_time)
        # the relaxed impacts lag the exact ones by at most h + eps each; only check once every
        # resolved impact (flight >= floor) has happened
        n_resolved = sum(1 for v in ref.impact_speeds(ref.zeno_time, 10_000) if 2 * c * v / g >= floor)
        if late > ref.zeno_time + n_resolved * (h + eps):
            rest = stress.ball_rest_check(ex, c, g, eps, late, T)
            assert rest.passed, rest.detail


@SETTINGS
@given(z0=st.floats(0.01, 2.0), c=st.floats(0.1, 0.9), eps=log_uniform(1e-10, 1e-2))
def test_ball_rests_by_default_at_the_crossing_the_accumulation_rule_names(z0, c, eps):
    # Its flights are exact (free fall is a cubic), 2 c^(k-1) v1 / g ending the k-th impact: the
    # rule rests it at the first crossing that ends one no longer than h + eps.
    g, h = 9.81, 1e-3
    system = make_system(g, c)
    ref = BouncingBallReference(g, c, z0, 0.0)
    T = 2.0 * ref.zeno_time
    k = stress.ball_rest_crossing(ref.impact_speed, c, g, h + eps)
    ex = simulate(system, [z0, 0.0], "flight", T, h, eps, max_transitions=1000)
    checks = stress.execution_checks(
        system, ex, eps, energy="dissipative", energy_tol=1e-9, bound=k, bound_why="1 + ceil(log(2 v1/(g w))/log(1/c))"
    )
    assert all(ch.passed for ch in checks), [f"{ch.name}: {ch.detail}" for ch in checks if not ch.passed]
    # on the floor, within the strip, at the crossing the rule names
    assert len(ex.transitions) == k and ex.transitions[-1].name == "rest" and ex.final_mode == "rest"
    assert abs(ex.final_state[0]) <= eps
    # no accumulation left unresolved; the strips' holds are reported where over 1% of the run
    held = sum(strip.exit_time - strip.time for strip in ex.strips)
    assert [w.kind for w in ex.warnings] == (["strip_hold"] if held > 0.01 * T else [])
