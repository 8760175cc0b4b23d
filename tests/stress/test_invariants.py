"""Every invariant of the stress suite can fail: each check is given an execution that breaks it
(built by hand from a good run) and must say so, and must pass the good run."""

import dataclasses
import math

import numpy as np
import pytest

from legsim import simulate, stress
from legsim.systems import bouncing_ball

EPS = 1e-3


@pytest.fixture(scope="module")
def good():
    system = bouncing_ball.make_system(restitution=0.5)
    ex = simulate(system, [1.0, 0.0], "flight", 1.2, 1e-3, EPS)  # three bounces, before the Zeno time
    assert len(ex.transitions) == 3
    return system, ex


def replaced(ex, **changes):
    return dataclasses.replace(ex, **changes)


def with_segment(ex, i, **changes):
    segs = list(ex.segments)
    segs[i] = dataclasses.replace(segs[i], **changes)
    return replaced(ex, segments=segs)


def test_the_good_run_passes_every_check(good):
    system, ex = good
    checks = stress.execution_checks(system, ex, EPS, energy="dissipative", energy_tol=1e-9, bound=3, bound_why="3")
    assert [c.name for c in checks] == [
        "status",
        "finite",
        "time increasing",
        "in relaxed domain",
        "resets in target domain",
        "energy non-increasing",
        "transition bound",
    ]
    assert all(c.passed for c in checks), [c.detail for c in checks if not c.passed]


def test_finite_fails_on_a_nan_state(good):
    _, ex = good
    x = ex.segments[1].x.copy()
    x[3, 1] = math.nan
    check = stress.check_finite(with_segment(ex, 1, x=x))
    assert not check.passed and "segment 1" in check.detail


def test_time_fails_on_a_repeated_time_and_on_a_strip_going_back(good):
    _, ex = good
    t = ex.segments[2].t.copy()
    t[5] = t[4]
    check = stress.check_time(with_segment(ex, 2, t=t))
    assert not check.passed and "segment 2" in check.detail
    strips = list(ex.strips)
    s = strips[0]
    strips[0] = dataclasses.replace(s, exit_time=s.time - 1e-3)
    assert not stress.check_time(replaced(ex, strips=strips)).passed
    # a run that says it finished but stopped short of t_final
    assert not stress.check_time(replaced(ex, t_final=ex.t_final + 1.0)).passed


def test_domain_fails_beyond_eps_and_holds_within_it(good):
    system, ex = good
    x = ex.segments[1].x.copy()
    x[4] = [-0.5 * EPS, -1.0]  # inside the strip: allowed
    assert stress.check_domain(system, with_segment(ex, 1, x=x), EPS).passed
    x[4] = [-2.0 * EPS, -1.0]  # past the strip
    check = stress.check_domain(system, with_segment(ex, 1, x=x), EPS)
    assert not check.passed and "bounce" in check.detail


def test_resets_fail_on_a_wrong_image_and_on_an_image_past_the_target_guard(good):
    system, ex = good
    trs = list(ex.transitions)
    tr = trs[0]
    trs[0] = dataclasses.replace(tr, state_after=tr.state_after + np.array([0.0, 1e-6]))
    check = stress.check_resets(system, replaced(ex, transitions=trs), EPS)
    assert not check.passed and "!= reset" in check.detail
    # an image past the floor while falling, and the strip point with it (reset keeps z)
    trs[0] = dataclasses.replace(tr, state_before=np.array([-0.1, -4.0]), state_after=np.array([-0.1, 2.0]))
    check = stress.check_resets(system, replaced(ex, transitions=trs), EPS)
    assert not check.passed and "past a guard" in check.detail


def test_energy_fails_when_it_rises_or_drifts(good):
    system, ex = good
    assert stress.check_energy(system, ex, "dissipative", 1e-9).passed
    assert not stress.check_energy(system, ex, "conservative", 1e-3).passed  # the bounces lose energy
    x = ex.segments[2].x.copy()
    x[-1, 1] *= 1.01  # a 1% faster point: more energy than before
    assert not stress.check_energy(system, with_segment(ex, 2, x=x), "dissipative", 1e-6).passed
    with pytest.raises(ValueError, match="conservative"):
        stress.check_energy(system, ex, "bounded", 1.0)


