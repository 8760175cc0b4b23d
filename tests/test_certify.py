"""Certified transitions of paper 004 Section V (legsim.certify)."""

import itertools
import math

import numpy as np
import pytest

from helpers.breaking_line import breaking_line
from legsim import HybridSystem, Mode, SimulationError, Transition
from legsim.certify import REASONS, certify
from legsim.systems.circular_flow import CircularReference
from legsim.systems.circular_flow import make_system as circular_flow
from legsim.systems.two_tanks import TwoTankReference
from legsim.systems.two_tanks import make_system as two_tanks


def corner():
    """A flow symmetric under x1 <-> x2 heading for the corner of two guards: from (0, 0) it
    reaches x1 = 1 and x2 = 1 at the same instant."""

    def f(t, x, u):
        return np.array([1.0 + 0.2 * x[1], 1.0 + 0.2 * x[0]])

    modes = {name: Mode(2, f) for name in ("box", "A", "B")}
    return HybridSystem(
        modes,
        [
            Transition("box", "A", lambda x: 1.0 - x[0], name="wall_x1"),
            Transition("box", "B", lambda x: 1.0 - x[1], name="wall_x2"),
        ],
        name="corner",
    )


def test_transversal_crossings_are_certified_and_bracket_the_true_switching_times():
    ref = CircularReference(1.0, 1.0)
    cert = certify(circular_flow(), "inside", [0.0, 1.5], 3.0, 0.1, "rk4")
    assert cert.certified
    assert [tr.name for tr in cert.transitions] == ["cross", "return"]
    assert all(tr.reason is None and tr.taken for tr in cert.transitions)
    # Exact crossing times of the circle of radius 1.5 with x1 = 1: asin(2/3) and pi - asin(2/3).
    exact = [ref.crossing_time(np.array([0.0, 1.5])), math.pi - math.asin(2 / 3)]
    for tr, t in zip(cert.transitions, exact, strict=True):
        # rk4 at h = 0.1 over 2.4 s: about 2e-6 of global error in the second crossing.
        assert tr.time == pytest.approx(t, abs=1e-5)
        assert tr.window[0] <= t <= tr.window[1]
    assert len(cert.levels) == 1  # no refinement needed


def test_grazing_point_is_refused_as_grazing():
    # The circle of radius 1 touches x1 = 1 at t = pi/2 without crossing: the computed
    # trajectory does not take the transition, the cone reaches the guard.
    cert = certify(circular_flow(), "inside", [0.0, 1.0], 3.0, 0.1, "rk4", max_refinements=3)
    assert not cert.certified
    (tr,) = cert.transitions
    assert (tr.name, tr.taken, tr.certified, tr.reason) == ("cross", False, False, "grazing")
    assert tr.time == pytest.approx(math.pi / 2, abs=1e-3)
    # Refining never separates it: the gap left by the method shrinks with the bound.
    gaps = [lv.separation / lv.bound for lv in cert.levels]
    assert len(gaps) == 4 and max(gaps) < 0.05


def test_a_near_miss_that_refinement_would_separate_is_a_refinement_limit():
    # Radius 1 - 1e-9: a real gap of 1e-9 that the bound (2e-8 at the last level) has not
    # yet resolved, but whose ratio to the bound grows with every refinement.
    cert = certify(circular_flow(), "inside", [0.0, 1.0 - 1e-9], 3.0, 0.1, "rk4", max_refinements=3)
    (tr,) = cert.transitions
    assert tr.reason == "refinement_limit"
    ratios = [lv.separation / lv.bound for lv in cert.levels]
    assert ratios[-1] > 4 * ratios[-2]


def test_guard_intersection_is_refused_and_a_nearby_crossing_certified_after_refinement():
    exact = certify(corner(), "box", [0.0, 0.0], 2.0, 0.1, "rk4", max_refinements=3)
    (tr,) = exact.transitions
    assert tr.reason == "intersecting_guards"
    assert sorted(tr.guards_met) == ["wall_x1", "wall_x2"]
    assert len(exact.levels) == 4
    # Offset by 3e-8 the flow reaches x2 = 1 first, 2.5e-8 from x1 = 1: at h = 0.1 the bound
    # (4e-8) keeps both guards in the cone, the refined h = 0.05 (bound 4.5e-9) separates them
    # (Algorithm 1: h := h / alpha until J_h is a singleton). The offset keeps both decisions
    # far from their thresholds, so the bound's rounding cannot move them.
    near = certify(corner(), "box", [0.0, 3e-8], 2.0, 0.1, "rk4", max_refinements=4)
    (tr,) = near.transitions
    assert tr.certified and tr.name == "wall_x2"
    assert near.levels[0].failure == "intersecting_guards" and len(near.levels) > 1


