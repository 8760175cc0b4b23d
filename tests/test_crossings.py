"""Section crossings on an execution's stored flow (legsim.crossings), against the bouncing
ball's closed form: free fall is a quadratic, which RK4 integrates exactly and the stored flow's
cubic Hermite interpolant reproduces, and each rebound leaves the floor at exactly
c^k sqrt(2 g z0) (the reset at the guard point), so every apex and every crossing of a height is
known in closed form."""

import math

import numpy as np
import pytest

from legsim import simulate
from legsim.crossings import returns, takings
from legsim.systems.bouncing_ball import make_system

G, C, Z0 = 9.81, 0.8, 1.0


@pytest.fixture(scope="module")
def ball():
    return simulate(make_system(G, C), [Z0, 0.0], "flight", 2.5, 1e-3, 1e-4, "rk4")


def flights(execution):
    """(index, start time, rebound speed) of each flight after a rebound."""
    return [(k, seg.t[0], seg.x[0, 1]) for k, seg in enumerate(execution.segments) if k > 0 and seg.mode == "flight"]


def test_each_apex_after_a_rebound_is_found_at_its_closed_form_time_and_height(ball):
    apexes = list(returns(ball, "flight", lambda x: x[1], -1))
    after = flights(ball)
    assert len(after) >= 3 and len(apexes) == len(after)
    for (k, t, x), (k_flight, t0, v) in zip(apexes, after, strict=True):
        assert k == k_flight
        assert t == pytest.approx(t0 + v / G, abs=1e-12)
        assert x[1] == pytest.approx(0.0, abs=1e-12)
        assert x[0] == pytest.approx(v**2 / (2 * G), abs=1e-12)
    # each rebound's speed is c^k sqrt(2 g z0), so the k-th apex is c^(2k) z0
    heights = np.array([x[0] for _, _, x in apexes])
    assert np.abs(heights - C ** (2 * np.arange(1, len(heights) + 1)) * Z0).max() < 1e-12


def test_a_height_crossed_both_ways_counts_once_a_flight_unless_every_crossing_counts(ball):
    level = 0.1

    def above(x):
        return x[0] - level

    every = list(returns(ball, "flight", above, 0, min_transitions=0))
    once = list(returns(ball, "flight", above, 0, min_transitions=1))
    high = [(k, t0, v) for k, t0, v in flights(ball) if v**2 / (2 * G) > level]
    assert len(high) >= 2
    # the first fall from z0, then each high flight's rise and, before the run's end, its fall
    expected = [math.sqrt(2 * (Z0 - level) / G)]
    for _, t0, v in high:
        root = math.sqrt(v**2 - 2 * G * level)
        expected += [t for t in (t0 + (v - root) / G, t0 + (v + root) / G) if t < ball.t_end]
    assert [t for _, t, _ in every] == pytest.approx(expected, abs=1e-12)
    assert [k for k, _, _ in once] == [k for k, _, _ in high]
    for (_, t, _), (_, t0, v) in zip(once, high, strict=True):
        rising = t0 + (v - math.sqrt(v**2 - 2 * G * level)) / G
        assert t == pytest.approx(rising, abs=1e-12)
    # min_time: a crossing counts only that long after the last one counted
    kept = [expected[0]]
    for t in expected[1:]:
        if t > kept[-1] + 0.1:
            kept.append(t)
    assert len(kept) < len(expected)
    spaced = [t for _, t, _ in returns(ball, "flight", above, 0, min_transitions=0, min_time=0.1)]
    assert spaced == pytest.approx(kept, abs=1e-12)


def test_takings_are_the_transitions_into_the_mode_with_their_exit_times_and_images(ball):
    found = takings(ball, ball.transitions[0].name, "flight")
    records = [r for r in ball.transitions if r.target == "flight"]
    assert len(found) == len(records) >= 3
    for (t, x), r in zip(found, records, strict=True):
        assert t == r.exit_time and np.array_equal(x, r.state_after)
