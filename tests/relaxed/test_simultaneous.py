"""Transitions crossed in the same landing step without a joint resolution: taken one after the
other, with a warning where the two orders of their resets give different states."""

import numpy as np
import pytest

from legsim import HybridSystem, Mode, Transition, simulate


def corner(mixing: float) -> HybridSystem:
    """A point (x, y, vx, vy) flying diagonally into the corner x, y >= 0: walls x = 0 and y = 0
    (guards max(x, vx) and max(y, vy), m), each reflecting its normal speed with c = 0.5; the x wall
    also pushes vx by ``mixing`` vy, so for mixing != 0 the two resets do not commute."""
    field = lambda t, s, u: np.array([s[2], s[3], 0.0, 0.0])  # noqa: E731
    wall_x = Transition(
        "p",
        "p",
        lambda s: max(s[0], s[2]),
        lambda s: np.array([s[0], s[1], -0.5 * s[2] + mixing * s[3], s[3]]),
        name="wall_x",
    )
    wall_y = Transition(
        "p", "p", lambda s: max(s[1], s[3]), lambda s: np.array([s[0], s[1], s[2], -0.5 * s[3]]), name="wall_y"
    )
    return HybridSystem({"p": Mode(4, field, ("x", "y", "vx", "vy"))}, [wall_x, wall_y], name="corner")


def test_commuting_resets_crossed_together_give_no_warning():
    ex = simulate(corner(0.0), [1.0, 1.0, -1.0, -1.0], "p", 2.0, 1e-2, 1e-3)
    assert ex.status == "finished" and len(ex.transitions) == 2 and ex.warnings == []


def test_non_commuting_resets_crossed_together_are_reported_with_their_difference():
    ex = simulate(corner(0.3), [1.0, 1.0, -1.0, -1.0], "p", 2.0, 1e-2, 1e-3)
    (warning,) = ex.warnings
    assert warning.kind == "non_commuting_resets" and set(warning.details["transitions"]) == {"wall_x", "wall_y"}
    # wall_x then wall_y: vx+ = 0.5 + 0.3 (-1) = 0.2; wall_y then wall_x: vx+ = 0.5 + 0.3 (0.5) = 0.65
    assert warning.details["difference"] == pytest.approx(0.45, rel=1e-9)
    assert abs(warning.time - 1.0) < 2e-3
