"""Minimal reproductions of the core bugs the stress suite found (strict xfail until the core is
fixed; the fixes are described in docs/stress.md, "Findings"), and of what already holds."""

import math

import numpy as np
import pytest

from legsim import HybridSystem, Mode, Transition, simulate
from legsim.errors import ModelBreakdown
from legsim.systems import bouncing_ball, circular_flow


@pytest.mark.xfail(strict=True, reason="core: crossing_on_step accepts a strip point with 0 < g <= tol (the domain "
                                       "side); the identity reset then puts the state past the complementary guard, "
                                       "and every later step crosses again at its start")
def test_a_grazing_excursion_is_crossed_twice_and_the_state_moves_on():
    # radius 1 + 1e-6: out through x1 = 1 and back 2.8e-3 s later, inside one step of 1e-2 s
    system = circular_flow.make_system(1.0, 1.0)
    x0 = np.array([0.0, 1.0 + 1e-6])
    ex = simulate(system, x0, "inside", 3.0, 1e-2, 1e-3, max_transitions=50)
    assert [tr.name for tr in ex.transitions] == ["cross", "return"]
    exact = circular_flow.CircularReference(1.0, 1.0, tuple(x0)).state(x0, 3.0)
    held = sum(tr.exit_time - tr.time for tr in ex.transitions)
    assert np.max(np.abs(ex.final_state - exact)) <= held + 1e-9  # speed 1: the holds only


def test_the_grazing_freeze_is_the_strip_point_on_the_domain_side():
    # What the bug looks like today: the 'return' strip point lies on the domain side of its
    # guard (x1 - 1 > 0), so the 'cross' guard (1 - x1) is already past when 'inside' is entered.
    system = circular_flow.make_system(1.0, 1.0)
    ex = simulate(system, [0.0, 1.0 + 1e-6], "inside", 3.0, 1e-2, 1e-3, max_transitions=6)
    ret = [tr for tr in ex.transitions if tr.name == "return"]
    if len(ex.transitions) == 2:
        pytest.skip("fixed in the core")
    assert ret and ret[0].state_before[0] - 1.0 > 0.0
    assert ex.transitions[2].time == ret[0].exit_time  # crossed again at once, at the entry


@pytest.mark.xfail(strict=True, reason="core: _step_transition appends the strip point at t + s*dt, which rounds "
                                       "to t when s ~ 1e-16: two equal times in one segment")
def test_segment_times_strictly_increase_in_a_resting_chatter():
    system = bouncing_ball.make_system(restitution=0.5)
    ex = simulate(system, [1.0, 0.0], "flight", 2.7, 1e-3, 1e-4)
    assert all(np.all(np.diff(seg.t) > 0) for seg in ex.segments)
    # and therefore dense output is finite everywhere
    for seg in ex.segments:
        assert np.all(np.isfinite(seg.interpolate(seg.t)))


@pytest.mark.xfail(strict=True, reason="core: _transition wraps every exception of a reset in ModelError, "
                                       "ModelBreakdown included, instead of ending the run with model_breakdown")
def test_a_reset_that_raises_model_breakdown_ends_the_run_with_that_status():
    def reset(x):
        if x[0] < 0.5:
            raise ModelBreakdown("the leg swung into the ground")
        return x.copy()

    system = HybridSystem({"a": Mode(1, lambda t, x, u: np.array([-1.0]))},
                          [Transition("a", "a", lambda x: x[0], reset)])
    ex = simulate(system, [1.0], "a", 3.0, 0.01, 1e-3)
    assert ex.status == "model_breakdown" and "swung into the ground" in ex.message
    assert math.isclose(ex.t_end, 1.0, abs_tol=0.02)
