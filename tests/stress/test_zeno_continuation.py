"""Zeno continuation against the exact references: the forced oscillator with a stop (paper 000
Table I Example 2, effect ``zeno = { window = h + eps }``) sticks where the impacts accumulate
and releases where the free acceleration at the stop changes sign; the bouncing ball keeps the
plain run's bounces, then rests. The oscillator's guards: tests/systems/test_oscillator_zeno.py."""

import math

import numpy as np
import pytest

from legsim import simulate
from legsim.errors import ModelError
from legsim.stress.models import oscillator_ex2

T = 4 * math.pi


def test_example_2_sticks_and_releases_as_the_reference_does_with_few_transitions():
    h, eps = 1e-2, 1e-5
    model = oscillator_ex2(True, h + eps)
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
