"""No crawl at extreme settings on a robot scene: the standing quadruped (a URDF robot, its
touchdown a joint impact with friction) at an eps below what float64 resolves is refused before
the run, naming eps, the mode and the thinnest eps it could take; at that thinnest eps it runs
its nominal steps and finishes. At eps = 1e-300 it used to crawl at the touchdown, some 1e-14 s
of simulated time every 5 s of wall time."""

from __future__ import annotations

import re
import sys

import pytest

from helpers.reliability import run_cli
from legsim.errors import SimulationError
from legsim.relaxed.loop import STALL_WINDOW
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


def test_past_the_refusal_the_driver_ends_the_quadruped_at_eps_1e_300_stalled_at_the_touchdown(monkeypatch):
    # The refusal before the run is the first defence; the loop's stall rule is the second, for a
    # strip that becomes too thin during the run. Switched off, the first lets the run reach the
    # touchdown, where no step lands in a strip of 1e-300 m: the rule ends it there.
    monkeypatch.setattr(sys.modules["legsim.relaxed.simulate"], "_check_resolution", lambda eps, x, mode: None)
    ex = load_scene("quadruped_stand", [SHORT, "integrator.eps=1e-300"]).simulate()
    assert ex.status == "stalled", ex.message
    assert re.match(r"the run stopped advancing in mode 'flight' next to the guard of transition graze_", ex.message)
    assert f"to t={ex.t_end:.17g}" in ex.message
    assert 0.1 < ex.t_end < 0.3  # the feet reach the ground near 0.2 s
    # 0.18 s of ordinary steps, then one stall window: not a crawl of millions of steps.
    assert ex.steps <= ex.t_end / 1e-3 + 2 * STALL_WINDOW
