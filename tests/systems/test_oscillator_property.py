"""Property-based: the forced oscillator with a stop from random parameters and states keeps the
stress suite's invariants, agrees with its exact reference up to the first impact, and an
undamped, unforced oscillator with an elastic stop conserves its energy.

CI runs a dozen examples per property; LEGSIM_FULL=1 runs 150."""

import math
import os

import numpy as np
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st

from legsim import simulate, stress
from legsim.systems.oscillator import OscillatorReference, forcing, make_system

FULL = os.environ.get("LEGSIM_FULL") == "1"
SETTINGS = settings(max_examples=150 if FULL else 12, deadline=None, derandomize=not FULL)


def log_uniform(lo, hi):
    return st.floats(math.log10(lo), math.log10(hi)).map(lambda e: 10.0**e)


@SETTINGS
@given(
    omega=st.floats(0.5, 3.0),
    damping=st.floats(0.0, 0.9),
    c=st.floats(0.0, 1.0),
    x_max=st.floats(-1.0, 1.0),
    gap=st.floats(0.0, 2.0),
    xd0=st.floats(-3.0, 3.0),
    amplitude=st.floats(0.0, 2.0),
    frequency=st.floats(0.0, 3.0),
    h=log_uniform(1e-3, 1e-2),
    eps=log_uniform(1e-5, 1e-2),
)
# At rest on a stop at the spring's equilibrium with no net force: the reference must not search
# a flight whose gap x - x_max is zero throughout (its bisection would never return).
@example(omega=2.0, damping=0.1, c=0.5, x_max=0.0, gap=0.0, xd0=0.0, amplitude=0.0, frequency=0.0, h=1e-3, eps=1e-4)
@example(omega=2.0, damping=0.1, c=0.0, x_max=0.25, gap=0.0, xd0=0.0, amplitude=1.0, frequency=0.0, h=1e-3, eps=1e-4)
def test_oscillator_keeps_the_invariants_and_its_first_impact(
    omega, damping, c, x_max, gap, xd0, amplitude, frequency, h, eps
):
    a = damping * omega  # sub-critical, as the reference needs
    # No (near-)undamped resonance: the reference's closed form would cancel a particular
    # amplitude of amplitude / (2 a Omega) against its homogeneous part (it refuses beyond 1e8).
    assume(not (a < 1e-6 and abs(frequency - omega) < 1e-3))
    x0 = x_max - gap
    system = make_system(omega, a, x_max, c)
    control = forcing(amplitude, frequency)
    T = 4.0
    ex = simulate(system, [x0, xd0], "free", T, h, eps, control=control, max_transitions=10**5)
    xs = np.concatenate([s.x for s in ex.segments])
    # the stop's guard max(x_max - x, -xd) accelerates at most at |U| + omega^2 max|x| + 2 a max|xd|
    acc = amplitude + omega**2 * float(np.max(np.abs(xs[:, 0]))) + 2 * a * float(np.max(np.abs(xs[:, 1])))
    floor = stress.transition_floor(h, eps, accel=acc, rate=float(np.max(np.abs(xs[:, 1]))))
    checks = stress.execution_checks(system, ex, eps, control=control, bound=T / floor + 1, bound_why="T/floor")
    assert all(ch.passed for ch in checks), [f"{ch.name}: {ch.detail}" for ch in checks if not ch.passed]
    # before its first impact the run is a plain RK4 solution of eq. (28): compare with the
    # reference on the steps before the first strip
    ref = OscillatorReference(omega, a, x_max, c, 1.0, amplitude, frequency, x0, xd0)
    seg = ex.segments[0]
    err = float(np.max(np.abs(seg.x[:, 0] - ref.position(seg.t))))
    # RK4's global error: about (omega_max h)^4 T / 100 per unit amplitude, generously
    scale = max(1.0, float(np.max(np.abs(xs))))
    w = max(omega, frequency)
    assert err <= 10 * (w * h) ** 4 * T * scale + 1e-9, err
    impacts = ref.impact_times(seg.t[-1] + 1e-9)
    if ex.transitions and len(impacts) and impacts[0] > 1e-6:
        # the first relaxed crossing is the first exact impact, up to RK4's error in position
        # turned into time by the impact speed (and the crossing tolerance 1e-9 eps)
        v = abs(float(ex.transitions[0].state_before[1]))
        if v > 1e-2:
            assert abs(ex.transitions[0].time - impacts[0]) <= (10 * (w * h) ** 4 * T * scale + 1e-9 * eps) / v + 1e-9


@SETTINGS
@given(
    omega=st.floats(0.5, 3.0),
    x_max=st.floats(0.1, 1.0),
    x0=st.floats(-1.0, 0.0),
    xd0=st.floats(-3.0, 3.0),
    h=log_uniform(1e-3, 1e-2),
)
def test_undamped_oscillator_with_elastic_stop_conserves_energy(omega, x_max, x0, xd0, h):
    system = make_system(omega, 0.0, x_max, 1.0)
    eps, T = 1e-6, 6.0
    ex = simulate(system, [x0, xd0], "free", T, h, eps, max_transitions=10**4)
    E0 = system.energy("free", np.array([x0, xd0]))
    # RK4's energy error on a harmonic oscillator: (omega h)^6/72 per step relative, (omega h)^5 T omega/72
    # in total; the impacts keep the speed exactly (c = 1)
    tol = (omega * h) ** 5 * omega * T / 72 * E0 * 10 + 1e-12
    checks = stress.execution_checks(
        system,
        ex,
        eps,
        energy="conservative",
        energy_tol=tol,
        bound=T * omega / math.pi + 2,
        bound_why="at most one impact per half period",
    )
    assert all(ch.passed for ch in checks), [f"{ch.name}: {ch.detail}" for ch in checks if not ch.passed]
