"""The accuracy estimate every run can state (legsim.accuracy, `legsim run --check-accuracy`):
against closed-form errors, its refinement rule, and its JSON."""

import json
import math

import numpy as np
import pytest

from legsim.accuracy import along_orbit, check_accuracy, refined
from legsim.cli import main
from legsim.scene import bundled_dir, load_scene
from legsim.systems.bouncing_ball import BouncingBallReference, make_system


def test_the_estimate_brackets_the_closed_form_error_of_example_1():
    scene = load_scene("oscillator_ex1")
    run, estimate = scene.check_accuracy()
    true = np.abs(run.final_state - scene.reference.state(run.t_end))
    guess = np.array([estimate.final_state[name] for name in ("x", "xd")])
    assert true.max() / 3 <= guess.max() <= 3 * true.max()
    sizes = [max(np.abs(seg.x[:, i]).max() for seg in run.segments) for i in range(2)]
    assert estimate.final_state_relative == pytest.approx(max(guess / sizes), rel=1e-2)
    assert not estimate.transitions_differ and estimate.transitions_matched == len(run.transitions) > 40


def test_the_estimate_of_the_ball_brackets_its_impact_time_error():
    # Free fall is a cubic: RK4 is exact, and the impact times lag the exact ones only by the
    # strip holds (first order in eps): the estimate against eps / 10 is 9/10 of the lag.
    ref = BouncingBallReference(9.81, 0.5, 1.0, 0.0)
    run, estimate = check_accuracy(make_system(9.81, 0.5), [1.0, 0.0], "flight", 1.0, 1e-3, 1e-3, "rk4")
    first_impacts = ref.impact_time(np.arange(1, 4))  # compared with the run's first three transitions
    lag = max(abs(tr.time - t) for tr, t in zip(run.transitions, first_impacts, strict=False))
    assert lag / 3 <= estimate.transition_times <= 3 * lag


def test_the_refined_run_has_eps_over_10_and_half_the_step_or_a_tenth_of_the_tolerances():
    assert refined({"h": 0.1, "eps": 1e-3, "rtol": None, "atol": None}) == {
        "h": 0.05,
        "eps": 1e-4,
        "rtol": None,
        "atol": None,
    }
    assert refined({"h": 0.1, "eps": 1e-3, "rtol": 1e-6, "atol": 1e-9}) == {
        "h": 0.1,
        "eps": 1e-4,
        "rtol": 1e-7,
        "atol": 1e-10,
    }


