"""Walks against closed forms: the rimless wheel's step map w -> c sqrt(w^2 + K) (steps to the
gait and the distance left), the bouncing ball's bounces accumulating at a geometric rate (a
walk that chatters in place stops), the elastic ball repeating its bounce (another gait), and
the compass gait falling (its hip below the slope)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from legsim.orbits import OrbitProblem, Section, find_orbit
from legsim.scene import load_scene
from legsim.scene.orbit import problem_from_scene
from legsim.sweep.walk import CHATTER_RETURNS, MIN_RETURN_STEPS, walk
from legsim.systems.bouncing_ball import make_system

ALPHA = math.pi / 10
C = math.cos(2 * ALPHA)


def wheel_map(w: float, slope_deg: float = 5.0) -> float:
    K = 4 * 9.81 * math.sin(ALPHA) * math.sin(math.radians(slope_deg))
    return C * math.sqrt(w * w + K)


def omega_star(slope_deg: float = 5.0) -> float:
    K = 4 * 9.81 * math.sin(ALPHA) * math.sin(math.radians(slope_deg))
    return math.sqrt(C * C * K / (1 - C * C))


@pytest.mark.parametrize("w0", [2.6, 0.8])
def test_rimless_wheel_walk_converges_after_the_steps_of_its_step_map(w0):
    scene = load_scene("rimless_wheel", [f"initial.state.thetad={w0!r}"])
    problem = problem_from_scene(scene).problem
    fixed = np.array([-ALPHA, omega_star(), 0.0])
    tol = 1e-3
    # The closed form: w_k = map^k(w0); the walk converges at the first k with |w_k - w*| < tol.
    w, k, distances = w0, 0, []
    while abs(w - omega_star()) >= tol:
        w, k = wheel_map(w), k + 1
        distances.append(abs(w - omega_star()))
    # Not a borderline case: the step before is clearly out, this one clearly in.
    assert distances[-1] < 0.9 * tol and distances[-2] > 1.1 * tol
    result = walk(problem, scene.initial_state, 0.0, fixed, max_steps=40, tol=tol)
    assert result.outcome == "converges" and result.status == "finished"
    assert result.steps_to_gait == k == result.steps
    assert result.distance == pytest.approx(distances[-1], abs=1e-7)
    assert result.period == 1 and result.transitions == k
    # Each step advances the contact by one spoke spacing 2 l sin(alpha).
    assert result.state[2] == pytest.approx(k * 2 * math.sin(ALPHA), rel=1e-9)


def ball_problem(restitution: float, h: float = 1e-3) -> OrbitProblem:
    return OrbitProblem(make_system(restitution=restitution), Section.after("bounce"), h=h, eps=1e-6, t_max=3.0)


def test_bounces_accumulating_like_a_zeno_execution_make_a_walk_that_stops():
    # From z = 1 m at rest, bounce j + 1 follows bounce j after 2 v1 c^j / g (v1 = sqrt(2 g)).
    # The walk stops at the first return whose last CHATTER_RETURNS intervals are all shorter
    # than MIN_RETURN_STEPS steps h; the intervals shrink, so that is when the interval after
    # return K - CHATTER_RETURNS falls below it.
    h, c, g = 1e-3, 0.5, 9.81
    v1 = math.sqrt(2 * g)
    interval = [None] + [2 * v1 * c**j / g for j in range(1, 40)]
    first = next(j for j in range(1, 40) if interval[j] < MIN_RETURN_STEPS * h)
    assert interval[first] < 0.8 * MIN_RETURN_STEPS * h < interval[first - 1] * 0.8  # not borderline
    expected = first + CHATTER_RETURNS
    result = walk(ball_problem(c, h), np.array([1.0, 0.0]), 0.0, None, max_steps=40)
    assert result.outcome == "stops" and "chatters in place" in result.message
    assert result.steps == expected
    # ... at the closed-form time of that bounce (the relaxation delays each by O(eps)).
    t_expected = math.sqrt(2 / g) + sum(interval[1:expected])
    assert result.t_end == pytest.approx(t_expected, abs=1e-3)


def test_an_elastic_ball_repeats_its_bounce_which_is_another_gait_without_a_reference():
    result = walk(ball_problem(1.0), np.array([1.0, 0.0]), 0.0, None, max_steps=10)
    assert result.outcome == "other_gait" and result.period == 1 and result.steps == 2
    # With the bounce itself as the reference it converges at the first return instead.
    fixed = np.array([0.0, math.sqrt(2 * 9.81)])
    result = walk(ball_problem(1.0), np.array([1.0, 0.0]), 0.0, fixed, max_steps=10, tol=1e-3)
    assert result.outcome == "converges" and result.steps_to_gait == 1


def test_a_walk_that_runs_out_of_steps_is_undecided():
    # The wheel from far below its gait needs many steps (closed form above): 3 are too few.
    scene = load_scene("rimless_wheel", ["initial.state.thetad=0.9"])
    result = walk(
        problem_from_scene(scene).problem,
        scene.initial_state,
        0.0,
        np.array([-ALPHA, omega_star(), 0.0]),
        max_steps=3,
        tol=1e-3,
    )
    assert result.outcome == "undecided" and result.steps == 3 and result.steps_to_gait is None
    w = 0.9
    for _ in range(3):
        w = wheel_map(w)
    assert result.distance == pytest.approx(abs(w - omega_star()), abs=1e-7)


def test_a_compass_gait_kicked_backwards_falls_with_its_hip_below_the_slope():
    scene = load_scene("compass_gait", ["initial.state.stanced=0.6", "initial.state.hipd=-2.0"])
    settings = problem_from_scene(scene)
    gait = find_orbit(settings.problem, settings.guess, **settings.solver)
    result = walk(settings.problem, scene.initial_state, 0.0, gait.fixed_point)
    assert result.outcome == "falls" and result.status == "model_breakdown"
    assert math.cos(result.state[0]) < 1e-4  # the hip l cos(stance) is at or below the slope


def test_a_compass_gait_started_on_its_gait_converges_at_once():
    scene = load_scene("compass_gait")
    settings = problem_from_scene(scene)
    gait = find_orbit(settings.problem, settings.guess, **settings.solver)
    result = walk(settings.problem, gait.fixed_point, 0.0, gait.fixed_point, tol=1e-6)
    assert result.outcome == "converges" and result.steps_to_gait == 1 and result.distance < 1e-8
    assert result.t_end == pytest.approx(gait.return_time, rel=1e-9)


def test_a_walk_keeps_each_warning_of_its_runs_once(monkeypatch):
    """A walk is many runs, one per transition: each run's warning reaches the walk's result,
    once however many runs repeat it (here every run is made to carry one)."""
    import dataclasses

    import legsim.sweep.walk as walk_module
    from legsim.execution import RunWarning

    real = walk_module.simulate
    warned = RunWarning("strip_hold", "held in strips", 0.0)

    def simulate_with_a_warning(*args, **kwargs):
        ex = real(*args, **kwargs)
        return dataclasses.replace(ex, warnings=[*ex.warnings, warned])

    monkeypatch.setattr(walk_module, "simulate", simulate_with_a_warning)
    scene = load_scene("rimless_wheel", ["initial.state.thetad=2.6"])
    fixed = np.array([-ALPHA, omega_star(), 0.0])
    result = walk(problem_from_scene(scene).problem, scene.initial_state, 0.0, fixed, max_steps=40, tol=1e-3)
    assert result.outcome == "converges" and result.steps > 1
    assert result.warnings == ["strip_hold: held in strips"]


#: The quadruped dropped with its knees folded: its thighs, which have no contact, reach the
#: ground before its feet do.
FOLDED = ['robot.parameters.below_ground="fall"', "initial.state.z=0.3", "initial.state.hind_knee=2.4",
          "initial.state.front_knee=-2.4"]  # fmt: skip


@pytest.mark.parametrize("name", ["slip_raibert", "quadruped_pronk_forward"])
def test_a_controlled_walk_follows_one_continuous_run_of_the_closed_loop(name):
    """Three steps of a controlled walk, each a return restarted with the controller restored to
    its memory, against one run of the scene's closed loop through the same three returns: the
    controller's memory carries over (the quadruped's includes touchdown epochs and places along
    x, shifted into each return's frame and back). Both runs are dop853 at rtol 1e-13 (the
    scenes' orbit.integrator); they take different steps after each restart and locate the
    crossing on different interpolants, so they agree to about 1e-11 s in time and 3e-9 in
    state (rad/s), not to rounding."""
    from legsim.crossings import returns
    from legsim.relaxed import simulate

    scene = load_scene(name)
    problem = problem_from_scene(scene).problem
    result = walk(problem, scene.initial_state, 0.0, None, max_steps=3, tol=1e-14)
    assert result.outcome == "undecided" and result.steps == 3
    system, _ = problem.instantiate()
    law = problem.restored_controller(dict(problem.parameters), problem.memory_guess)
    start = np.concatenate([scene.initial_state, problem.memory_guess])
    p = problem
    run = simulate(system, start, p.bound.mode, result.t_end + 0.01, p.h, p.eps, p.tableau, law, rtol=p.rtol,
                   atol=p.atol, landing=p.landing, max_halvings=p.max_halvings)  # fmt: skip
    hits = list(returns(run, p.bound.mode, p.bound.s, p.section.direction, p.min_transitions, p.min_time))
    assert len(hits) == 3
    _, t_third, x_third = hits[-1]
    assert abs(t_third - result.t_end) < 1e-10
    assert np.abs(x_third[: p.dim] - result.state).max() < 1e-8
    assert result.transitions == len([tr for tr in run.transitions if tr.exit_time <= t_third])


def test_a_controlled_walk_that_falls_after_some_steps_falls_where_one_continuous_run_does():
    """Thrown from a 2 m apex at 3.25 m/s, the SLIP runner falls (its body down to the [fall]
    section's 0.5 m) in stance after several hops. The walk's fall, after its returns, is the one
    continuous run of the closed loop meets: the same time and state, the stance foot's place
    along x included (a coordinate of the stance mode only), to the accuracy of the restarts."""
    from legsim.crossings import returns
    from legsim.relaxed import simulate

    scene = load_scene("slip_raibert", ["fall.height_min=0.5", "initial.state.xd=3.25", "initial.state.z=2.0"])
    p = problem_from_scene(scene).problem
    checks = scene.watches(scene.control, p.eps)
    result = walk(p, scene.initial_state, 0.0, None, max_steps=40, tol=1e-14, watches=checks)
    assert result.outcome == "falls" and result.status == "fell" and result.mode == "stance"
    system, _ = p.instantiate()
    law = p.restored_controller(dict(p.parameters), p.memory_guess)
    start = np.concatenate([scene.initial_state, p.memory_guess])
    run = simulate(system, start, p.bound.mode, 20.0, p.h, p.eps, p.tableau, law, rtol=p.rtol, atol=p.atol,
                   landing=p.landing, max_halvings=p.max_halvings, watches=checks)  # fmt: skip
    assert run.status == "fell" and run.final_mode == "stance"
    apexes = list(returns(run, p.bound.mode, p.bound.s, p.section.direction, p.min_transitions, p.min_time))
    assert result.steps == len(apexes) >= 3
    assert abs(run.t_end - result.t_end) < 1e-10
    assert np.abs(run.final_state[: result.state.shape[0]] - result.state).max() < 1e-8


def test_a_controlled_walk_without_a_return_within_t_max_stops_where_its_run_ended():
    # The SLIP runner's first apex comes 0.63 s after its start; with t_max = 0.3 s none does.
    # The walk ends where the return's run did, in stance at t_max, with the plant's state (the
    # controller's memory, which the run's state carries after it, left out).
    scene = load_scene("slip_raibert", ["orbit.t_max=0.3"])
    problem = problem_from_scene(scene).problem
    result = walk(problem, scene.initial_state, 0.0, None, max_steps=3)
    assert result.outcome == "stops" and result.status == "finished" and result.steps == 0
    assert "within t_max = 0.3 s" in result.message
    assert result.t_end == pytest.approx(0.3, abs=1e-12) and result.mode == "stance"
    assert result.state.shape == (len(problem.instantiate()[0].state_names("stance")),)
    assert result.counters["steps"] > 0


def test_a_sweeps_controlled_walk_converges_or_falls_by_the_scenes_fall_section():
    """The SLIP runner under Raibert's controller walks to its gait from 1 m/s; thrown at 8 m/s it
    comes down to the [fall] section's height bound in its first flight: a fall, not a run that
    failed (without the watch, the run would end halving_exhausted, its leg inside the ground)."""
    from legsim.sweep import tasks
    from legsim.sweep.spec import SweepSpec

    spec = SweepSpec(scene="slip_raibert", overrides=("fall.height_min=0.5",), run="walk")
    rows = {}
    for xd in (1.0, 8.0):
        values = {"initial.state.xd": xd}
        scene = load_scene("slip_raibert", ["fall.height_min=0.5", f"initial.state.xd={xd}"])
        rows[xd] = tasks.walk_row(scene, spec, values, tasks.Deadline(None))
    assert rows[1.0]["outcome"] == "converges" and not rows[1.0]["fell"]
    assert rows[1.0]["distance_to_gait"] < 1e-3
    fell = rows[8.0]
    assert fell["outcome"] == "falls" and fell["status"] == "fell" and fell["fell"]
    assert "height_min" in fell["message"] and fell["walk_steps"] == 0
    assert fell["final_state"][1] == pytest.approx(0.5, abs=1e-9)


def test_a_sweeps_walk_takes_the_scenes_watches_at_the_walks_strip_width(monkeypatch):
    import legsim.sweep.walk as walk_module
    from legsim.sweep import tasks
    from legsim.sweep.spec import SweepSpec

    class Gait:
        converged, fixed_point = True, None

    seen = {}

    def capture(problem, x0, t0, fixed_point, **options):
        seen.update(options, eps=problem.eps)
        raise RuntimeError("captured")

    monkeypatch.setattr(tasks, "reference_gait", lambda spec, values: Gait())
    monkeypatch.setattr(walk_module, "walk", capture)
    scene = load_scene("quadruped_pronk", FOLDED)
    with pytest.raises(RuntimeError, match="captured"):
        tasks.walk_row(scene, SweepSpec(scene="quadruped_pronk"), {}, tasks.Deadline(None))
    names = [w.name for w in seen["watches"]]
    assert "pitch_max" in names and "below_ground" in names and "passed_through" in names
    # The allowance of passed_through is the walk's eps (the orbit's 1e-11), not the run's 1e-4.
    passed = next(w for w in seen["watches"] if w.name == "passed_through")
    assert "eps = 1e-11 +" in passed.message(0.0, "flight", scene.initial_state)
    assert seen["eps"] == 1e-11


def test_an_orbit_row_without_an_orbit_carries_no_fixed_point_period_or_step_length():
    # One Newton step at a tolerance below rounding: the search stops unconverged, and its last
    # iterate is no gait (the columns are null, its residual says how far it was).
    from legsim.sweep import tasks

    scene = load_scene("compass_gait", ["orbit.max_iterations=1", "orbit.tol=1e-15"])
    row = tasks.orbit_columns(scene, tasks.Deadline(None))
    assert row["orbit_status"] != "converged"
    assert row["orbit_fixed_point"] is None and row["orbit_period"] is None and row["orbit_step_length"] is None
    assert row["orbit_spectral_radius"] is None and row["orbit_residual"] > 1e-15
    found = tasks.orbit_columns(load_scene("compass_gait"), tasks.Deadline(None))
    assert found["orbit_status"] == "converged" and found["orbit_period"] > 0 and len(found["orbit_fixed_point"]) > 0


def test_a_controlled_walks_row_says_how_its_last_return_ended_and_on_which_clock():
    # Each return of a controlled walk runs on a clock restarted at the return: a message's
    # times are that clock's, and the row says where it started, so that start + the message's
    # time is the walk's end. A return that spent its transition budget is max_transitions (it
    # was `finished`, its message saying otherwise).
    import re

    from legsim.sweep import tasks
    from legsim.sweep.spec import SweepSpec

    spec = SweepSpec(scene="slip_raibert", overrides=("fall.height_min=0.5",), run="walk")
    rows = {}
    for xd, z in ((0.25, 1.05), (3.0, 2.05)):
        values = {"initial.state.xd": xd, "initial.state.z": z}
        scene = load_scene("slip_raibert", ["fall.height_min=0.5", f"initial.state.xd={xd}", f"initial.state.z={z}"])
        rows[xd] = tasks.walk_row(scene, spec, values, tasks.Deadline(None))
    assert rows[0.25]["outcome"] == "stops" and rows[0.25]["status"] == "max_transitions"
    assert "transition budget" in rows[0.25]["message"]
    fell = rows[3.0]
    assert fell["outcome"] == "falls" and fell["status"] == "fell"
    at, start = (float(v) for v in re.findall(r"at t=([0-9.e+-]+)", fell["message"])[:2])
    assert start + at == pytest.approx(fell["t_end"], abs=1e-9)
