"""Minimal reproductions of the core bugs the stress suite found (docs/stress.md, "Findings"):
they keep the core's fixes in place."""

import math

import numpy as np

from legsim import HybridSystem, Mode, Transition, simulate
from legsim.errors import ModelBreakdown
from legsim.systems import bouncing_ball, circular_flow


def test_a_grazing_excursion_is_crossed_twice_and_the_state_moves_on():
    # radius 1 + 1e-6: out through x1 = 1 and back 2.8e-3 s later, inside one step of 1e-2 s
    system = circular_flow.make_system(1.0, 1.0)
    x0 = np.array([0.0, 1.0 + 1e-6])
    ex = simulate(system, x0, "inside", 3.0, 1e-2, 1e-3, max_transitions=50)
    assert [tr.name for tr in ex.transitions] == ["cross", "return"]
    exact = circular_flow.CircularReference(1.0, 1.0, tuple(x0)).state(x0, 3.0)
    held = sum(tr.exit_time - tr.time for tr in ex.transitions)
    assert np.max(np.abs(ex.final_state - exact)) <= held + 1e-9  # speed 1: the holds only


def test_segment_times_strictly_increase_in_a_resting_chatter():
    # The paper's relaxed execution (continuation=False): past its Zeno time the ball chatters.
    system = bouncing_ball.make_system(restitution=0.5)
    ex = simulate(system, [1.0, 0.0], "flight", 2.7, 1e-3, 1e-4, continuation=False)
    assert len(ex.transitions) > 1000
    assert all(np.all(np.diff(seg.t) > 0) for seg in ex.segments)
    # and therefore dense output is finite everywhere
    for seg in ex.segments:
        assert np.all(np.isfinite(seg.interpolate(seg.t)))


def test_a_reset_that_raises_model_breakdown_ends_the_run_with_that_status():
    def reset(x):
        if x[0] < 0.5:
            raise ModelBreakdown("the leg swung into the ground")
        return x.copy()

    system = HybridSystem(
        {"a": Mode(1, lambda t, x, u: np.array([-1.0]))}, [Transition("a", "a", lambda x: x[0], reset)]
    )
    ex = simulate(system, [1.0], "a", 3.0, 0.01, 1e-3)
    assert ex.status == "model_breakdown" and "swung into the ground" in ex.message
    assert math.isclose(ex.t_end, 1.0, abs_tol=0.02)
