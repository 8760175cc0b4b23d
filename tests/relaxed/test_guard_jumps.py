"""A guard that jumps past its strip (discontinuous in the state): crossed where it jumps by a
mode that declares ``crosses_jumps`` (counted in ``guard_jumps``); a run's end (halving_exhausted) otherwise.

The model: a point drifting at 1 m/s from x = 0, whose guard is +1 before x = C and -1 from
there on, so that it jumps past any strip at t = C. The closed form: the crossing is at t = C,
to the rounding of the step that brackets it.
"""

import pytest

from legsim import HybridSystem, Mode, ModeFunctions, Transition, model_function
from legsim.relaxed import simulate

C = 0.3
EPS = 1e-4


@model_function
def drift(t, x, u, p, dx):
    dx[0] = 1.0


@model_function
def step_guard(t, x, u, p, g):
    g[0] = 1.0 if x[0] < p[0] else -1.0


@model_function
def ramp_guard(t, x, u, p, g):
    g[0] = p[0] - x[0]


@model_function
def kept(e, t, x, u, p, out):
    out[0] = x[0]


def system(guard, crosses_jumps: bool) -> HybridSystem:
    before = Mode(1, names=("x",), functions=ModeFunctions(drift, guard, kept, params=[C], crosses_jumps=crosses_jumps))
    after = Mode(1, names=("x",), functions=ModeFunctions(drift, params=[C]))
    return HybridSystem({"before": before, "after": after}, [Transition("before", "after", name="jump")], name="jumper")


@pytest.mark.parametrize("python", [False, True], ids=["compiled", "interpreted"])
def test_a_guard_that_jumps_is_crossed_where_it_jumps_and_counted(python):
    ex = simulate(system(step_guard, True), [0.0], "before", 1.0, 0.01, EPS, "rk4", python=python)
    assert ex.status == "finished"
    (tr,) = ex.transitions
    assert tr.name == "jump" and tr.target == "after"
    assert abs(tr.time - C) < 1e-15  # the bracket closes to the rounding of t
    assert tr.exit_time == tr.time  # past its strip: left at once, no time held
    assert tr.depth == 1.0  # the guard's value past the jump, beyond eps
    assert ex.counters["guard_jumps"] == 1
    assert not ex.warnings  # located to rounding, closer than any strip: nothing to vouch for
    assert abs(ex.final_state[0] - 1.0) < 1e-12


def test_a_continuous_guard_crosses_there_too_within_its_strip():
    """The same event with a continuous guard (C - x) is crossed within eps of C, as paper 000's
    strip says, and is no jump."""
    ex = simulate(system(ramp_guard, True), [0.0], "before", 1.0, 0.01, EPS, "rk4")
    (tr,) = ex.transitions
    assert abs(tr.time - C) < EPS and 0.0 <= tr.depth <= EPS
    assert "guard_jumps" not in ex.counters  # counted only where a transition was crossed at a jump


@pytest.mark.parametrize("python", [False, True], ids=["compiled", "interpreted"])
def test_without_crosses_jumps_the_run_ends_at_the_jump_naming_the_transition(python):
    ex = simulate(system(step_guard, False), [0.0], "before", 1.0, 0.01, EPS, "rk4", python=python)
    assert ex.status == "halving_exhausted"
    assert abs(ex.t_end - C) < 1e-15
    assert "jump" in ex.message and not ex.transitions
