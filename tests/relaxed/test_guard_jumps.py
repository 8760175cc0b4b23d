"""A guard that jumps past its strip (discontinuous in the state): crossed where it jumps by a
mode that declares ``crosses_jumps`` (counted in ``guard_jumps``); a run's end (halving_exhausted) otherwise.

The model: a point drifting at 1 m/s from x = 0, whose guard is +1 before x = C and -1 from
there on, so that it jumps past any strip at t = C. The closed form: the crossing is at t = C,
to the rounding of the step that brackets it.
"""

import dataclasses

import numpy as np
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


@pytest.mark.parametrize("python", [False, True], ids=["compiled", "interpreted"])
def test_a_held_input_releases_a_stuck_mass_at_the_first_sample_where_the_held_force_pulls_away(python):
    """Under a zero-order hold the input is sampled at each step's start and held over the step,
    so a guard that reads it (the forced oscillator's release, paper 000 Table I Example 2) jumps
    at the samples, not between them. The release must come at the first sample (a stored point
    of the stuck visit) where the sampled force turns the stop's guard, u / m - omega^2 x, negative:
    not later, and the run must not stop there."""
    from legsim.systems import oscillator as osc

    example = osc.EXAMPLES["ex2"]
    plant = osc.make_system(example["omega"], example["a"], example["x_max"], example["c"])
    held = dataclasses.replace(osc.forcing(example["amplitude"], example["frequency"]), hold=True)
    ex = simulate(plant, [example["x0"], example["xd0"]], "free", 4.0, 1e-2, EPS_EX2, "rk4", held, python=python)
    assert ex.status == "finished", ex.message
    release = next(tr for tr in ex.transitions if tr.name == "release")
    (stuck,) = [s for s in ex.segments if s.mode == "stuck" and s.t_start < release.time]
    u = example["amplitude"] * np.cos(example["frequency"] * stuck.t)
    guard = u / example.get("mass", 1.0) - example["omega"] ** 2 * stuck.x[:, 0]
    assert np.all(guard[:-1] >= 0.0)  # the stop pushes at every earlier sample
    assert guard[-1] < -EPS_EX2  # the sample the release is taken at: past the strip, a jump
    assert release.time == stuck.t[-1] and release.exit_time == release.time
    assert ex.counters["guard_jumps"] >= 1
    assert np.all(np.diff(stuck.t[1:-1]) == pytest.approx(1e-2, abs=1e-12))  # full steps: the hold's samples


EPS_EX2 = 1e-5