def test_symmetric_pronk_touchdown_is_a_guard_intersection():
    from legsim.scene import load_scene

    scene = load_scene("pronk")
    cert = certify(
        scene.model.system,
        scene.initial_mode,
        scene.initial_state,
        1.0,
        1e-2,
        "rk4",
        control=scene.model.control,
        max_refinements=1,
    )
    (tr,) = cert.transitions
    assert tr.reason == "intersecting_guards"
    assert sorted(tr.guards_met) == ["touchdown_left", "touchdown_right"]
    # Ballistic flight: the touchdown time is where z - leg cos(psi) reaches 0 from z = 1.1.
    leg, psi, z0, g = 1.0, math.pi / 5, 1.1, 9.81
    assert tr.time == pytest.approx(math.sqrt(2 * (z0 - leg * math.cos(psi)) / g), abs=1e-9)


def test_zeno_point_is_refused_as_zeno_after_certifying_more_transitions_at_each_refinement():
    ref = TwoTankReference(0.75, 0.5, 0.5)
    x0 = np.array([1.0, 1.0])
    cert = certify(two_tanks(), "q1", x0, 10.0, 0.05, "rk4", floor=1.0, max_refinements=3)
    *done, last = cert.transitions
    assert last.reason == "zeno" and not last.certified
    counts = [lv.certified for lv in cert.levels]
    assert all(a < b for a, b in itertools.pairwise(counts)), counts
    exact, modes = ref.switching_times("q1", x0, len(done))
    for tr, t, target in zip(done, exact, modes, strict=True):
        assert tr.certified and tr.target == target
        assert tr.time == pytest.approx(t, abs=1e-9)
        assert tr.window[0] <= t <= tr.window[1]
    assert last.time == pytest.approx(ref.zeno_time(x0), abs=0.01)


def test_reasons_are_the_documented_ones():
    assert REASONS == ("grazing", "intersecting_guards", "zeno", "refinement_limit", "t_final")


def test_bad_input_is_reported_by_name():
    system = circular_flow()
    with pytest.raises(SimulationError, match="alpha must be a number > 1"):
        certify(system, "inside", [0.0, 1.5], 1.0, 0.1, alpha=1.0)
    with pytest.raises(SimulationError, match="max_refinements must be an integer >= 0"):
        certify(system, "inside", [0.0, 1.5], 1.0, 0.1, max_refinements=-1)
    with pytest.raises(SimulationError, match="unknown mode 'nowhere'"):
        certify(system, "nowhere", [0.0, 1.5], 1.0, 0.1)
    with pytest.raises(SimulationError, match="h must be finite and > 0"):
        certify(system, "inside", [0.0, 1.5], 1.0, 0.0)


def test_a_clock_guard_on_t_is_certified_at_its_exact_time():
    # guard(t, x, u) = 1 - t does not depend on the state, so no error ball can blur it.
    system = HybridSystem(
        {"a": Mode(1, lambda t, x, u: np.array([-x[0]])), "b": Mode(1, lambda t, x, u: np.zeros(1))},
        [Transition("a", "b", lambda t, x, u: 1.0 - t, name="clock", guard_args="t,x,u")],
    )
    cert = certify(system, "a", [1.0], 2.0, 0.3, "rk4")
    (tr,) = cert.transitions
    assert tr.certified and tr.time == pytest.approx(1.0, abs=1e-12)
    # The true switch is at the computed time itself: the window is that instant, not (-inf, inf),
    # and the next mode is entered with the ball of the event, not an infinite one.
    assert tr.window[0] <= 1.0 <= tr.window[1] and tr.window[1] - tr.window[0] < 1e-12
    assert cert.certified and len(cert.levels) == 1


def test_an_exact_tangency_next_to_a_step_end_is_still_refused_as_grazing():
    # The grazing circle started so that the tangency falls at 95% of a step: the closest
    # approach is in the step's last sub-interval. The cone still meets the guard there.
    h = 0.0125
    t0 = math.pi / 2 - 15.95 * h
    x0 = CircularReference(1.0, 1.0).state(np.array([0.0, 1.0]), t0)
    cert = certify(circular_flow(), "inside", x0, t0 + 3.0, h, "rk4", t0=t0, max_refinements=0)
    (tr,) = cert.transitions
    assert (tr.reason, tr.taken, cert.certified) == ("grazing", False, False)
    assert tr.time == pytest.approx(math.pi / 2, abs=1e-3)


