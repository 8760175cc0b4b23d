"""The checks against closed forms that several case families share: each passes on a good run
of its model and fails on one broken by hand."""

import dataclasses

import numpy as np
import pytest

from legsim import simulate, stress

G, C, H, EPS = 9.81, 0.5, 1e-3, 1e-4


@pytest.fixture(scope="module")
def ball():
    """The ball from 1 m through and past its Zeno time (1.35 s), and that time: the paper's
    relaxed execution (continuation=False), whose rest is a chatter in the strip band."""
    model = stress.build("bouncing_ball", {"g": G, "z0": 1.0}, {"floor": {"restitution": C}})
    t_zeno = model.reference.zeno_time
    return simulate(
        model.system, [1.0, 0.0], "flight", 2 * t_zeno, H, EPS, max_transitions=10**5, continuation=False
    ), t_zeno


def with_transition(ex, k, **changes):
    transitions = list(ex.transitions)
    transitions[k] = dataclasses.replace(transitions[k], **changes)
    return dataclasses.replace(ex, transitions=transitions)


def test_ball_flights_last_2_w_over_g_and_a_shifted_landing_fails(ball):
    ex, _ = ball
    assert stress.ball_flight_checks(ex, G, EPS, resolved=4 * H).passed
    late = with_transition(ex, 2, time=ex.transitions[2].time + 1e-6)
    check = stress.ball_flight_checks(late, G, EPS, resolved=4 * H)
    assert not check.passed and "worst error" in check.detail


def test_ball_rests_after_its_zeno_time_but_not_while_it_bounces(ball):
    ex, t_zeno = ball
    assert stress.ball_rest_check(ex, C, G, EPS, 1.5 * t_zeno, 2 * t_zeno).passed
    assert not stress.ball_rest_check(ex, C, G, EPS, 0.0, 2 * t_zeno).passed


def test_ball_holds_are_at_most_eps_1_plus_1_over_v(ball):
    ex, _ = ball
    assert stress.ball_hold_check(ex, EPS).passed
    first = ex.transitions[0]
    held_long = with_transition(ex, 0, exit_time=first.time + 2 * EPS * (1 + 1 / abs(first.state_before[1])))
    assert not stress.ball_hold_check(held_long, EPS).passed


def test_tank_switches_are_the_exact_ones_and_a_moved_strip_point_fails():
    model = stress.build("two_tanks")
    x0 = stress.model_state(model, "q1")
    ex = simulate(model.system, x0, "q1", 10.0, 1e-2, 1e-3, max_transitions=10**5)  # past the Zeno time, 8 s
    assert stress.tank_switch_checks(ex, model.reference, x0, 24).passed
    moved = with_transition(ex, 3, state_before=ex.transitions[3].state_before + np.array([1e-6, 0.0]))
    check = stress.tank_switch_checks(moved, model.reference, x0, 24)
    assert not check.passed and check.name == "switches exact"


def test_tank_level_rate_is_the_fastest_level_in_either_mode():
    model = stress.build("two_tanks")
    x = np.array([0.3, 0.2])
    fastest = max(float(np.max(np.abs(model.system.mode(m).field(0.0, x, None)))) for m in ("q1", "q2"))
    assert stress.tank_level_rate(model.reference) == fastest


def test_the_ball_rests_at_the_first_crossing_that_ends_a_flight_within_the_window(ball):
    # Counted flight by flight: the k-th impact ends the flight 2 c^(k-1) v1 / g.
    v1 = (2 * G) ** 0.5
    for window in (1.1e-3, 0.01, 0.05, 0.2, 1.0):
        k = 2
        while 2 * C ** (k - 1) * v1 / G > window:
            k += 1
        assert stress.ball_rest_crossing(v1, C, G, window) == k
    # the plain run's accumulation begins at that crossing too
    ex, _ = ball
    k = stress.ball_rest_crossing(v1, C, G, H + EPS)
    assert stress.first_accumulating_crossing(ex, "bounce", H + EPS) == k - 1  # an index
    assert stress.first_accumulating_crossing(ex, "bounce", H + EPS, after=ex.transitions[k - 1].time) == k


def test_the_oscillator_sequence_needs_a_run_that_starts_and_ends_stuck():
    from legsim.systems.oscillator import OscillatorReference

    ex2 = OscillatorReference.example("ex2")
    names = stress.oscillator_stick_sequence(ex2, 4 * np.pi, 1e-2 + 1e-5)
    assert names[:3] == ["impact", "stick", "release"] and names[-1] == "stick" and names.count("release") == 2
    with pytest.raises(ValueError, match="start and end stuck"):
        stress.oscillator_stick_sequence(OscillatorReference.example("ex1"), 10.0, 1e-2)
    with pytest.raises(ValueError, match="as short as 1e-12 s"):
        stress.oscillator_stick_sequence(ex2, 4 * np.pi, 1e-12)
