"""No crawl at extreme settings on a robot scene: the standing quadruped (a URDF robot, its
touchdown a joint impact with friction) at an eps below what float64 resolves is refused before
the run, naming the scene's integrator.eps (simulate: the mode) and the thinnest eps it could
take; at that thinnest eps it runs
its nominal steps and finishes; past the refusal, at eps = 1e-300, no step lands in the strip,
and the touchdown is crossed where the steps reach rounding instead of crawling there. At
tight error control the runner passes its apexes (its flight legs turn on time, not on the
state)."""

from __future__ import annotations

import sys

import pytest

from helpers.reliability import run_cli
from legsim import simulate
from legsim.errors import SceneError, SimulationError
from legsim.relaxed.resolution import thinnest_strip
from legsim.scene import load_scene

SHORT = "integrator.t_final=0.5"  # s: the feet touch down near 0.2 s


def test_the_quadruped_at_eps_1e_300_is_refused_before_the_run_naming_eps_mode_and_the_least_eps():
    scene = load_scene("quadruped_stand")
    least = thinnest_strip(scene.initial_state)
    code, out, err = run_cli("run", "quadruped_stand", "--set", "integrator.eps=1e-300", "--set", SHORT)
    assert code == 2 and out == "", err
    prefix = f"legsim: error: {scene.path}: integrator.eps: 1e-300 is thinner than float64 resolves"
    assert err.startswith(prefix), err
    assert f"give eps >= {least:.3g} in guard units" in err
    assert len(err.splitlines()) == 1


def test_the_quadruped_at_the_thinnest_eps_it_takes_finishes_in_its_nominal_steps():
    least = thinnest_strip(load_scene("quadruped_stand").initial_state)
    # Just below the least eps is refused, by the scene (naming its field) and by simulate (naming
    # the mode); the least itself runs.
    with pytest.raises(SceneError, match=r"integrator.eps: .* is thinner than float64 resolves"):
        load_scene("quadruped_stand", [SHORT, f"integrator.eps={least * 0.99!r}"])
    scene = load_scene("quadruped_stand", [SHORT, f"integrator.eps={least!r}"])
    with pytest.raises(SimulationError, match=r"eps = .* is thinner than float64 resolves .* in mode 'flight'"):
        simulate(scene.model.system, scene.initial_state, scene.initial_mode, 0.5, 1e-3, least * 0.99)
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
    monkeypatch.setattr(sys.modules["legsim.scene.load"], "_check_resolved", lambda path, x0, names, eps: None)
    ex = load_scene("quadruped_stand", [SHORT, "integrator.eps=1e-300"]).simulate()
    nominal = load_scene("quadruped_stand", [SHORT]).simulate()
    assert ex.status == "finished", ex.message
    (touchdown,) = ex.transitions
    (expected,) = nominal.transitions
    assert touchdown.name == expected.name and abs(touchdown.time - expected.time) < 1e-12
    assert ex.counters["guard_jumps"] == 1
    # 0.18 s of ordinary steps and one halving sequence down to rounding: not a crawl.
    assert ex.steps <= nominal.steps + 64


def test_the_runner_under_tight_error_control_passes_its_apexes_switching_its_legs_on_time():
    """The quadruped pronk under dop853 at rtol 1e-12: its flight legs turn from rising to falling
    at the apex time predicted at the liftoff (t + zd / g, memory ``apex``), not on the sign of
    the trunk's vertical speed, a switch on the state that held the flow at the apex (a sliding
    mode no error-controlled step passes; the core's stall message for such a field:
    tests/relaxed/test_simulate.py). The run passes its apexes to t_final."""
    fine = ["integrator.method=dop853", "integrator.rtol=1e-12", "integrator.atol=1e-12", "integrator.landing=dense"]
    ex = load_scene(
        "quadruped_pronk", ["integrator.t_final=1.5", "integrator.eps=1e-9", "integrator.h=2e-3", *fine]
    ).simulate()
    assert ex.status == "finished" and ex.t_end == 1.5, ex.message
    names = ex.state_names["flight"]
    zd, apex = names.index("zd"), names.index("apex_hind")
    liftoffs = [tr for tr in ex.transitions if tr.target == "flight" and tr.source != "flight"]
    assert len(liftoffs) >= 2
    for liftoff in liftoffs:
        after = liftoff.state_after
        # the memory is noted at the entry, after the strip (exit_time)
        assert after[apex] == pytest.approx(liftoff.exit_time + after[zd] / 9.81, abs=1e-12)