def test_a_used_up_transition_budget_leaves_the_certificate_incomplete():
    ref = TwoTankReference(0.75, 0.5, 0.5)
    x0 = np.array([1.0, 1.0])
    cert = certify(two_tanks(), "q1", x0, 10.0, 0.05, "rk4", floor=1.0, max_transitions=3)
    assert all(tr.certified for tr in cert.transitions) and len(cert.transitions) == 3
    exact, _ = ref.switching_times("q1", x0, 3)
    assert [tr.time for tr in cert.transitions] == pytest.approx(list(exact), abs=1e-9)
    # Three transitions certified up to 6.5 s say nothing about the rest of [0, 10]: not certified.
    assert not cert.complete and not cert.certified
    assert "max_transitions = 3" in cert.message and cert.end_time == pytest.approx(6.5, abs=1e-9)


def test_refinement_stops_before_a_level_beyond_the_step_limit():
    from legsim.bounds import MAX_STEPS

    # alpha = 1e6: the first refinement would take 3e7 steps over 3 s; the verdict of the last
    # level that ran stands (grazing), and the detail says why refining stopped.
    cert = certify(circular_flow(), "inside", [0.0, 1.0], 3.0, 0.1, "rk4", alpha=1e6, max_refinements=3)
    (tr,) = cert.transitions
    assert tr.reason == "grazing" and len(cert.levels) == 1
    assert "refinement stopped at h = 0.1" in tr.detail and f"{MAX_STEPS:.0e}" in tr.detail
    with pytest.raises(SimulationError, match="steps, more than the limit"):
        certify(circular_flow(), "inside", [0.0, 1.0], 3.0, 3.0 / (2 * MAX_STEPS), "rk4")


def test_a_model_that_breaks_down_past_the_guard_is_a_refusal_then_certified_when_refined():
    # Euler with floor 0.5: B grows by 0.5 h^2 per step. The flow keeps its points up to the last
    # one inside the model's range (x <= 1.03): at h = 0.1 and 0.05 that is the point on the wall
    # (x = 1), where the ball (0.055, 0.026) still straddles it: those levels cannot certify,
    # and the breakdown is their refusal, not an exception out of the run. At h = 0.025 the point
    # x = 1.025 has its ball (0.013) wholly past the wall: certified there.
    coarse = certify(breaking_line(), "a", [0.0], 2.0, 0.1, "euler", floor=0.5, max_refinements=0)
    (tr,) = coarse.transitions
    assert (tr.name, tr.certified, tr.reason) == ("wall", False, "refinement_limit")
    assert "past its range 1.03" in tr.detail and tr.guards_met == ["wall"]
    refined = certify(breaking_line(), "a", [0.0], 2.0, 0.1, "euler", floor=0.5, max_refinements=3)
    (tr,) = refined.transitions
    assert tr.certified and tr.time == pytest.approx(1.0, abs=1e-9)
    assert [lv.h for lv in refined.levels] == [0.1, 0.05, 0.025]
    assert tr.window[0] <= 1.0 <= tr.window[1]


def circle_crossings(radius):
    """Exact times (s) at which the clockwise unit-rate circle from (0, radius) crosses the wall
    x1 = 1 out and back: x1(t) = radius sin t = 1 at t = asin(1 / radius) and pi - asin(1 / radius)."""
    a = math.asin(1.0 / radius)
    return a, math.pi - a


def test_a_return_inside_the_entry_ball_is_refused_then_certified_with_its_exact_time():
    # Radius 1.0001: out at 1.556655 s, back at 1.584938 s, both before t_final = 3 s. At h = 0.1
    # the `outside` visit is entered with a ball (~1e-3) wider than the whole excursion (1e-4): the
    # computed return lies inside the ball of the guard it just crossed. It must not be left out.
    exact = circle_crossings(1.0001)
    coarse = certify(circular_flow(), "inside", [0.0, 1.0001], 3.0, 0.1, "rk4", max_refinements=0)
    assert not coarse.certified
    assert [(tr.name, tr.certified, tr.reason) for tr in coarse.transitions] == [
        ("cross", True, None),
        ("return", False, "grazing"),
    ]
    assert coarse.transitions[1].time == pytest.approx(exact[1], abs=1e-3)
    # Refining shrinks the entry ball below the excursion: both crossings certified at their times.
    cert = certify(circular_flow(), "inside", [0.0, 1.0001], 3.0, 0.1, "rk4", max_refinements=3)
    assert cert.certified
    assert [tr.name for tr in cert.transitions] == ["cross", "return"]
    for tr, t in zip(cert.transitions, exact, strict=True):
        assert tr.time == pytest.approx(t, abs=1e-5)
        assert tr.window[0] <= t <= tr.window[1]


