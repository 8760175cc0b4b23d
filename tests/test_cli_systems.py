"""`legsim run` on the bundled analytic scenes: the JSON summary against a direct `simulate` call
and the closed forms, and effects switched on and off seen in the evaluation counts."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from legsim import simulate
from legsim.cli import main
from legsim.scene import load_scene


def run_json(capsys, *argv):
    code = main(["run", *argv, "--json"])
    out, err = capsys.readouterr()
    return code, json.loads(out), err


def test_bouncing_ball_json_equals_direct_simulate_and_closed_form(capsys):
    from legsim.systems.bouncing_ball import BouncingBallReference, make_system

    code, summary, err = run_json(capsys, "bouncing_ball")
    assert code == 0 and err == "" and summary["status"] == "finished"
    scene = load_scene("bouncing_ball")
    s = scene.integrator
    # The same system built by hand from the scene's numbers, simulated directly.
    system = make_system(g=9.81, restitution=0.5)
    direct = simulate(system, [1.0, 0.0], "flight", s["t_final"], s["h"], s["eps"], s["method"])
    assert summary["final_state"] == direct.final_state.tolist()
    assert summary["final_mode"] == direct.final_mode == "rest"  # accumulating bounces continue at rest
    assert summary["state_names"] == ["z", "zd"] and summary["t_final"] == s["t_final"] == 2.7
    assert summary["transitions"] == len(direct.transitions)
    assert summary["mode_sequence"] == direct.mode_sequence
    for key in ("steps", "halvings", "field_evals", "guard_evals", "reset_evals"):
        assert summary[key] == direct.counters[key], key
    # Energy m (g z + zd^2 / 2) with m = 1: 9.81 J at rest at z = 1.
    assert summary["energy_initial"] == pytest.approx(9.81, rel=1e-15)
    z, zd = summary["final_state"]
    assert summary["energy_final"] == pytest.approx(9.81 * z + 0.5 * zd**2, rel=1e-12)
    # Past the Zeno time the ball rests on the floor: within eps of z = 0, at rest.
    ref = BouncingBallReference(g=9.81, restitution=0.5, z0=1.0)
    assert s["t_final"] > ref.zeno_time
    assert abs(z) <= s["eps"] and abs(zd) < 1e-6
    # Free fall is cubic in t: the first impact is exact to rounding.
    assert abs(direct.transitions[0].time - ref.first_impact) < 1e-12


def test_oscillator_without_stop_evaluates_no_guard_and_converges_to_closed_form(capsys):
    t_final = 10 * math.pi
    errors = []
    for h in (2e-2, 1e-2):
        code, summary, _ = run_json(
            capsys,
            "oscillator_ex1",
            "--set",
            "effects.stop=false",
            "--set",
            f"integrator.h={h}",
            "--set",
            f"integrator.t_final={t_final}",
        )
        assert code == 0
        # No stop: one mode, no guard, no reset, ever.
        assert summary["guard_evals"] == 0 and summary["reset_evals"] == 0 and summary["transitions"] == 0
        assert summary["mode_sequence"] == ["free"] and summary["halvings"] == 0
        # RK4: four field evaluations a step (the first of a step is the last one's end).
        assert summary["field_evals"] == pytest.approx(4 * summary["steps"], abs=2)
        reference = load_scene("oscillator_ex1", overrides=["effects.stop=false"]).model.reference
        errors.append(np.linalg.norm(np.array(summary["final_state"]) - reference.state(t_final)))
    # The error against the closed form falls like h^4 (RK4): halving h divides it by ~16.
    assert 3.5 < math.log2(errors[0] / errors[1]) < 4.5


def test_oscillator_with_stop_counts_the_reference_impacts(capsys):
    t_final = 10.0
    code, summary, _ = run_json(capsys, "oscillator_ex1", "--set", f"integrator.t_final={t_final}")
    assert code == 0 and summary["guard_evals"] > 0
    reference = load_scene("oscillator_ex1").model.reference
    impacts = reference.impact_times(t_final)
    assert summary["transitions"] == summary["reset_evals"] == len(impacts) > 0
    assert summary["mode_sequence"] == ["free"] * (len(impacts) + 1)


def test_double_pendulum_stop_and_damping_switch_guards_and_terms(capsys):
    short = ["--set", "integrator.t_final=2"]
    _, with_stop, _ = run_json(capsys, "double_pendulum_zeno", *short)
    _, no_stop, _ = run_json(capsys, "double_pendulum_zeno", *short, "--set", "effects.stop=false")
    _, damped, _ = run_json(capsys, "double_pendulum_zeno", *short, "--set", "effects.damping=true")
    assert with_stop["guard_evals"] > 0 and with_stop["transitions"] > 0
    assert no_stop["guard_evals"] == 0 and no_stop["transitions"] == 0 and no_stop["mode_sequence"] == ["unconstrained"]
    # The damping term is computed only when the scene asks for it.
    assert with_stop["damping_evals"] == 0 and no_stop["damping_evals"] == 0
    assert damped["damping_evals"] >= damped["steps"] > 0
    # Without damping or a stop the pendulum's energy is conserved up to the method's drift; the
    # damped one loses energy (b > 0) relative to the undamped run with the same impacts.
    assert damped["energy_final"] < with_stop["energy_final"]


def test_double_pendulum_controller_is_built_only_when_asked(capsys):
    # The PD scene actuates the shoulder (one actuation term per dynamics solve asked for: a
    # solve the native library serves from its last one, same inputs, counts in cache_hits); off,
    # the same scene has no actuated joint and computes no actuation term at all.
    short = ["--set", "integrator.t_final=1"]
    code, pd, _ = run_json(capsys, "double_pendulum_pd", *short)
    _, off, _ = run_json(capsys, "double_pendulum_pd", *short, "--set", "effects.controller=false")
    assert code == 0 and pd["status"] == off["status"] == "finished"
    assert pd["actuation_evals"] == pd["aba"] + pd["cache_hits"] and pd["aba"] > 0
    assert off["actuation_evals"] == 0 and off["aba"] > 0
    # the controller lifts link 1 towards its target (1 rad); without it the shoulder swings back
    assert pd["final_state"][0] > 0.6 and off["final_state"][0] < 0.3
    # and the plastic-stop scene gains the controller from the command line, with its parameters
    _, added, _ = run_json(capsys, "double_pendulum_plastic", *short, "--set", "effects.controller.kp=80")
    assert added["actuation_evals"] > 0 and added["scene"] == "double_pendulum_plastic"


def test_digital_control_json_takes_the_simultaneous_crossing(capsys):
    code, summary, _ = run_json(capsys, "digital_control")
    scene = load_scene("digital_control")
    s = scene.integrator
    direct = simulate(
        scene.model.system,
        scene.initial_state,
        scene.initial_mode,
        s["t_final"],
        s["h"],
        s["eps"],
        s["method"],
        scene.model.control,
        max_transitions=s["max_transitions"],
    )
    assert code == 0 and summary["mode_sequence"] == direct.mode_sequence
    # Both thresholds are crossed at once (paper 000 Fig. 1): one transition, then the next at once.
    assert summary["mode_sequence"] == ["0", "1", "3"]
    assert direct.transitions[1].time == direct.transitions[0].exit_time
    assert summary["final_state"] == direct.final_state.tolist()


def test_pronk_with_one_leg_has_two_modes_and_a_fall_exits_3(capsys):
    from legsim.graph import reachable_modes

    scene = load_scene("pronk", overrides=["effects.left_leg=false"])
    assert sorted(reachable_modes(scene.model.system, scene.initial_mode)) == ["aerial", "right"]
    both = load_scene("pronk")
    assert len(both.model.system.outgoing("aerial")) == 2 and len(scene.model.system.outgoing("aerial")) == 1
    # On one leg the runner pitches over and falls: the run stops early, exit code 3, the
    # summary still printed and the reason on stderr.
    code, summary, err = run_json(capsys, "pronk", "--set", "effects.left_leg=false")
    assert code == 3 and summary["status"] != "finished" and summary["t_final"] < 2.0
    assert set(summary["mode_sequence"]) <= {"aerial", "right"}
    assert err.startswith(f"legsim: run stopped early ({summary['status']}): ")


def test_readme_demo_writes_rrd_html_and_png_and_replay_agrees(tmp_path, capsys):
    # `make demo` is `legsim run pronk --rrd out/pronk.rrd --html out/pronk.html --plot out/pronk.png`;
    # cut to the first hop (0.8 s: touchdowns, both stance, liftoffs) to keep the test short.
    from matplotlib.image import imread

    from legsim.record import read_rrd

    out = tmp_path / "out"
    files = {kind: out / f"pronk.{ext}" for kind, ext in (("rrd", "rrd"), ("html", "html"), ("plot", "png"))}
    code, summary, err = run_json(
        capsys,
        "pronk",
        "--set",
        "integrator.t_final=0.8",
        *[a for kind, p in files.items() for a in (f"--{kind}", str(p))],
    )
    assert code == 0 and err == "" and summary["transitions"] == 4
    assert summary["outputs"] == {kind: str(p) for kind, p in files.items()}
    assert sorted(p.name for p in out.iterdir()) == ["pronk.html", "pronk.png", "pronk.rrd"]  # no temporaries
    # The recording is this run: `legsim replay --json` gives the same summary.
    assert main(["replay", str(files["rrd"]), "--json"]) == 0
    replayed = json.loads(capsys.readouterr().out)
    assert {k: v for k, v in replayed.items() if k != "outputs"} == {k: v for k, v in summary.items() if k != "outputs"}
    data = read_rrd(files["rrd"])
    # The symmetric pronk (paper 000 Fig. 17 left): theta stays 0 in every recorded sample.
    assert np.abs(data["series"]["theta"][1]).max() < 1e-9
    assert data["frames"] is not None and set(data["frames"].parts) >= {"body"}
    # The page embeds meshcat's viewer and no network resource; the png is a full figure.
    page = files["html"].read_text()
    assert "<script" in page and "http://" not in page.replace("http://www.w3.org", "")
    assert imread(files["plot"]).shape[0] > 400


@pytest.mark.parametrize("scene, moving", [("double_pendulum_zeno", ()), ("pronk", (0,)), ("slip", (0,))])
def test_gravity_effect_off_leaves_free_inertial_motion(capsys, scene, moving):
    # Gravity is an effect a scene switches. Without it the robots start at
    # rest (pendulum) or flying level at xd0 = 3.4 m/s (runners): the closed form is
    # x(t) = x0 + xd0 t with every other coordinate constant, no contact is ever reached and
    # the energy is the initial kinetic energy (0, or m xd0^2 / 2 = 5.78 J for m = 1).
    t_final = 1.0
    code, summary, _ = run_json(
        capsys, scene, "--set", "effects.gravity=false", "--set", f"integrator.t_final={t_final}"
    )
    start = load_scene(scene).initial_state
    expected = start.copy()
    for i in moving:
        expected[i] += 3.4 * t_final
    assert code == 0 and summary["transitions"] == 0
    np.testing.assert_allclose(summary["final_state"], expected, rtol=0, atol=1e-12)
    kinetic = 0.0 if not moving else 0.5 * 3.4**2
    assert summary["energy_initial"] == pytest.approx(kinetic, abs=1e-12)
    assert summary["energy_final"] == pytest.approx(kinetic, abs=1e-12)
