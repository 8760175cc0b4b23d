"""Zeno continuation of the oscillator (``make_system(..., zeno_window=...)``, effect ``zeno``):
its guards choose between a bounce and sticking by the rebound and the force on the stop, it is
off without a window, and a scene switches it on by effect. How Example 2 then sticks and
releases against the reference: tests/stress/test_zeno_continuation.py."""

import numpy as np
import pytest

from legsim.errors import ModelError, SceneError
from legsim.scene import load_scene
from legsim.systems.oscillator import make_system


def test_guards_decide_between_bounce_and_stick_by_the_rebound_and_the_force():
    window = 2e-3
    system = make_system(1.0, 0.95, -0.8, 0.5, zeno_window=window)
    guards = {tr.name: tr for tr in system.outgoing("free")}
    assert set(guards) == {"impact", "stick"} and all(tr.guard_args == "t,x,u" for tr in guards.values())
    (release,) = system.outgoing("stuck")
    assert release.name == "release" and release.target == "free"
    depth = 1e-7
    # u = 1 N: F = 1 + 0.8 = 1.8 m/s^2 pressing; threshold F window / 2 = 1.8e-3 m/s for c v0
    for speed, sticks in ((1e-4, True), (3e-3, True), (4e-3, False), (1.0, False)):
        x = np.array([-0.8 + depth, speed])
        g_stick, g_impact = guards["stick"].guard_value(x, 0.0, 1.0), guards["impact"].guard_value(x, 0.0, 1.0)
        assert (g_stick < 0) == sticks and (g_impact < 0) == (not sticks)
        assert min(g_stick, g_impact) == pytest.approx(-depth)  # the branch taken has the stop's guard
    # u = -1 N: F = -1 + 0.8 < 0 pulls the mass off: even a slow impact bounces
    x = np.array([-0.8 + depth, 1e-4])
    assert guards["stick"].guard_value(x, 0.0, -1.0) > 0 > guards["impact"].guard_value(x, 0.0, -1.0)
    # the release guard is F itself (m/s^2)
    assert release.guard_value(np.array([-0.8, 0.0]), 0.0, 1.0) == pytest.approx(1.8)


def test_without_a_window_the_system_is_the_plain_one():
    plain = make_system(1.0, 0.95, -0.8, 0.5)
    assert list(plain.modes) == ["free"] and [tr.name for tr in plain.outgoing("free")] == ["impact"]
    assert plain.outgoing("free")[0].guard_args == "x"
    with pytest.raises(ModelError, match="zeno_window must be finite and >= 0"):
        make_system(1.0, 0.95, -0.8, 0.5, zeno_window=-1.0)


def test_the_scene_switches_it_on_by_effect():
    scene = load_scene("oscillator_ex2", overrides=["effects.zeno.window=0.01001"])
    assert sorted(scene.model.system.modes) == ["free", "stuck"]
    ex = scene.simulate()
    assert ex.status == "finished" and len(ex.transitions) <= 15
    with pytest.raises(SceneError, match="effects.zeno.window"):
        load_scene("oscillator_ex2", overrides=["effects.zeno.window=0"])
