"""The decision rules shared by the Python loop and the compiled kernel, on closed forms."""

import math

import numpy as np
import pytest

from legsim.relaxed import crossing_on_step, rules
from legsim.relaxed.stages import hermite_point, hermite_slope


def test_the_crossing_of_a_smooth_guard_is_found_to_the_tolerance_past_the_guard():
    # g(s) = 1 - 4 s^2 crosses at s = 1/2; the point returned is on the guard's far side.
    s, evals, converged = crossing_on_step(lambda s: 1.0 - 4.0 * s * s, 1.0, -3.0, 1e-12)
    assert converged and s >= 0.5 and 1.0 - 4.0 * s * s >= -1e-12 and s - 0.5 < 1e-12
    assert evals < 15


#: Curved guards along a step (fraction s in [0, 1]), each crossing once.
CURVED_GUARDS = {
    "convex": lambda s: math.exp(-4.0 * s) - 0.3,
    "concave": lambda s: 0.5 - 0.2 * s - s**3,
    "quadratic": lambda s: 1.0 - 3.0 * s + 1.2 * s * s,
    "flat, then steep": lambda s: 1.0 - 1.5 * s**6,
    "a foot's height": lambda s: 0.05 - 0.3 * s + 0.2 * math.sin(1.7 * s) ** 2,
}


@pytest.mark.parametrize("name", CURVED_GUARDS)
def test_the_search_converges_superlinearly_on_curved_guards(name):
    # Bisection shrinks [0, 1] to 1e-13 in log2(1e13) = 43 evaluations; Illinois' false position,
    # superlinear, takes at most 12 on these guards.
    g = CURVED_GUARDS[name]
    tol = 1e-13
    s, evals, converged = crossing_on_step(g, g(0.0), g(1.0), tol)
    assert converged and -tol <= g(s) <= 0.0
    assert evals <= 12


def test_a_jump_is_bracketed_and_its_domain_side_returned_unconverged():
    s, _, converged = crossing_on_step(lambda s: 1.0 if s < 0.3 else -1.0, 1.0, -1.0, 1e-12)
    assert not converged and s < 0.3 and 0.3 - s < 1e-15


def test_an_end_already_at_the_root_is_straddled_at_once():
    # The guard is ~0 at s = 1 (to rounding): the search must not crawl towards it.
    _s, evals, converged = crossing_on_step(lambda s: 1e-16 * (1.0 - s) - 1e-30, 1e-16, -1e-30, 0.0)
    assert converged and evals < 60


def test_trivial_brackets_need_no_evaluation():
    assert crossing_on_step(lambda s: math.nan, 0.0, -1.0, 1e-9) == (0.0, 0, True)
    assert crossing_on_step(lambda s: math.nan, 1.0, -1e-12, 1e-9) == (1.0, 0, True)


def test_a_nan_inside_the_bracket_ends_the_search_on_the_domain_side():
    s, evals, converged = crossing_on_step(lambda s: math.nan, 1.0, -1.0, 1e-9)
    assert (s, evals, converged) == (0.0, 1, False)


@pytest.mark.parametrize("err", [0.5, 1e-9, 0.0])
def test_accepted_steps_grow_by_at_most_max_factor_and_never_after_a_rejection(err):
    grown = rules.proposed_step(0.1, err, -0.2, False)
    assert grown <= rules.MAX_FACTOR * 0.1 + 1e-15
    assert rules.proposed_step(0.1, err, -0.2, True) <= 0.1


def test_a_rejected_step_shrinks_by_the_safety_rule_within_bounds():
    assert rules.rejected_step(1.0, 2.0**5, -0.2) == pytest.approx(rules.SAFETY * 0.5)
    assert rules.rejected_step(1.0, 1e30, -0.2) == rules.MIN_FACTOR


def test_a_shortened_landing_keeps_the_larger_proposal():
    assert rules.kept_proposal(0.1, 1e-6, True, False) == 0.1
    assert rules.kept_proposal(0.1, 1e-6, True, True) == 1e-6
    assert rules.kept_proposal(0.1, 0.2, False, False) == 0.2


def test_the_aim_falls_back_to_halving_outside_the_step():
    assert rules.aimed_step(0.2, 0.25, True) == 0.05
    assert rules.aimed_step(0.2, 1.0, True) == 0.1
    assert rules.aimed_step(0.2, 0.25, False) == 0.1


def test_the_hermite_interpolant_reproduces_a_cubic_and_holds_a_held_coordinate():
    # x(t) = t^3 on [1, 3]: ends 1, 27, slopes 3, 27; a second coordinate held at 0.1 + 2e-17.
    held = 0.1 + 2e-17
    x0, d0, x1, d1 = np.array([1.0, held]), np.array([3.0, 0.0]), np.array([27.0, held]), np.array([27.0, 0.0])
    point, slope = np.empty(2), np.empty(2)
    # At s = 0.325, 0.4 or 0.65 the weighted sum of the ends, w0 x0 + w2 x1, misses the held value
    # by a float spacing.
    for s in (0.0, 0.3, 0.325, 0.4, 0.5, 0.65, 1.0):
        hermite_point(x0, d0, x1, d1, 2.0, s, point)
        hermite_slope(x0, d0, x1, d1, 2.0, s, slope)
        assert point[0] == pytest.approx((1.0 + 2.0 * s) ** 3, rel=1e-14)
        assert slope[0] == pytest.approx(3 * (1.0 + 2.0 * s) ** 2, rel=1e-14)
        assert point[1] == held and slope[1] == 0.0


def test_the_strip_is_left_after_eps_minus_tau():
    assert rules.strip_exit_time(2.0, 1e-3, 4e-4) == pytest.approx(2.0006, abs=1e-15)
    assert rules.entered_in_strip(-1e-9, 1.0) is False and rules.entered_in_strip(-2e-9, 1.0) is True
