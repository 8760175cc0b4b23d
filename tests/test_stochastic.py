"""Stochastic approximation of paper 004 Section IV (legsim.stochastic)."""

import itertools
import math

import numpy as np
import pytest

from helpers.breaking_line import breaking_line
from legsim import SimulationError
from legsim.stochastic import sample_ensemble, sample_execution, transition_functions
from legsim.systems.circular_flow import make_system as circular_flow
from legsim.systems.two_tanks import TwoTankReference
from legsim.systems.two_tanks import make_system as two_tanks

H = 0.1  # rk4 on the unit circle: B ~ 1.5e-5 at the tangency time pi/2


def grazing(radius, intensity="hazard", t_final=3.0):
    return transition_functions(circular_flow(), "inside", [0.0, radius], t_final, H, "rk4", intensity=intensity)


def segment_fraction(u):
    """Independent closed form of the share of a disc beyond a chord at u radii from its centre."""
    u = np.clip(u, -1.0, 1.0)
    return (np.arccos(u) - u * np.sqrt(1 - u * u)) / np.pi


def test_grazing_probability_rises_towards_one_half_as_the_trajectory_nears_tangency():
    tangent = grazing(1.0)
    k = int(np.argmax(tangent.pi[:, 0]))
    b_star = tangent.radius[k]
    assert tangent.t[k] == pytest.approx(math.pi / 2, abs=1e-3)
    offsets = b_star * np.array([4.0, 0.8, 0.5, 0.2, 0.05, 0.0])
    probs = [grazing(1.0 - d).switching_probability[-1] for d in offsets]
    assert probs[0] == 0.0  # the ball never reaches the plane
    assert all(a < b for a, b in itertools.pairwise(probs)), probs
    # At tangency half the ball lies past the plane; the computed circle sits inside the true
    # one by the method's own O(h^4) error, a few percent of B here.
    assert 0.45 < probs[-1] <= 0.5
    # Each value is the disc-segment share at the computed closest approach (hazard reading:
    # probability of switching = largest share of the ball past the guard).
    for d, p in zip(offsets, probs, strict=True):
        tf = grazing(1.0 - d)
        j = int(np.argmin(tf.distance[:, 0] / tf.radius))
        assert p == pytest.approx(float(segment_fraction(tf.distance[j, 0] / tf.radius[j])), abs=1e-6)


def test_grazing_probability_vanishes_away_from_the_guard():
    # Fig. 1: the transition function is zero except near the tangency time, and a circle well
    # inside never switches.
    tangent = grazing(1.0)
    far_in_time = np.abs(tangent.t - math.pi / 2) > 0.05
    assert np.all(tangent.pi[far_in_time, 0] == 0.0)
    assert np.all(grazing(0.5).pi == 0.0)
    # Intensities are non-negative and the survival never increases.
    assert np.all(tangent.intensity >= 0.0)
    assert np.all(np.diff(tangent.survival) <= 0.0)


@pytest.mark.parametrize("intensity", ["hazard", "derivative"])
def test_monte_carlo_switching_frequency_matches_the_survival_function(intensity):
    tf = grazing(1.0, intensity)
    ens = sample_ensemble(
        circular_flow(), "inside", [0.0, 1.0], 3.0, H, "rk4", samples=400, seed=7, intensity=intensity
    )
    switched = np.mean([len(e.times) > 0 for e in ens.executions])
    p = tf.switching_probability[-1]
    # Closed forms in the largest share pi* of the ball past the guard: pi* (hazard) and
    # 1 - exp(-pi*) (the literal derivative reading).
    pi_star = tf.pi[:, 0].max()
    assert p == pytest.approx(pi_star if intensity == "hazard" else 1 - math.exp(-pi_star), rel=1e-9)
    assert abs(switched - p) < 4 * math.sqrt(p * (1 - p) / 400)
    times = ens.switching_times(0)
    assert np.all(np.abs(times - math.pi / 2) < 0.05)  # switches happen while the ball straddles the plane


def test_two_tank_switching_times_approach_the_deterministic_ones_as_h_falls():
    # Constant fields: every Runge-Kutta method is exact, so the ball comes from the declared
    # floor alone (here Euler's h^2 per step, a bound of order h).
    ref = TwoTankReference(0.75, 0.5, 0.5)
    x0 = np.array([1.0, 1.0])
    exact, _ = ref.switching_times("q1", x0, 2)
    hs = [0.04, 0.02, 0.01]
    rms = []
    for h in hs:
        # Up to 6.3 s: every sample has switched twice (at 2 and 5 s, +- 0.33 s at h = 0.04).
        ens = sample_ensemble(two_tanks(), "q1", x0, 6.3, h, "euler", samples=20, seed=3, floor=1.0)
        errs = [ens.switching_times(i) - exact[i] for i in range(2)]
        assert all(len(e) == 20 for e in errs)
        rms.append(math.sqrt(np.mean(np.concatenate(errs) ** 2)))
    assert rms[0] > rms[1] > rms[2]
    slope = np.polyfit(np.log(hs), np.log(rms), 1)[0]
    assert 0.7 < slope < 1.4, (rms, slope)


