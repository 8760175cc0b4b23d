"""Guards of the bridge: a release under a time-varying control located exactly, armed contacts
(by a coordinate, and ahead of another frame), the initial-state check."""

import math

import numpy as np
import pinocchio as pin
import pytest
from legsim.robots.bridge import Armed, ContactBridge, JointStop, PointContact, add_point_frame
from legsim.robots.bridge.guards import THROUGH_DEPTH

from helpers.bridge_models import G, ball_model, rod_model
from legsim import ModelError, simulate


def test_release_under_a_time_varying_control_is_located_exactly():
    """A point mass resting on the floor is lifted by an actuator force u = F t: the floor force
    m g - F t vanishes at t* = m g / F. The release guard of an actuated robot is declared on
    (t, x, u), so the crossing search evaluates the force with the control at each interpolated
    time (with the control of the last field evaluation it would be found O(h) early)."""
    model, _ = ball_model()
    model.gravity = pin.Motion(np.array([0, 0, -G, 0, 0, 0]))
    bridge = ContactBridge(model, [PointContact("floor", "ball", tangential=False)], actuated=("z",))
    F = 2.9
    ex = simulate(bridge.system(), np.zeros(4), "floor", 5.0, 1e-3, 1e-3, control=lambda t, x: np.array([F * t]))
    assert ex.transitions[0].name == "liftoff_floor"
    assert ex.transitions[0].time == pytest.approx(G / F, abs=1e-9)


def test_an_armed_contact_lands_only_where_it_is_armed():
    """The floor only counts for x >= 1 m (armed = x - 1). A ball thrown from x = 0 comes back to
    z = 0 at x = 1.22 m, armed: it lands at the ballistic time. Below the floor at x = 0.5, not
    armed, the guard is 0.5 (inside the domain)."""
    model, _ = ball_model()
    model.gravity = pin.Motion(np.array([0, 0, -G, 0, 0, 0]))
    floor = PointContact("floor", "ball", restitution=0.5, tangential=False, armed=Armed(coordinate="x", beyond=1.0))
    bridge = ContactBridge(model, [floor])
    x0 = [0.0, 0.0, 2.0, 3.0]  # flight time 2 * 3 / g = 0.61 s, landing at x = 1.22 m
    ex = simulate(bridge.system("free", x0), x0, "free", 0.7, 1e-3, 1e-3)
    assert ex.transitions[0].time == pytest.approx(2 * 3.0 / G, abs=1e-12)
    np.testing.assert_allclose(bridge.system().guard_values("free", np.array([0.5, -0.1, 2.0, -1.0])), [0.5])
    # the same floor armed where the ball is 1 m ahead of a frame at the origin
    post = add_point_frame(model, "post", 0, (0.0, 0.0, 0.0))
    assert post > 0
    ahead = PointContact("floor", "ball", restitution=0.5, tangential=False, armed=Armed(ahead_of="post", beyond=1.0))
    np.testing.assert_allclose(
        ContactBridge(model, [ahead]).system().guard_values("free", np.array([0.5, -0.1, 2.0, -1.0])), [0.5]
    )
    with pytest.raises(ModelError, match=r"armed must be a legsim\.robots\.bridge\.Armed"):
        ContactBridge(model, [PointContact("floor", "ball", armed=1.0)])
    with pytest.raises(ModelError, match="exactly one of coordinate and ahead_of"):
        ContactBridge(model, [PointContact("floor", "ball", armed=Armed())])
    with pytest.raises(ModelError, match=r"armed\.coordinate 'w' is not a coordinate"):
        ContactBridge(model, [PointContact("floor", "ball", armed=Armed(coordinate="w"))])


def test_an_armed_point_counts_as_passed_through_only_where_it_is_armed():
    """A ball 0.1 m below the floor and rising (its guard inside the domain): where the floor is
    armed (x >= 1 m, or 1 m ahead of a post at the origin) it passed through by 0.1 m; at
    x = 0.5 m, not armed, it may pass below by design."""
    model, _ = ball_model()
    post = add_point_frame(model, "post", 0, (0.0, 0.0, 0.0))
    assert post > 0
    eps = 1e-3
    states = np.array([[0.5, -0.1, 2.0, 1.0], [1.5, -0.1, 2.0, 1.0]])
    for armed in (Armed(coordinate="x", beyond=1.0), Armed(ahead_of="post", beyond=1.0)):
        floor = PointContact("floor", "ball", restitution=0.5, tangential=False, armed=armed)
        (watch,) = ContactBridge(model, [floor]).contact_watches(eps)
        depth = eps + THROUGH_DEPTH - watch.values("free", np.zeros(2), states)
        np.testing.assert_allclose(depth, [-np.inf, 0.1])


def test_a_stop_passed_and_left_behind_is_named_with_its_depth():
    # An upper stop at 0.3 m on z: the ball 0.5 m past it and moving back (guard inside the domain).
    ball, _ = ball_model()
    stop = ContactBridge(ball, [JointStop("lid", "z", position=0.3, side="upper")], mode_names={(): "free"})
    (watch,) = stop.contact_watches(1e-3)
    x = np.array([[0.0, 0.8, 0.0, -1.0]])
    assert 1e-3 + THROUGH_DEPTH - watch.values("free", np.zeros(1), x)[0] == pytest.approx(0.5, abs=1e-15)
    assert "z = 0.8 lies past the upper stop 'lid' (z <= 0.3) by 0.5 m at t=0.25" in watch.message(0.25, "free", x[0])


def test_initial_check_measures_a_point_below_the_ground_and_a_stop_from_its_side():
    # The rod's tip at (L/2) from the base, pitched by theta about +y: its height is
    # z - (L/2) sin(theta) (RY turns +x towards -z); ground at 0.2 m.
    model = rod_model(L=1.0)
    bridge = ContactBridge(model, [PointContact("tip", "tip", ground=0.2)], mode_names={(): "air"})
    check = bridge.initial_check()
    theta = 0.5
    depth = 0.2 - (0.1 - 0.5 * math.sin(theta))
    msg = check("air", np.array([0.0, 0.1, theta, 0, 0, 0]), 0.01)
    assert msg is not None and "'tip'" in msg and f"by {depth:.3g} m >" in msg
    assert check("air", np.array([0.0, 0.1, theta, 0, 0, 0]), depth * 1.001) is None
    assert check("tip", np.array([0.0, 0.1, theta, 0, 0, 0]), 0.01) is None  # active: on the ground
    # An upper stop at 0.3 m on z: the domain is z <= 0.3.
    ball, _ = ball_model()
    stop = ContactBridge(ball, [JointStop("lid", "z", position=0.3, side="upper")], mode_names={(): "free"})
    msg = stop.initial_check()("free", np.array([0.0, 0.8, 0.0, -1.0]), 0.1)
    assert msg is not None and "upper stop 'lid'" in msg and "by 0.5 m >" in msg
    assert stop.initial_check()("free", np.array([0.0, -5.0, 0.0, 0.0]), 0.1) is None
