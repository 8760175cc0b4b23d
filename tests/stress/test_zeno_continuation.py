"""Zeno continuation of the forced oscillator with a stop (paper 000 Table I Example 2): the
effect ``zeno = { window = h + eps }`` sticks where the impacts accumulate and releases where the
free acceleration at the stop changes sign, against the exact reference; its guards."""

import math

import numpy as np
import pytest

from legsim import simulate
from legsim.errors import ModelError, SceneError
from legsim.scene import load_scene
from legsim.stress import _oscillator_model
from legsim.systems.oscillator import make_system

T = 4 * math.pi


def test_example_2_sticks_and_releases_as_the_reference_does_with_few_transitions():
    h, eps = 1e-2, 1e-5
    model = _oscillator_model(True, h + eps)
    ref = model.reference
    ex = simulate(model.system, [-0.8, 0.0], "free", T, h, eps, control=model.control)
    names = [tr.name for tr in ex.transitions]
    assert names.count("stick") == 3 and names.count("release") == 2 and len(names) <= 15
    sticks = ref.sticking_intervals(T)
    releases = [tr.time for tr in ex.transitions if tr.name == "release"]
    # F(t) = cos t + 0.8 changes sign at t = acos(-0.8) and 2 pi + acos(-0.8): closed form
    np.testing.assert_allclose(releases, [math.acos(-0.8), 2 * math.pi + math.acos(-0.8)], atol=1e-9)
    np.testing.assert_allclose(releases, [s1 for _, s1 in sticks[:2]], atol=1e-9)
    # a stick skips at most the tail of the accumulation, window/(1 - c) = 2 (h + eps)
    for tr, (s0, _) in zip([t for t in ex.transitions if t.name == "stick"][1:], sticks[1:]):
        assert -2 * (h + eps) - 1e-12 <= tr.time - s0 <= h + eps
    # while stuck the state is the stop at rest, and the stop pushes (F >= 0)
    for tr in ex.transitions:
        if tr.name == "stick":
            assert tr.state_after[1] == 0.0 and abs(tr.state_after[0] + 0.8) <= 1e-9
    # the position error at the step points is that of the plain relaxed run, or better
    ts = ex.step_times()
    rho = np.max(np.abs(np.concatenate([s.x[:, 0] for s in ex.segments]) - ref.position(ts)))
    assert rho < 1e-5


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


def test_the_ball_rests_after_its_bounces_as_long_as_a_step_and_keeps_the_plain_bounces_before():
    from legsim.systems.bouncing_ball import BouncingBallReference, make_system as ball

    g, c, h, eps = 9.81, 0.5, 1e-3, 1e-4
    ref = BouncingBallReference(g, c)
    cont = simulate(ball(g, c, zeno_window=h + eps), [1.0, 0.0], "flight", 2 * ref.zeno_time, h, eps)
    plain = simulate(ball(g, c), [1.0, 0.0], "flight", 2 * ref.zeno_time, h, eps)
    names = [tr.name for tr in cont.transitions]
    assert names[-1] == "rest" and names.count("rest") == 1 and cont.final_mode == "rest"
    # the bounces it keeps are the plain run's, strip for strip (same guard values, same holds)
    kept = cont.transitions[:-1]
    np.testing.assert_array_equal([tr.exit_time for tr in kept], [tr.exit_time for tr in plain.transitions[:len(kept)]])
    # it rests once the rebound c v would fly less than h + eps: c v < g (h + eps) / 2
    v = abs(cont.transitions[-1].state_before[1])
    assert c * v < 0.5 * g * (h + eps) <= c * abs(kept[-1].state_before[1])
    # ... which is before the exact Zeno time by at most the skipped tail, 2 c v / (g (1 - c)),
    # plus the holds of the strips kept (each at most h + eps)
    t_rest = cont.transitions[-1].time
    assert ref.zeno_time - 2 * c * v / (g * (1 - c)) - 1e-12 <= t_rest <= ref.zeno_time + len(kept) * (h + eps)
    assert len(plain.transitions) > 100 * len(names)
    with pytest.raises(ModelError, match="zeno_window"):
        ball(g, c, zeno_window=math.inf)