@pytest.mark.parametrize("h", [0.04, 0.02, 0.01])
def test_two_tank_stochastic_executions_are_not_zeno(h):
    # The deterministic execution switches infinitely often before t_zeno = 8 s; a stochastic
    # one switches finitely often on [0, t_zeno + 1] and every visit lasts a positive time.
    # The same 8 samples (seed 5) at each h: all three h together take ~7 s, so no need to cut
    # samples; the cap of 2000 transitions is twice the count bound asserted below, so it changes
    # no outcome, only makes a run-away execution fail in seconds rather than minutes.
    ref = TwoTankReference(0.75, 0.5, 0.5)
    x0 = np.array([1.0, 1.0])
    t_zeno = ref.zeno_time(x0)
    ens = sample_ensemble(
        two_tanks(), "q1", x0, t_zeno + 1.0, h, "euler", samples=8, seed=5, floor=1.0, max_transitions=2000
    )
    for e in ens.executions:
        assert e.status == "finished", e.message
        assert e.t_end == pytest.approx(t_zeno + 1.0)
        assert np.all(np.diff(np.concatenate([[0.0], e.times])) > 0.0)
        # Before the Zeno time the ball keeps visits apart at every h: a handful of switches
        # (measured 5-12 at h = 0.04, 0.02, 0.01) where the deterministic execution has infinitely many.
        assert np.sum(e.times < t_zeno) < 50
        # Not Zeno: no accumulation of ever shorter visits. Without the hazard cap
        # (hazard_cap=inf) the visits past the Zeno time shrank geometrically at h = 0.01, to
        # 7e-15 s, thousands in a row (2 of these 8 executions used up 100000 transitions before
        # t = 9 s). With it a short visit is an isolated draw between visits of ~1e-2 s (the
        # shortest measured, 3e-8 s, sits between 1.6e-3 and 3.8e-4 s): never 4 in a row below
        # 1e-4 s.
        short = np.concatenate([[0], (e.dwell_times < 1e-4).astype(int), [0]])
        edges = np.flatnonzero(np.diff(short))
        longest_run = int((edges[1::2] - edges[::2]).max()) if len(edges) else 0
        assert longest_run < 4, (longest_run, e.dwell_times)
    counts = [len(e.times) for e in ens.executions]
    assert max(counts) < 100, counts  # measured 5-12 (h = 0.04), 8-22 (0.02), 40-63 (0.01)
    # ... and they go on switching past the Zeno time. Not every one of them: near the Zeno
    # point the switching times spread by O(h) (std 0.25 s at the 4th switch for h = 0.02, see
    # docs/bounds.md), so one execution of 8 may take its last switch shortly before t_zeno
    # (measured: 7.91 s at h = 0.02); the typical one switches past it.
    assert np.median([e.times[-1] for e in ens.executions]) > t_zeno


def test_restarting_the_bound_at_each_switch_lets_the_accumulation_back_in():
    # Without the uncertainty inherited through the switch, each visit near the Zeno point
    # starts with a ball of one step's floor: visits shrink towards zero length again.
    x0 = np.array([1.0, 1.0])
    # The hazard cap (which bounds the intensities) is off here to show the carry's own effect.
    carried = sample_execution(
        two_tanks(), "q1", x0, 9.0, 0.04, "euler", rng=1, floor=1.0, max_transitions=300, hazard_cap=math.inf
    )
    restarted = sample_execution(
        two_tanks(),
        "q1",
        x0,
        9.0,
        0.04,
        "euler",
        rng=1,
        floor=1.0,
        max_transitions=300,
        carry=False,
        hazard_cap=math.inf,
    )
    assert restarted.dwell_times.min() < 1e-3 * carried.dwell_times.min()
    # With the cap the restarted visits still shrink, but stay bounded below.
    capped = sample_execution(
        two_tanks(), "q1", x0, 9.0, 0.04, "euler", rng=1, floor=1.0, max_transitions=300, carry=False
    )
    assert capped.status == "finished" and capped.dwell_times.min() > 1e-6


