"""The accuracy estimate every run can state (legsim.accuracy, `legsim run --check-accuracy`):
against closed-form errors, its refinement rule, and its JSON."""

import json

import numpy as np
import pytest

from legsim.accuracy import check_accuracy, refined
from legsim.cli import main
from legsim.scene import load_scene
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