def test_run_check_accuracy_reports_the_estimate_in_json_and_text(capsys):
    assert main(["run", "bouncing_ball", "--check-accuracy", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    estimate = summary["error_estimate"]
    eps = load_scene("bouncing_ball").integrator["eps"]
    assert set(estimate["final_state"]) == {"z", "zd"} and estimate["refined"]["eps"] == pytest.approx(eps / 10)
    assert main(["run", "bouncing_ball", "--check-accuracy"]) == 0
    text = capsys.readouterr().out
    assert "estimated error (against eps/10, h/2):" in text and "transition times:" in text
    assert estimate["along_orbit"]["section"] == "flight" and estimate["along_orbit"]["crossings"] > 3
    assert "along the orbit (states at " in text and "entries into 'flight', phase-aligned)" in text


def test_along_the_orbit_a_run_late_by_a_constant_time_has_no_error_but_its_phase():
    # The same bounce started 0.1 s later: at any fixed time its state is far off, but it is the
    # same execution shifted in time, so at matching entries the states agree to rounding and
    # the entry times are 0.1 s apart.
    from legsim import simulate

    system = make_system(9.81, 0.8)
    early = simulate(system, [1.0, 0.0], "flight", 2.0, 1e-3, 1e-4, "rk4")
    late = simulate(system, [1.0, 0.0], "flight", 2.1, 1e-3, 1e-4, "rk4", t0=0.1)
    assert np.abs(early.sample([2.0]).states[0] - late.sample([2.0]).states[0]).max() > 0.1
    orbit = along_orbit(early, late)
    assert orbit.section == "flight" and orbit.crossings == len(early.transitions) >= 3
    assert orbit.relative < 1e-12
    assert orbit.phase == pytest.approx(0.1, abs=1e-12)


def test_along_the_orbit_the_balls_error_is_in_its_timing_not_its_rebounds():
    # Free fall is a cubic, which RK4 integrates exactly, and each impact is reset at the guard
    # point: the k-th rebound leaves the floor at exactly c^k sqrt(2 g z0). The run's error is
    # all in its timing (the strip holds), and the along-the-orbit estimate separates the two.
    g, c, z0 = 9.81, 0.8, 1.0
    run, estimate = check_accuracy(make_system(g, c), [z0, 0.0], "flight", 2.5, 1e-3, 1e-3, "rk4")
    orbit = estimate.along_orbit
    rebounds = np.array([seg.x[0, 1] for seg in run.segments[1:]])
    exact = c ** np.arange(1, len(rebounds) + 1) * np.sqrt(2 * g * z0)
    assert len(rebounds) >= 3 and np.abs(rebounds - exact).max() < 1e-12
    assert orbit.crossings == estimate.transitions_matched == len(rebounds)
    assert orbit.relative < 1e-12
    # entries are strip exits, a hold after each guard crossing: their lag is the crossings' and
    # the holds' together
    assert estimate.transition_times / 3 <= orbit.phase <= 3 * estimate.transition_times
    assert along_orbit(run, run).relative == 0.0


def test_along_the_orbit_at_the_balls_apexes_the_states_are_exact_and_only_the_times_differ():
    # At each apex the ball is at c^(2k) z0 with zd = 0 exactly in both runs (free fall is exact
    # under RK4 and the stored flow's Hermite interpolant): compared there, the runs agree to
    # rounding, and the apexes' times lag as the rebounds' do.
    from legsim.accuracy import OrbitSection

    g, c, z0 = 9.81, 0.8, 1.0
    apex = OrbitSection("flight", "zd = 0 (decreasing) in flight", lambda x: x[1], -1)
    run, estimate = check_accuracy(make_system(g, c), [z0, 0.0], "flight", 2.5, 1e-3, 1e-3, "rk4", section=apex)
    orbit = estimate.along_orbit
    assert orbit.where == "crossings of zd = 0 (decreasing) in flight" and orbit.section == "flight"
    assert orbit.crossings == len(run.transitions) >= 3 and orbit.unmatched == 0
    assert orbit.state["z"] < 1e-12 and orbit.state["zd"] < 1e-12
    assert orbit.phase == pytest.approx(estimate.along_orbit.phase) and orbit.phase > 1e-6


BALL_TO_1_S = ["integrator.t_final=1.0"]


def ball_scene(tmp_path, accuracy: str):
    text = (bundled_dir() / "bouncing_ball.toml").read_text() + "\n[accuracy]\n" + accuracy + "\n"
    path = tmp_path / "ball.toml"
    path.write_text(text)
    return path


def test_a_scenes_accuracy_section_chooses_where_the_runs_are_compared_along_the_orbit(tmp_path, capsys):
    path = ball_scene(tmp_path, 'along = { mode = "flight", coordinate = "zd", value = 0.0, direction = "decreasing" }')
    _, estimate = load_scene(path, BALL_TO_1_S).check_accuracy()
    assert estimate.along_orbit.where == "crossings of zd = 0 (decreasing) in flight"
    assert main(["run", str(path), "--check-accuracy", *(f"--set={o}" for o in BALL_TO_1_S)]) == 0
    assert "crossings of zd = 0 (decreasing) in flight, phase-aligned)" in capsys.readouterr().out
    entries = ball_scene(tmp_path, 'along = "entries"')
    _, estimate = load_scene(entries, BALL_TO_1_S).check_accuracy()
    assert estimate.along_orbit.where == "entries into 'flight'"


@pytest.mark.parametrize(
    ("accuracy", "field", "message"),
    [
        ('along = "apex"', "accuracy.along", "expected 'entries', 'orbit' or a section table"),
        ('along = "orbit"', "accuracy.along", "the scene has none"),
        ('along = "entries"\nmin_time = 0.1', "accuracy.min_time", "along = 'entries' has none"),
        ('along = { mode = "flight", coordinate = "zdd" }', "accuracy.along", "no coordinate 'zdd'"),
        ('along = { mode = "flight", coordinate = "zd" }\nmin_transitions = -1', "accuracy.min_transitions", ">= 0"),
        ('alongside = "entries"', "accuracy: unknown key(s) ['alongside']", "allowed: ['along', "),
    ],
)
def test_a_bad_accuracy_section_is_named_before_anything_runs(tmp_path, accuracy, field, message):
    from legsim import SceneError

    scene = load_scene(ball_scene(tmp_path, accuracy), BALL_TO_1_S)
    with pytest.raises(SceneError) as caught:
        scene.check_accuracy()
    assert "ball.toml" in str(caught.value) and field in str(caught.value) and message in str(caught.value)


def test_the_quotient_distance_at_matched_crossings_is_the_rebound_speeds_difference_in_closed_form():
    # Two balls dropped from 1 m and 1.0001 m: their k-th rebounds leave the floor at exactly
    # c^k sqrt(2 g z0), so at matched entries the plant states differ by c^k sqrt(2 g) times
    # the difference of the square roots, largest at the first rebound; shorter than eps, that
    # chord is the quotient distance (every other path crosses a strip, of length eps).
    from legsim import simulate

    g, c, eps = 9.81, 0.8, 1e-3
    system = make_system(g, c)
    low = simulate(system, [1.0, 0.0], "flight", 2.5, 1e-3, eps, "rk4")
    high = simulate(system, [1.0001, 0.0], "flight", 2.5, 1e-3, eps, "rk4")
    orbit = along_orbit(low, high, system=system)
    first = c * math.sqrt(2 * g) * (math.sqrt(1.0001) - 1.0)
    assert orbit.crossings >= 3 and first < eps
    assert orbit.quotient == pytest.approx(first, rel=1e-9)
    assert along_orbit(low, high).quotient is None


def test_phase_aligned_the_quotient_distance_sees_no_timing_error():
    # The same bounce started 0.1 s later: far apart at equal times, the same at matched entries.
    from legsim import simulate

    system = make_system(9.81, 0.8)
    early = simulate(system, [1.0, 0.0], "flight", 2.0, 1e-3, 1e-4, "rk4")
    late = simulate(system, [1.0, 0.0], "flight", 2.1, 1e-3, 1e-4, "rk4", t0=0.1)
    assert along_orbit(early, late, system=system).quotient < 1e-12
    _, estimate = check_accuracy(system, [1.0, 0.0], "flight", 2.0, 1e-3, 1e-3, "rk4")
    assert estimate.along_orbit.quotient < 1e-3 * estimate.quotient_distance.value


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({}, "give a function or a transition"),
        ({"function": lambda x: x[1], "transition": "bounce"}, "give a function or a transition"),
        ({"function": 1.0}, "must be callable"),
        ({"function": lambda x: x[1], "direction": 2}, r"direction must be -1, 0 or \+1"),
        ({"function": lambda x: x[1], "min_time": -1.0}, "must be >= 0"),
    ],
)
def test_a_bad_orbit_section_is_refused_by_name(kwargs, message):
    from legsim import SimulationError
    from legsim.accuracy import OrbitSection

    with pytest.raises(SimulationError, match=message) as caught:
        OrbitSection("flight", "apex", **kwargs)
    assert "'apex'" in str(caught.value)
