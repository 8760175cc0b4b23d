"""The Execution: save/load round trip, dense sampling (continuous, O(h^4) between steps) and the
hold of the state inside relaxation strips."""

from __future__ import annotations

import numpy as np
import pytest

from legsim import Execution, simulate
from legsim.systems import bouncing_ball as bb


@pytest.fixture(scope="module")
def ball_run() -> Execution:
    # The plain relaxed run: past the Zeno time the ball chatters in its strips.
    return simulate(bb.make_system(), [1.0, 0.0], "flight", 2.0, 1e-2, 1e-3, continuation=False)


def test_strips_hold_the_guard_point_and_exit_with_the_reset(ball_run):
    ex = ball_run
    # One strip per transition, plus the one the run ended in.
    assert len(ex.strips) == len(ex.transitions) + ex.final_in_strip > 5
    for strip, tr in zip(ex.strips[:20], ex.transitions[:20], strict=False):
        assert strip.time == tr.time and strip.exit_time == tr.exit_time
        inside = np.linspace(strip.time, strip.exit_time, 7)[1:-1]
        s = ex.sample(inside)
        assert all(s.in_strip) and s.modes == [strip.mode] * 5
        np.testing.assert_array_equal(s.stack(), np.tile(strip.state, (5, 1)))
        np.testing.assert_array_equal(strip.state, tr.state_before)
        # The guard point is on the guard (the floor), never the overshot landing point.
        assert abs(strip.state[0]) <= 1e-9 * 1e-3
        # At the exit the state is the reset image, and the next segment starts from it.
        _mode, x = ex.state_at(tr.exit_time)
        np.testing.assert_array_equal(x, tr.state_after)
        np.testing.assert_allclose(tr.state_after, [tr.state_before[0], -0.5 * tr.state_before[1]])
        # Strip length = landing - crossing + eps - depth.
        assert tr.exit_time - tr.landing_time == pytest.approx(1e-3 - tr.depth, abs=1e-15)
        assert 0.0 <= tr.depth <= 1e-3
