"""Zeno continuation of the oscillator with a stop: the impact names its continuation ``stick``
into mode ``stuck``, left through ``release`` where the force on the stop changes sign; by
default (``simulate(continuation=True)``) paper 000 Table I Example 2 then sticks where its
impacts accumulate and releases at the closed-form times; the scene's ``zeno`` effect only sets
the window of the accumulation rule (legsim.relaxed.zeno)."""

import math

import numpy as np
import pytest

from legsim import simulate
from legsim.errors import SceneError
from legsim.scene import load_scene
from legsim.stress import oscillator_stick_sequence
from legsim.stress.models import oscillator_ex2
from legsim.systems.oscillator import make_system

T = 4 * math.pi
C = 0.5


def test_the_impact_names_its_stick_continuation_and_release_is_the_force_on_the_stop():
    system = make_system(1.0, 0.95, -0.8, C)
    (impact,) = system.outgoing("free")
    (release,) = system.outgoing("stuck")
    assert impact.name == "impact" and impact.target == "free"
    stick = impact.continuation
    assert (stick.name, stick.target) == ("stick", "stuck")
    # a plastic impact: the mass stays where it is, at rest
    np.testing.assert_array_equal(stick.reset(np.array([-0.8, 0.3])), [-0.8, 0.0])
    # the impact's guard is the distance to the stop (m) once the mass moves into it
    assert impact.guard_value(np.array([-0.8 + 1e-7, 0.2])) == pytest.approx(-1e-7)
    # release: F = u/m - omega^2 x (m/s^2), the stop pushing while F >= 0. With u = 1 N,
    # F = 1.8 > 0: the stick's image lies in the domain of 'stuck' and the continuation can be
    # taken; with u = -1 N, F = -0.2 < 0 would pull the mass off, and the core bounces instead.
    assert release.name == "release" and release.target == "free" and release.guard_args == "t,x,u"
    assert release.guard_value(np.array([-0.8, 0.0]), 0.0, 1.0) == pytest.approx(1.8)
    assert release.guard_value(np.array([-0.8, 0.0]), 0.0, -1.0) == pytest.approx(-0.2)


def test_without_a_stop_there_is_neither_a_transition_nor_a_stuck_mode():
    free = make_system(1.0, 0.95, None, C)
    assert list(free.modes) == ["free"] and free.outgoing("free") == ()


def test_example_2_sticks_and_releases_at_the_closed_form_times_by_default():
    h, eps = 1e-2, 1e-5
    window = h + eps  # the default window
    model = oscillator_ex2()
    ref = model.reference
    ex = simulate(model.system, [-0.8, 0.0], "free", T, h, eps, control=model.control)
    assert ex.status == "finished" and ex.warnings == [] and ex.settings["zeno_window"] == window
    # The rule's decision: from rest on the stop the first impact starts a chain and the next
    # crossing (a flight of zero) sticks; after each release the impacts bounce until one ends a
    # flight no longer than the window, counted on the exact impacts (5 after each release here).
    expected = oscillator_stick_sequence(ref, T, window)
    assert expected.count("impact") == 11 and [tr.name for tr in ex.transitions] == expected
    # F(t) = cos t + 0.8 changes sign at t = acos(-0.8) and 2 pi + acos(-0.8): the releases are
    # located on the force's own zero crossing, exact to the crossing tolerance.
    releases = [tr.time for tr in ex.transitions if tr.name == "release"]
    np.testing.assert_allclose(releases, [math.acos(-0.8), 2 * math.pi + math.acos(-0.8)], atol=1e-9)
    np.testing.assert_allclose(releases, [s1 for _, s1 in ref.sticking_intervals(T)[:2]], atol=1e-9)
    # A stick comes at the crossing that ends a flight <= window: the exact impacts left after it
    # last at most window * c / (1 - c) (F grows through both accumulations, -sin t > 0 there,
    # so the flights shrink faster than by c), and the relaxed crossing lags the exact one by the
    # strips held since the chain began.
    chain_start = 0
    for k, tr in enumerate(ex.transitions):
        if tr.name == "release":
            chain_start = k + 1
        if tr.name != "stick":
            continue
        s0 = min(ref.sticking_intervals(T), key=lambda iv: abs(iv[0] - tr.time))[0]
        held = sum(t.exit_time - t.time for t in ex.transitions[chain_start:k])
        assert -window * C / (1 - C) <= tr.time - s0 <= held + 1e-9, (tr.time, s0, held)
        # while stuck the state is the stop at rest
        assert tr.state_after[1] == 0.0 and abs(tr.state_after[0] + 0.8) <= 1e-9
    # the position error at the step points is no worse than the plain relaxed run's
    ts = ex.step_times()
    rho = np.max(np.abs(np.concatenate([s.x[:, 0] for s in ex.segments]) - ref.position(ts)))
    assert rho < 1e-5


def test_the_scene_sets_the_window_by_effect_or_integrator_and_can_switch_continuation_off():
    default = load_scene("oscillator_ex2")
    assert sorted(default.model.system.modes) == ["free", "stuck"]
    assert "zeno_window" not in default.model.info
    # a window of 0.05 s: flights up to 0.05 s count, so each accumulation sticks sooner
    wide = load_scene("oscillator_ex2", overrides=["effects.zeno.window=0.05"])
    assert wide.model.info["zeno_window"] == 0.05
    ex_default, ex_wide = default.simulate(), wide.simulate()
    assert ex_wide.settings["zeno_window"] == 0.05 and ex_default.settings["zeno_window"] == pytest.approx(0.01001)
    assert ex_wide.status == ex_default.status == "finished"
    assert len(ex_wide.transitions) < len(ex_default.transitions)
    # integrator.zeno_window wins over the effect
    both = load_scene("oscillator_ex2", overrides=["effects.zeno.window=0.05", "integrator.zeno_window=0.02"])
    assert both.simulate().settings["zeno_window"] == 0.02
    # integrator.continuation = false: the paper's relaxed execution chatters where the mass sticks
    plain = load_scene("oscillator_ex2", overrides=["integrator.continuation=false", "integrator.t_final=6.0"])
    ex_plain = plain.simulate()
    assert ex_plain.settings["continuation"] is False and "stuck" not in ex_plain.mode_sequence
    # one accumulation warning per sticking phase begun by t = 6 s ([0, 2.498] and from 5.065 s)
    assert len(ex_plain.transitions) > 100 and [w.kind for w in ex_plain.warnings] == ["accumulation"] * 2
    with pytest.raises(SceneError, match=r"effects\.zeno\.window"):
        load_scene("oscillator_ex2", overrides=["effects.zeno.window=0"])
    with pytest.raises(SceneError, match=r"integrator\.zeno_window"):
        load_scene("oscillator_ex2", overrides=["integrator.zeno_window=-1"])
    with pytest.raises(SceneError, match=r"integrator\.continuation"):
        load_scene("oscillator_ex2", overrides=["integrator.continuation=3"])
