"""Modes of the bridge: built lazily (only those reached), named by their contacts, and state
maps that change the dimension as footholds join and leave the state."""

import math

import numpy as np
import pytest
from legsim.robots import pronk
from legsim.robots.bridge import ContactBridge, PointContact, add_point_frame

from helpers.bridge_models import rod_model
from legsim import ModelError


def test_many_contacts_build_only_the_modes_reached():
    model = rod_model()
    body = model.getJointId("theta")
    names = []
    for i in range(12):  # a rimless wheel's spokes: 2^12 contact subsets
        a = 2 * math.pi * i / 12
        add_point_frame(model, f"spoke{i}", body, (math.sin(a), 0, -math.cos(a)))
        names.append(f"s{i}")
    bridge = ContactBridge(model, [PointContact(n, f"spoke{i}") for i, n in enumerate(names)])
    system = bridge.system("free", [0, 2.0, 0, 0, 0, 0])
    # the initial mode and the targets of its transitions, nothing else
    assert sorted(system.modes) == sorted(["free", *names])
    assert system.mode("s0+s6").dim == 6 and "s0+s6" in system.modes and len(system.modes) == 14
    assert bridge.active_contacts("s0+s6") == ("s0", "s6")
    with pytest.raises(ModelError, match="is called 's0\\+s6'"):
        system.mode("s6+s0")
    with pytest.raises(ModelError, match="'wheel' is not a mode"):
        system.mode("wheel")


def test_spring_leg_and_joint_stop_resets_change_the_state_dimension():
    model = pronk.make()
    system = model.system
    td = next(tr for tr in system.outgoing("aerial") if tr.name == "touchdown_left")
    x = pronk.state({"z": math.cos(math.pi / 5)})
    after = td.reset(x)
    assert after.shape == (7,) and after[6] == pytest.approx(-0.5 + math.sin(math.pi / 5), abs=1e-12)
    lo = next(tr for tr in system.outgoing("left") if tr.name == "liftoff_left")
    np.testing.assert_array_equal(lo.reset(after), x)