def test_bad_input_is_reported_by_name():
    system = circular_flow()
    with pytest.raises(SimulationError, match=r"samples must be an integer in \[1, 1000000\]"):
        sample_ensemble(system, "inside", [0.0, 1.0], 1.0, 0.1, samples=0)
    with pytest.raises(SimulationError, match="intensity must be one of"):
        sample_execution(system, "inside", [0.0, 1.0], 1.0, 0.1, intensity="rate")
    with pytest.raises(SimulationError, match="unknown mode 'nowhere'"):
        transition_functions(system, "nowhere", [0.0, 1.0], 1.0, 0.1)
    with pytest.raises(SimulationError, match="h must be finite and > 0"):
        sample_execution(system, "inside", [0.0, 1.0], 1.0, -0.1)
    with pytest.raises(SimulationError, match="t_final must be a finite number > t0"):
        sample_execution(system, "inside", [0.0, 1.0], float("nan"), 0.1)


def test_two_tank_reference_samples_match_a_relaxed_run_and_refuse_the_zeno_time():
    from legsim import simulate

    ref = TwoTankReference(0.75, 0.5, 0.5).with_initial("q1", [1.0, 1.0])
    times = np.linspace(0.0, 7.9, 40)
    # Constant fields: the relaxed run is exact in each mode and each strip delays by < eps.
    ex = simulate(two_tanks(), [1.0, 1.0], "q1", 7.9, 0.01, 1e-10)
    got, want = ex.sample(times), ref.sample(times)
    assert got.modes == want.modes
    assert np.allclose(np.array(got.states), np.array(want.states), atol=1e-8)
    with pytest.raises(SimulationError, match=r"past the Zeno time 8\.0"):
        ref.sample([8.5])


@pytest.mark.parametrize("phase", [0.02, 0.5, 0.95])
def test_grazing_probability_does_not_depend_on_where_the_step_grid_meets_the_tangency(phase):
    # Started so that the tangency at pi/2 falls at this fraction of a step: the largest share
    # of the ball past the plane is the disc-segment share at the computed trajectory's closest
    # approach wherever that lies in the step (next to a step's end too).
    from scipy.optimize import minimize_scalar

    from legsim.bounds import LocalErrorEstimator, ModeFlow
    from legsim.systems.circular_flow import CircularReference

    t0 = math.pi / 2 - (15 + phase) * H
    x0 = CircularReference(1.0, 1.0).state(np.array([0.0, 1.0]), t0)
    tf = transition_functions(circular_flow(), "inside", x0, t0 + 3.0, H, "rk4", t0=t0)
    # The same numerical flow, to find the interpolant's closest approach in step 15 directly.
    flow = ModeFlow(circular_flow(), "inside", x0, t0, H, LocalErrorEstimator("rk4"), t_end=t0 + 3.0)
    flow.point(16)
    closest = minimize_scalar(
        lambda s: float(flow.on_step(15, s)[4][0] / flow.on_step(15, s)[2]),
        bounds=(0.0, 1.0),
        method="bounded",
        options={"xatol": 1e-12},
    )
    assert abs(closest.x - phase) < 0.01
    assert tf.switching_probability[-1] == pytest.approx(float(segment_fraction(closest.fun)), abs=1e-6)
    assert 0.45 < tf.switching_probability[-1] <= 0.5


def test_a_bound_at_rounding_level_stops_a_zeno_accumulation_as_stalled():
    # Without a floor the two tanks' constant flows are integrated exactly: the ball is rounding
    # noise (~1e-13) and the visits shrink to nothing at the Zeno time 8 s. The execution must
    # stop there (status stalled) rather than record switches at one and the same instant.
    e = sample_execution(two_tanks(), "q1", [1.0, 1.0], 9.0, 0.02, "euler", rng=1, floor=0.0, max_transitions=10_000)
    assert e.status == "stalled" and "stopped advancing" in e.message
    assert len(e.times) < 200 and np.all(e.dwell_times > 0.0)
    assert e.times[-1] == pytest.approx(8.0, abs=1e-9)
    assert 0.0 < e.max_radius < 1e-10


def test_a_model_breaking_down_past_the_guard_ends_that_execution_only():
    # x' = 1 towards the wall x = 1, valid only up to x = 1.03 (helpers.breaking_line). With
    # Euler, h = 0.1 and floor 0.5 the flow's last point is on the wall, where half the ball is
    # past it: an execution that has not switched by then stops (model_breakdown), the others
    # switch and finish. The ensemble itself must not raise.
    ens = sample_ensemble(breaking_line(), "a", [0.0], 2.0, 0.1, "euler", samples=40, seed=2, floor=0.5)
    statuses = ens.summary()["statuses"]
    assert set(statuses) == {"finished", "model_breakdown"}
    broken = [e for e in ens.executions if e.status == "model_breakdown"]
    assert all("past its range 1.03" in e.message and not len(e.times) for e in broken)
    # P(no switch by the last point) = 1 - pi there, pi ~ 1/2 (a 1-ball half past the wall).
    assert abs(len(broken) / 40 - 0.5) < 4 * math.sqrt(0.25 / 40)


