"""The loop of paper 000 Fig. 12: the nominal step restored after halving and after each
transition, guards on time and input crossed at their exact times, model breakdowns and nan
guards ending the run with the execution kept."""

from __future__ import annotations

import math

import numpy as np
import pytest

from legsim import HybridSystem, Mode, ModelError, Transition, simulate
from legsim.errors import ModelBreakdown
from legsim.systems import bouncing_ball as bb


def test_nominal_step_is_restored_after_halving_and_after_each_transition():
    # Fig. 12 step 3: a step shortened to land in a strip does not shrink the next
    # ones. The ball at h = 0.1 s with eps = 1e-4 m must halve to land (it falls 4 m/s * 0.1 s
    # = 0.4 m per step near the floor), and every flight after a bounce starts again at h.
    h = 0.1
    ex = simulate(bb.make_system(), [1.0, 0.0], "flight", 1.0, h, 1e-4)
    assert ex.counters["halvings"] > 0 and len(ex.transitions) >= 2
    for seg in ex.segments:
        if seg.t_end - seg.t_start > 3 * h:
            # Points: the segment's start (reset image), whole steps, then the step that was
            # halved into the strip and its guard point q.
            np.testing.assert_allclose(np.diff(seg.t[:3]), h, rtol=1e-12)


def still(t, x, u):
    return np.zeros(1)


def clock_system(guard, guard_args="t,x,u"):
    return HybridSystem(
        {"before": Mode(1, still), "after": Mode(1, still)},
        [Transition("before", "after", guard=guard, guard_args=guard_args, name="alarm")],
    )


@pytest.mark.parametrize("landing", ["halve", "aim"])
def test_a_time_dependent_guard_is_crossed_at_its_exact_time(landing):
    # Nothing moves: only the guard's own time dependence can trigger the transition, and the
    # crossing search on the interpolant must evaluate the guard at the interpolated time.
    ex = simulate(clock_system(lambda t, x, u: 1.0 - t), [0.0], "before", 2.0, 0.3, 1e-3, landing=landing)
    assert ex.mode_sequence == ["before", "after"]
    assert ex.transitions[0].time == pytest.approx(1.0, abs=1e-12)


def test_a_guard_on_the_input_sees_the_control_at_the_trial_time():
    # The guard is the input itself, u(t) = cos(t): it reaches zero at pi/2.
    ex = simulate(clock_system(lambda t, x, u: u), [0.0], "before", 2.0, 0.1, 1e-4, control=lambda t, x: math.cos(t))
    assert ex.transitions[0].time == pytest.approx(math.pi / 2, abs=1e-10)
    # The strip lasts eps - depth; the depth is measured in the guard's units at the landing.
    tr = ex.transitions[0]
    assert tr.exit_time == pytest.approx(tr.landing_time + 1e-4 - tr.depth, abs=1e-15)


def test_guard_args_is_validated():
    with pytest.raises(ModelError, match="guard_args must be 'x' or 't,x,u'"):
        Transition("a", "b", guard=lambda x: 1.0, guard_args="x,t")


def test_a_model_breakdown_ends_the_run_with_its_message_and_keeps_the_execution():
    def field(t, x, u):
        if x[0] > 0.5:
            raise ModelBreakdown("the body hit the ground")
        return np.ones(1)

    system = HybridSystem({"run": Mode(1, field)}, [])
    ex = simulate(system, [0.0], "run", 2.0, 0.01, 1e-3)
    assert ex.status == "model_breakdown"
    assert "the body hit the ground" in ex.message and "mode 'run'" in ex.message
    # Everything up to the last good step is kept: x = t there.
    assert 0.49 <= ex.t_end <= 0.5 + 1e-12
    assert ex.final_state[0] == pytest.approx(ex.t_end, abs=1e-12)


def test_under_error_control_a_breakdown_is_bracketed_from_the_steps_own_length():
    # The error control keeps steps near 1e-4 s (a fast wiggle) far below the largest step h = 1
    # s: a step that runs into the model's range is halved from its own length, ten times, so
    # the run stops within 1e-4 / 2^10 s of the boundary at t = 0.5, not at the first trial
    # shorter than h / 2^10.
    def field(t, x, u):
        if x[0] > 0.5:
            raise ModelBreakdown("past the boundary")
        return np.array([1.0, math.cos(2000.0 * t)])

    system = HybridSystem({"run": Mode(2, field)}, [])
    ex = simulate(system, [0.0, 0.0], "run", 2.0, 1.0, 1e-3, "dopri5", rtol=1e-9, atol=1e-12)
    assert ex.status == "model_breakdown"
    steps = np.diff(ex.segments[0].t)
    assert 1e-5 < np.median(steps) < 1e-3
    assert 0.5 - 1e-6 < ex.t_end <= 0.5


def test_a_nan_guard_after_the_first_ends_the_run_non_finite():
    # min([1.0, nan]) is 1.0 in Python: the second guard's nan must still be caught and named.
    system = HybridSystem(
        {"a": Mode(1, lambda t, x, u: np.ones(1))},
        [
            Transition("a", "a", guard=lambda x: 1.0, name="fine"),
            Transition("a", "a", guard=lambda x: math.nan if x[0] > 0.5 else 1.0, name="broken"),
        ],
    )
    ex = simulate(system, [0.0], "a", 2.0, 0.1, 1e-3)
    assert ex.status == "non_finite"
    assert "guard of transition broken is nan" in ex.message
    assert ex.t_end <= 0.5 + 1e-12