@pytest.mark.parametrize("t_final", [0.7297286, 0.72973, 0.7298, 0.73])
def test_a_crossing_in_the_last_eighth_of_a_step_before_t_final_is_certified(t_final):
    # Radius 1.5 crosses x1 = 1 at asin(2/3) = 0.7297277 s, less than a sample spacing (h / 8 =
    # 0.0125 s) before t_final: the computed crossing (0.7297285 s) is in the horizon, and the
    # cone is followed past it even when it leaves the domain only after t_final.
    exact, _ = circle_crossings(1.5)
    assert exact < t_final
    cert = certify(circular_flow(), "inside", [0.0, 1.5], t_final, 0.1, "rk4")
    assert cert.certified
    (tr,) = cert.transitions
    assert (tr.name, tr.taken, tr.reason) == ("cross", True, None)
    assert tr.time == pytest.approx(exact, abs=1e-5)
    assert tr.window[0] <= exact <= tr.window[1]


def test_a_crossing_computed_just_after_t_final_but_reached_by_the_cone_before_is_not_skipped():
    # t_final 3.4e-7 s after the exact crossing: at h = 0.1 the computed crossing (8.8e-7 s late)
    # falls after t_final while the cone meets the guard before it: refused as t_final, then
    # certified once refining puts the computed crossing before t_final.
    exact, _ = circle_crossings(1.5)
    t_final = 0.729728
    coarse = certify(circular_flow(), "inside", [0.0, 1.5], t_final, 0.1, "rk4", max_refinements=0)
    (tr,) = coarse.transitions
    assert (tr.name, tr.certified, tr.reason) == ("cross", False, "t_final")
    assert exact < t_final < tr.time and tr.window[0] <= t_final
    cert = certify(circular_flow(), "inside", [0.0, 1.5], t_final, 0.1, "rk4", max_refinements=3)
    assert cert.certified
    (tr,) = cert.transitions
    assert tr.time == pytest.approx(exact, abs=1e-7) and tr.window[0] <= exact <= tr.window[1]


def test_a_crossing_whose_window_reaches_past_t_final_is_refused_until_refining_resolves_it():
    # t_final halfway between the computed crossing and the end of its window at h = 0.1: the
    # true crossing may come after t_final, so it is not certified there; refining narrows the
    # window to before t_final and around the exact time.
    exact, _ = circle_crossings(1.5)
    wide = certify(circular_flow(), "inside", [0.0, 1.5], 3.0, 0.1, "rk4", max_refinements=0).transitions[0]
    t_final = 0.5 * (wide.time + wide.window[1])
    coarse = certify(circular_flow(), "inside", [0.0, 1.5], t_final, 0.1, "rk4", max_refinements=0)
    (tr,) = coarse.transitions
    assert (tr.certified, tr.reason) == (False, "t_final") and tr.window[1] > t_final
    cert = certify(circular_flow(), "inside", [0.0, 1.5], t_final, 0.1, "rk4", max_refinements=3)
    assert cert.certified
    (tr,) = cert.transitions
    assert tr.window[0] <= exact <= tr.window[1] <= t_final


@pytest.mark.parametrize("h", [2.9, 3.0])
def test_a_ball_across_the_guard_from_the_start_is_refused_not_certified(h):
    # One step of h ~ t_final: the ball at t = 0 (radius 5.9) already reaches the wall 1 away, the
    # flow heads for it, and the true circle crosses at asin(2/3) < 3 s: zeno, not "meets no guard".
    exact, back = circle_crossings(1.5)
    assert exact < back < 3.0
    cert = certify(circular_flow(), "inside", [0.0, 1.5], 3.0, h, "rk4", max_refinements=0)
    assert not cert.certified
    (tr,) = cert.transitions
    assert (tr.name, tr.certified, tr.reason) == ("cross", False, "zeno")


@pytest.mark.parametrize(("t_final", "crossings"), [(0.7, 0), (0.74, 1), (1.0, 1), (3.0, 2)])
def test_crossings_well_inside_or_outside_the_horizon_are_certified_at_their_exact_times(t_final, crossings):
    exact = circle_crossings(1.5)
    assert sum(t < t_final for t in exact) == crossings
    cert = certify(circular_flow(), "inside", [0.0, 1.5], t_final, 0.1, "rk4")
    assert cert.certified and len(cert.levels) == 1
    assert [tr.name for tr in cert.transitions] == ["cross", "return"][:crossings]
    for tr, t in zip(cert.transitions, exact, strict=False):
        assert tr.time == pytest.approx(t, abs=1e-5) and tr.window[0] <= t <= tr.window[1]