@pytest.mark.parametrize(
    ("max_transitions", "shortest_dwell", "samples"),
    [
        # The short form: capped executions of this draw switch at most ~63 times, none dwelling
        # under 3e-5 s; uncapped, every one passes 200 switches, dwelling under 2e-7 s. Half the
        # samples of the long form (each uncapped one takes some 1.2 s of switching).
        (200, 1e-6, 4),
        # The long form follows the accumulation ten times further, to dwell times of 4e-12 s.
        pytest.param(2000, 1e-9, 8, marks=pytest.mark.slow),
    ],
)
def test_without_the_hazard_cap_the_two_tanks_accumulate_switches_past_the_zeno_time(
    max_transitions, shortest_dwell, samples
):
    # The finding behind the cap: the hazard rate pi' / (1 - pi) is unbounded as pi -> 1, and a
    # visit entered with its ball nearly all past its guard switches almost at once. At h = 0.01
    # (same seed as the test above) some executions then switch ever faster before t = 9 s,
    # which Theorem 2 excludes for bounded intensities.
    ref = TwoTankReference(0.75, 0.5, 0.5)
    x0 = np.array([1.0, 1.0])
    t_final = ref.zeno_time(x0) + 1.0

    def ensemble(**cap):
        return sample_ensemble(two_tanks(), "q1", x0, t_final, 0.01, "euler", samples=samples, seed=5, floor=1.0,
                               max_transitions=max_transitions, **cap)  # fmt: skip

    uncapped = ensemble(hazard_cap=math.inf)
    assert any(e.status == "max_transitions" for e in uncapped.executions)
    assert min(e.dwell_times.min() for e in uncapped.executions) < shortest_dwell
    capped = ensemble()
    assert all(e.status == "finished" for e in capped.executions)
    # The cap binds only in the tail of a passage (1 - pi below ~1%): a transversal crossing far
    # from the Zeno point switches at the same instant with and without it, for the same draw.
    # (One execution per seed: an ensemble shares its generator, whose later draws then depend
    # on how many switches the earlier executions took.)
    for seed in range(samples):
        a = sample_execution(two_tanks(), "q1", x0, 3.0, 0.01, "euler", rng=seed, floor=1.0)
        b = sample_execution(two_tanks(), "q1", x0, 3.0, 0.01, "euler", rng=seed, floor=1.0, hazard_cap=math.inf)
        assert a.times[0] == b.times[0]


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), "16", True])
def test_hazard_cap_must_be_positive(bad):
    with pytest.raises(SimulationError, match="hazard_cap must be a number > 0"):
        sample_execution(two_tanks(), "q1", np.array([1.0, 1.0]), 1.0, 0.04, "euler", floor=1.0, hazard_cap=bad)


def test_an_execution_whose_ball_outgrows_the_state_says_from_when():
    """The unit circle at omega = 5 rad/s crosses the wall x1 = 0.5 at asin(0.5) / 5 and
    (pi - asin(0.5)) / 5 s of each turn of 2 pi / 5 s. Its error bound grows like e^(5 t) and
    passes the state's size (1) near t = 2.95 s: from there the ball holds the wall on both sides
    and the execution draws no more switches, though the circle crosses 4 more times by 5 s. The
    execution must say from when (``unresolved_from``), and the ensemble's summary too; every
    true crossing before it is drawn. On the slow circle (omega = 1, B ~ 7e-5) nothing is said."""
    e = sample_execution(circular_flow(omega=5.0, wall=0.5), "inside", [0.0, 1.0], 5.0, 0.01, "rk4", rng=1)
    turns = 2.0 * math.pi / 5.0 * np.arange(4)[:, None]
    true = np.sort((turns + np.array([math.asin(0.5), math.pi - math.asin(0.5)]) / 5.0).ravel())
    true = true[true < 5.0]
    assert e.status == "finished" and e.unresolved_from is not None and e.max_radius > 1.0
    assert len(e.times) == int(np.sum(true < e.unresolved_from)) < len(true)
    np.testing.assert_allclose(e.times[:2], true[:2], atol=1e-6)
    ensemble = sample_ensemble(circular_flow(omega=5.0, wall=0.5), "inside", [0.0, 1.0], 5.0, 0.01, "rk4", samples=3)
    assert ensemble.summary()["unresolved"]["executions"] == 3
    slow = sample_execution(circular_flow(), "inside", [0.0, 1.0], 3.0, H, "rk4", rng=1)
    assert slow.unresolved_from is None
    slow_ensemble = sample_ensemble(circular_flow(), "inside", [0.0, 1.0], 3.0, H, "rk4", samples=2)
    assert slow_ensemble.summary()["unresolved"] is None
