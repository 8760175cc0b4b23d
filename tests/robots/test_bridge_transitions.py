"""Transitions of the bridge: a striking contact releases the contacts it names."""

import math

import numpy as np
import pytest
from legsim.robots.bridge import ContactBridge, PointContact, add_point_frame

from helpers.bridge_models import rod_model
from legsim import ModelError


def test_a_striking_contact_releases_the_ones_it_names():
    """Two spokes of a wheel: spoke b striking (c = 0) releases spoke a, as a walker's heel
    strike releases its stance foot; both are declared in either order."""
    model = rod_model()
    body = model.getJointId("theta")
    add_point_frame(model, "end_b", body, (-0.5, 0, 0))
    contacts = [PointContact("a", "tip", releases=("b",)), PointContact("b", "end_b", releases=("a",))]
    bridge = ContactBridge(model, contacts)
    system = bridge.system("a", [0.0, math.sin(0.3) * 0.5, -0.3, 0.0, 0.0, 0.0])
    assert {(tr.name, tr.target) for tr in system.outgoing("a")} == {
        ("liftoff_a", "free"),
        ("touchdown_b", "b"),
        ("graze_b", "free"),
    }
    # the impact solves only the striking contact: the released one may move
    q, v = np.array([0.0, 0.0, 0.0]), np.array([0.0, -1.0, 0.5])
    reset = next(tr for tr in system.outgoing("a") if tr.name == "touchdown_b").reset
    v_after = reset(np.concatenate([q, v]))[3:]
    np.testing.assert_allclose(v_after, bridge.impact_velocity([("b", 0.0)], q, v), atol=1e-15)
    with pytest.raises(ModelError, match="releases must be a tuple of contact names"):
        ContactBridge(rod_model(), [PointContact("a", "tip", releases="b")])