def test_transition_bound_fails_above_it_and_on_the_budget(good):
    _, ex = good
    assert stress.check_transition_bound(ex, 3, "three bounces").passed
    check = stress.check_transition_bound(ex, 2, "two")
    assert not check.passed and "3 transitions" in check.detail
    assert not stress.check_transition_bound(replaced(ex, status="max_transitions"), 10, "ten").passed


def test_status_and_order_checks():
    system = bouncing_ball.make_system()
    ex = simulate(system, [1.0, 0.0], "flight", 0.3, 1e-3, EPS, max_transitions=0)
    assert stress.check_status(ex).passed  # no impact before 0.45 s
    assert not stress.check_status(replaced(ex, status="halving_exhausted")).passed
    assert stress.check_order("o", [1.0, 0.5, 0.25], [1.0, 0.25, 0.0625], 1.9, 2.1).passed
    assert not stress.check_order("o", [1.0, 0.5, 0.25], [1.0, 0.5, 0.25], 1.9, 2.1).passed
    assert not stress.check_order("o", [1.0, 0.5], [1.0, 0.0], 0.0, 5.0).passed  # a zero error has no order


def test_step_floor_is_the_largest_step_inside_the_strip_halved():
    # a guard at rate 2 units/s, eps = 1e-3: steps <= 5e-4 s land in the strip; halving stops above 2.5e-4
    assert stress.step_floor(1.0, 1e-3, rate=2.0) == pytest.approx(2.5e-4)
    # from rest at acceleration 8: sqrt(2 eps / a) = 0.0158 s, halved
    assert stress.step_floor(1.0, 1e-3, accel=8.0) == pytest.approx(0.5 * math.sqrt(2e-3 / 8.0))
    assert stress.step_floor(1e-4, 1e-3, rate=2.0, accel=8.0) == 1e-4  # h itself when it is shorter


def test_transition_floor_is_the_step_floor_or_a_strip_whichever_is_shorter():
    assert stress.transition_floor(1.0, 1e-3, rate=2.0) == stress.step_floor(1.0, 1e-3, rate=2.0)
    # a strip of eps = 1e-3 s is shorter than the steps of 5e-3 s a slow guard allows
    assert stress.transition_floor(1.0, 1e-3, rate=0.1) == pytest.approx(1e-3 * (1 - 1e-9), rel=1e-15)
    assert stress.transition_floor(1.0, 1e-3, rate=0.1) < 1e-3


def test_the_accumulation_check_fails_on_a_missing_misplaced_or_misnamed_warning():
    system = bouncing_ball.make_system(restitution=0.5)
    ex = simulate(system, [1.0, 0.0], "flight", 2.0, 1e-3, EPS, continuation=False)  # past t_zeno = 1.355 s
    (warning,) = ex.warnings
    t = warning.time
    assert stress.check_accumulation(ex, [("bounce", t, t)]).passed
    assert not stress.check_accumulation(ex, [("bounce", t + 1e-9, t + 1.0)]).passed  # misplaced
    assert not stress.check_accumulation(ex, [("land", t, t)]).passed  # another transition
    assert not stress.check_accumulation(replaced(ex, warnings=[]), [("bounce", t, t)]).passed  # missing
    assert not stress.check_accumulation(ex, []).passed  # not expected
    assert stress.check_accumulation(replaced(ex, warnings=[]), []).passed
    # the crossing it began at: the first whose flight is within the window and shrinking
    k = stress.first_accumulating_crossing(ex, "bounce", 1e-3 + EPS)
    assert ex.transitions[k].time == t
    assert stress.first_accumulating_crossing(ex, "other", 1e-3 + EPS) is None
