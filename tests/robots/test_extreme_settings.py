"""No crawl at extreme settings on a robot scene: the standing quadruped (a URDF robot, its
touchdown a joint impact with friction) at an eps below what float64 resolves is refused before
the run, naming eps, the mode and the thinnest eps it could take; at that thinnest eps it runs
its nominal steps and finishes; past the refusal, at eps = 1e-300, no step lands in the strip,
and the touchdown is crossed where the steps reach rounding instead of crawling there."""

from __future__ import annotations

import sys

import pytest

from helpers.reliability import run_cli
from legsim.errors import SimulationError
from legsim.relaxed.resolution import thinnest_strip
from legsim.scene import load_scene

SHORT = "integrator.t_final=0.5"  # s: the feet touch down near 0.2 s


def test_the_quadruped_at_eps_1e_300_is_refused_before_the_run_naming_eps_mode_and_the_least_eps():
    scene = load_scene("quadruped_stand")
    least = thinnest_strip(scene.initial_state)
    code, out, err = run_cli("run", "quadruped_stand", "--set", "integrator.eps=1e-300", "--set", SHORT)
    assert code == 2 and out == "", err
    assert err.startswith("legsim: error: eps = 1e-300 is thinner than float64 resolves"), err
    assert "in mode 'flight'" in err and f"give eps >= {least:.3g} in guard units" in err
    assert len(err.splitlines()) == 1


def test_the_quadruped_at_the_thinnest_eps_it_takes_finishes_in_its_nominal_steps():
    least = thinnest_strip(load_scene("quadruped_stand").initial_state)
    # Just below the least eps is refused; the least itself runs.
    with pytest.raises(SimulationError, match=r"eps = .* is thinner than float64 resolves"):
        load_scene("quadruped_stand", [SHORT, f"integrator.eps={least * 0.99!r}"]).simulate()
    scene = load_scene("quadruped_stand", [SHORT, f"integrator.eps={least!r}"])
    ex = scene.simulate()
    assert ex.status == "finished", ex.message
    assert ex.transitions and ex.t_end == pytest.approx(0.5)  # through the touchdown, to t_final
    # Fixed steps of h = 1 ms over 0.5 s are 500; the touchdown's strip and the crossings add a
    # few. A crawl at the touchdown took thousands of steps for no time.
    nominal = 0.5 / scene.integrator["h"]
    assert ex.steps <= 1.1 * nominal, ex.steps


def test_past_the_refusal_the_quadruped_at_eps_1e_300_crosses_its_touchdown_where_steps_reach_rounding(monkeypatch):
    # The refusal before the run is the first defence. Switched off, the run reaches the
    # touchdown, where no step lands in a strip of 1e-300 m: the bridge's modes cross a guard
    # past its strip once the step moves t and x by rounding only (``crosses_jumps``), which
    # locates the touchdown where the default eps's crossing point q is, to the last digit.
    monkeypatch.setattr(sys.modules["legsim.relaxed.simulate"], "_check_resolution", lambda eps, x, mode: None)
    ex = load_scene("quadruped_stand", [SHORT, "integrator.eps=1e-300"]).simulate()
    nominal = load_scene("quadruped_stand", [SHORT]).simulate()
    assert ex.status == "finished", ex.message
    (touchdown,) = ex.transitions
    (expected,) = nominal.transitions
    assert touchdown.name == expected.name and abs(touchdown.time - expected.time) < 1e-12
    assert ex.counters["guard_jumps"] == 1
    # 0.18 s of ordinary steps and one halving sequence down to rounding: not a crawl.
    assert ex.steps <= nominal.steps + 64


def test_a_stall_of_the_error_control_away_from_guards_says_so_and_not_strip_advice():
    """The quadruped pronk under dop853 at rtol 1e-12: at its first apex the runner law's flight
    legs switch on the trunk's vertical speed, a sliding mode of the field that error control
    cannot step across. The run stops `stalled` there (t = 0.455 s, zd at rounding), saying the
    error control took the step to rounding with no guard near, not that a thicker strip would
    let steps land."""
    fine = ["integrator.method=dop853", "integrator.rtol=1e-12", "integrator.atol=1e-12", "integrator.landing=dense"]
    ex = load_scene("quadruped_pronk", [SHORT, "integrator.eps=1e-9", "integrator.h=2e-3", *fine]).simulate()
    assert ex.status == "stalled" and 0.45 < ex.t_end < 0.46
    assert abs(ex.final_state[ex.state_names["flight"].index("zd")]) < 1e-9
    assert "error control took the step down to" in ex.message and "sliding mode" in ex.message
    assert "next to the guard" not in ex.message and "thicker strip" not in ex.message
