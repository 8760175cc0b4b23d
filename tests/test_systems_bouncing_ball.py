"""The bouncing ball: its closed-form reference checked on its own, then the relaxed integrator
through the Zeno time and on to twice it: the paper's relaxed execution (continuation=False),
and by default resting where the bounces accumulate (legsim.relaxed.zeno)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from legsim import simulate
from legsim.scene import load_scene
from legsim.systems import bouncing_ball as bb
from legsim.systems.bouncing_ball import BouncingBallReference

G, C, Z0 = 9.81, 0.5, 1.0


@pytest.fixture(scope="module")
def ref() -> BouncingBallReference:
    return BouncingBallReference(G, C, Z0)


# -- the reference -----------------------------------------------------------------------------
def test_impact_times_are_the_sums_of_the_flights(ref):
    # Independent recursion: fall sqrt(2 z0 / g), then flights of 2 v_k / g with v_k = c^k v1.
    v = math.sqrt(2 * G * Z0)
    t, times = math.sqrt(2 * Z0 / G), []
    for _ in range(40):
        times.append(t)
        v *= C
        t += 2 * v / G
    np.testing.assert_allclose(ref.impact_time(np.arange(1, 41)), times, rtol=1e-14)
    assert ref.zeno_time == pytest.approx(t, rel=1e-11)  # the flights left after 40 are 2^-40 of it
    assert ref.zeno_time == pytest.approx(math.sqrt(2 * Z0 / G) * (1 + 2 * C / (1 - C)), rel=1e-15)


def test_impact_count_matches_the_impact_times(ref):
    times = ref.impact_time(np.arange(1, 30))
    for k, t in enumerate(times, start=1):
        assert ref.impact_count(t) == k
        assert ref.impact_count(np.nextafter(t, 0.0)) == k - 1
    assert ref.impact_count(ref.zeno_time) == math.inf
    assert len(ref.impact_times(float(times[9]))) == 10


def test_reference_states_obey_free_fall_and_the_impact_law(ref):
    times = ref.impact_time(np.arange(1, 12))
    # Between impacts z'' = -g (the closed form is a parabola: central differences are exact
    # up to rounding), and the velocity is dz/dt.
    d = 1e-4
    mids = 0.5 * (times[:-1] + times[1:])
    z = {k: ref.states(mids + k * d)[:, 0] for k in (-1, 0, 1)}
    np.testing.assert_allclose((z[1] - 2 * z[0] + z[-1]) / d**2, -G, rtol=1e-6)
    np.testing.assert_allclose((z[1] - z[-1]) / (2 * d), ref.states(mids)[:, 1], rtol=1e-8, atol=1e-9)
    # At impacts: on the floor, velocity reversed and scaled by c.
    before = ref.states(times - 1e-12)
    after = ref.states(times)
    np.testing.assert_allclose(after[:, 0], 0.0, atol=1e-12)
    np.testing.assert_allclose(after[:, 1], -C * before[:, 1], rtol=1e-12, atol=C * G * 1e-12 * 1.01)
    # Energy: c^(2k) of the initial one after k impacts.
    energies = G * after[:, 0] + 0.5 * after[:, 1] ** 2
    np.testing.assert_allclose(energies, G * Z0 * C ** (2 * np.arange(1, 12)), rtol=1e-9)
    # Rest after the Zeno time.
    np.testing.assert_array_equal(ref.states([ref.zeno_time, 2 * ref.zeno_time]), 0.0)


def test_reference_special_cases():
    up = BouncingBallReference(G, C, 0.0, 2.0)  # thrown up from the floor
    assert up.first_impact == pytest.approx(2 * 2.0 / G)
    down = BouncingBallReference(G, C, 1.0, -3.0)  # thrown down: root without cancellation
    assert down.z0 + down.zd0 * down.first_impact - 0.5 * G * down.first_impact**2 == pytest.approx(0, abs=1e-15)
    plastic = BouncingBallReference(G, 0.0, 1.0)
    assert plastic.zeno_time == plastic.first_impact
    elastic = BouncingBallReference(G, 1.0, 1.0)
    assert elastic.zeno_time == math.inf
    np.testing.assert_allclose(elastic.state(elastic.impact_time(5) + 0.1), elastic.state(elastic.first_impact + 0.1))
    moved = BouncingBallReference().with_initial("flight", [2.0, 0.0], t0=1.0)
    assert moved.first_impact == pytest.approx(1.0 + math.sqrt(4.0 / 9.81))


# -- the relaxed integrator ------------------------------------------------------------------------
def test_impact_times_zeno_time_and_rest(ref):
    eps, h = 1e-4, 1e-3
    # The paper's relaxed execution (continuation=False): past the Zeno time the ball chatters
    # in the strip band; by default it rests (test_by_default_the_ball_rests_...).
    ex = simulate(bb.make_system(G, C), [Z0, 0.0], "flight", 2 * ref.zeno_time, h, eps, continuation=False)
    assert ex.status == "finished"
    # Through the Zeno time to twice it with a bounded number of transitions.
    assert len(ex.transitions) < 20_000
    # Free fall is a cubic: RK4 and the Hermite crossing are exact, so the only error is the
    # strip: each crossing holds the ball for eps - tau + tau / v <= eps max(1, 1/v), delaying
    # every later impact. Hence 0 <= t_sim_k - t_k <= sum_{j<k} eps max(1, 1/v_j).
    k_max = 12
    sim = np.array([tr.time for tr in ex.transitions[:k_max]])
    exact = ref.impact_time(np.arange(1, k_max + 1))
    speeds = ref.impact_speeds(ref.zeno_time, k_max)
    bound = np.r_[0.0, np.cumsum(eps * np.maximum(1.0, 1.0 / speeds[:-1]))]
    assert abs(sim[0] - exact[0]) < 1e-12
    assert np.all(sim - exact >= -1e-12) and np.all(sim - exact <= bound + 1e-12)
    # Zeno time: the exact ball stays below 2 eps from the flight whose apex (c^k v1)^2 / (2 g)
    # falls under 2 eps on, which is at most 2 sqrt(4 g eps) / (g (1 - c)) before the Zeno
    # time; the simulation can be later by at most its strip delays.
    ts = np.linspace(0, 2 * ref.zeno_time, 20001)
    z = np.array(ex.sample(ts).states)[:, 0]
    settled = ts[np.nonzero(z > 2 * eps)[0][-1] + 1]
    n_before = sum(tr.time < ref.zeno_time for tr in ex.transitions)
    early = 2 * math.sqrt(4 * G * eps) / (G * (1 - C))
    assert ref.zeno_time - early - (ts[1] - ts[0]) <= settled <= ref.zeno_time + n_before * eps * 10
    # After it, the ball rests on the floor: within the strip, with at most the speed of a fall
    # through it.
    after = ts > settled + 0.05
    states = np.array(ex.sample(ts[after]).states)
    assert np.all(np.abs(states[:, 0]) <= eps)
    assert np.all(np.abs(states[:, 1]) <= math.sqrt(2 * G * eps))


def test_by_default_the_ball_rests_at_the_crossing_the_rule_names_with_the_plain_bounces_before(ref):
    g, c, h, eps = G, C, 1e-3, 1e-4
    window = h + eps
    cont = simulate(bb.make_system(g, c), [Z0, 0.0], "flight", 2 * ref.zeno_time, h, eps)
    plain = simulate(bb.make_system(g, c), [Z0, 0.0], "flight", 2 * ref.zeno_time, h, eps, continuation=False)
    names = [tr.name for tr in cont.transitions]
    assert names[-1] == "rest" and names.count("rest") == 1 and cont.final_mode == "rest"
    assert cont.warnings == [] and [w.kind for w in plain.warnings] == ["accumulation"]
    # the bounces it keeps are the plain run's, strip for strip (same guard values, same holds)
    kept = cont.transitions[:-1]
    np.testing.assert_array_equal(
        [tr.exit_time for tr in kept], [tr.exit_time for tr in plain.transitions[: len(kept)]]
    )
    # It rests at the crossing that ends the first flight no longer than the window: the flight
    # after impact j is 2 c^j v1 / g (free fall is a cubic, integrated exactly), so at impact
    # k = 1 + ceil(log(2 v1 / (g window)) / log(1/c)), 11 here.
    v1 = ref.impact_speed
    k = 1 + math.ceil(math.log(2 * v1 / (g * window)) / math.log(1 / c))
    assert len(cont.transitions) == k == 11
    rest = cont.transitions[-1]
    assert rest.time - kept[-1].exit_time <= window < kept[-1].time - kept[-2].exit_time
    # ... which is the exact k-th impact delayed by the strips held before it: at most the
    # exact flights still to come, window c / (1 - c), before the Zeno time, and at most those
    # holds after it
    held = sum(tr.exit_time - tr.time for tr in kept)
    assert rest.time == pytest.approx(float(ref.impact_time(k)) + held, abs=1e-9)
    assert ref.zeno_time - window * c / (1 - c) <= rest.time - held <= ref.zeno_time
    # at rest on the floor: the rest's image is the strip point with no speed, held from then on
    assert rest.state_after[1] == 0.0 and abs(rest.state_after[0]) <= 1e-12
    np.testing.assert_array_equal(cont.final_state, rest.state_after)
    assert len(plain.transitions) > 100 * len(names)


def test_a_continuation_after_a_single_flight_the_step_could_resolve_says_so(ref):
    """At h = 0.5 s the window h + eps holds the ball's first real flight (2 c v1 / g = 0.4515 s):
    the second impact counts as an accumulation on that one flight, with nothing before it to
    show the flights shrinking, and the ball rests at 0.903 s where it bounces on to its Zeno
    time 1.3546 s. The run says so; at h = 0.2 s (two flights, halving) and at the default
    h = 1e-3 s it does not, and a ball already resting (a second crossing right after the
    first) takes the continuation without a word."""
    system = bb.make_system(G, C)
    coarse = simulate(system, [Z0, 0.0], "flight", 2.0, 0.5, 1e-4)
    flight = 2 * C * ref.impact_speed / G
    assert [tr.name for tr in coarse.transitions] == ["bounce", "rest"] and coarse.final_mode == "rest"
    assert [w.kind for w in coarse.warnings] == ["unconfirmed_continuation"]
    said = coarse.warnings[0]
    assert said.details["flight"] == pytest.approx(flight, rel=1e-6)
    assert said.time == pytest.approx(float(ref.impact_time(2)), abs=1e-3)  # the second impact, its strip held
    for h in (0.2, 1e-3):
        assert simulate(system, [Z0, 0.0], "flight", 2.0, h, 1e-4).warnings == []
    resting = simulate(system, [0.0, 0.0], "flight", 0.5, 1e-3, 1e-4)
    assert resting.final_mode == "rest" and resting.warnings == []


@pytest.mark.parametrize("eps", [1e-2, 1e-3, 1e-4])
def test_ball_never_sinks_more_than_eps(eps):
    ex = simulate(bb.make_system(G, C), [Z0, 0.0], "flight", 2.7, 1e-3, eps, "rk2")
    assert ex.status == "finished"
    for seg in ex.segments:
        assert seg.x[:, 0].min() >= -eps
    for strip in ex.strips:
        assert strip.state[0] >= -eps
    # Off the stored points too (dense output between steps).
    ts = np.linspace(0, 2.7, 27001)
    assert np.array(ex.sample(ts).states)[:, 0].min() >= -eps


def test_energy_after_each_impact(ref):
    ex = simulate(bb.make_system(G, C), [Z0, 0.0], "flight", 1.33, 1e-3, 1e-6)
    energy = bb.make_system(G, C).energy
    after = [energy("flight", tr.state_after) for tr in ex.transitions[:5]]
    assert len(after) == 5
    # The reset is applied to q, the crossing on the step's interpolant, which for a cubic flow
    # lies on the floor with the exact velocity: the energy is c^(2k) E0 exactly. (Resetting the
    # overshot point instead would lose energy g tau per impact.)
    np.testing.assert_allclose(after, G * Z0 * C ** (2 * np.arange(1, 6)), rtol=1e-9)


def test_scene_and_builder():
    scene = load_scene("bouncing_ball")
    assert scene.effects == {"floor": {"restitution": 0.5}}
    ref = scene.model.reference
    assert ref.zeno_time == pytest.approx(math.sqrt(2 / 9.81) * 3)
    assert scene.integrator["t_final"] >= 2 * ref.zeno_time * 0.99
    no_floor = bb.BUILDER.make({}, {"floor": False})
    assert no_floor.system.outgoing("flight") == () and no_floor.reference.zeno_time == math.inf
    ex = simulate(no_floor.system, [1.0, 0.0], "flight", 1.0, 0.1, 1e-3)
    np.testing.assert_allclose(ex.final_state, no_floor.reference.state(1.0), atol=1e-12)  # a cubic: exact
    box = scene.model.geometry("flight", np.array([0.3, 0.0]))["ball"]
    assert box[:, 1].min() == 0.3  # the box's bottom is the coordinate z


def test_a_start_below_the_floor_is_refused_and_huge_states_have_infinite_energy():
    from legsim import SceneError

    # max(z, zd) >= 0 holds for a ball 5 m under the floor at rest: the builder's check names it.
    with pytest.raises(
        SceneError,
        match=r"bouncing_ball.toml: initial.state: \{'z': -5.0, 'zd': 0.0\}: z = -5 m "
        r"lies below the floor \(z >= 0\) by more than eps = 0.0001 m$",
    ):
        load_scene("bouncing_ball", overrides=["initial.state.z=-5"])
    # Inside the strip is a legal start (a run may be continued from where one ended).
    assert load_scene("bouncing_ball", overrides=["initial.state.z=-5e-5"]).initial_state[0] == -5e-5
    assert bb.make_system().energy("flight", np.array([0.0, 1e200])) == math.inf
