"""`legsim orbit`: JSON and text reports against closed forms, continuation with located
stability changes and plots, exit codes and error messages."""

import json
import math

import numpy as np
import pytest

from legsim.cli import main

# Closed forms of the bundled rimless wheel (see robots/rimless_wheel.py): m = 1, I = 0, l = 1,
# 10 spokes, g = 9.81: c = cos(2 alpha), K = 4 g sin(alpha) sin(slope), w*^2 = c^2 K / (1 - c^2).
ALPHA = math.pi / 10
C = math.cos(2 * ALPHA)


def omega_star(slope_deg):
    K = 4 * 9.81 * math.sin(ALPHA) * math.sin(math.radians(slope_deg))
    return math.sqrt(C * C * K / (1 - C * C))


def run_cli(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_orbit_json_has_the_documented_keys_and_the_closed_form_orbit(capsys):
    code, out, err = run_cli(capsys, "orbit", "rimless_wheel", "--json")
    assert code == 0 and err == ""
    data = json.loads(out)
    assert {"fixed_point", "state_names", "period", "multipliers", "residual", "iterations", "step_length"} <= set(data)
    assert data["state_names"] == ["theta", "thetad", "foot_x"]
    assert abs(data["fixed_point"][0] + ALPHA) < 1e-12
    assert abs(data["fixed_point"][1] - omega_star(5.0)) < 1e-9
    assert data["multipliers"] == [[pytest.approx(C * C, abs=1e-8), 0.0]]
    assert abs(data["step_length"] - 2 * math.sin(ALPHA)) < 1e-12
    assert data["residual"] <= 1e-10 and data["iterations"] >= 1 and data["status"] == "converged"


def test_orbit_text_report(capsys):
    code, out, err = run_cli(capsys, "orbit", "compass_gait")
    assert code == 0 and err == ""
    assert out.startswith("compass_gait: periodic orbit found in ")
    assert "section: after heel_strike (mode stance)" in out
    assert "stable: spectral radius 0.5799" in out  # |mu| of the complex pair, as in the walker tests
    assert "step length 0.53544" in out


def test_orbit_runs_with_the_scenes_tolerances_and_reaches_the_reference_gait(capsys):
    # The independent computation (helpers.compass_gait_reference: scipy DOP853 at 1e-12, no
    # legsim): with fixed 0.1 s steps of dopri5 the gait would be 2e-5 off; with the scene's
    # rtol the steps are error-controlled and the fixed point is within 1e-9.
    from helpers.compass_gait_reference import STANDARD, PointMassCompassGait

    code, out, err = run_cli(
        capsys,
        "orbit",
        "compass_gait",
        "--set",
        'integrator.method="dopri5"',
        "--set",
        "integrator.rtol=1e-10",
        "--set",
        "integrator.h=0.1",
        "--json",
    )
    assert code == 0, err
    data = json.loads(out)
    assert data["integrator"] == {
        "method": "dopri5",
        "h": 0.1,
        "eps": 1e-6,
        "rtol": 1e-10,
        "atol": pytest.approx(1e-13, rel=1e-15),
        "landing": "halve",
        "max_halvings": 64,
    }
    stance, hip, stanced, hipd, _ = data["fixed_point"]
    ref = PointMassCompassGait(**STANDARD).gait()
    leans = np.array([stance, stance + hip, stanced, stanced + hipd])
    assert np.max(np.abs(leans - ref["x"])) < 1e-9
    assert abs(data["period"] - ref["period"]) < 1e-9


def test_orbit_report_names_the_integrator_settings(capsys):
    code, out, err = run_cli(
        capsys,
        "orbit",
        "rimless_wheel",
        "--set",
        'integrator.method="bs32"',
        "--set",
        "integrator.atol=1e-9",
        "--set",
        'integrator.landing="aim"',
    )
    assert code == 0, err
    assert out.splitlines()[1] == (
        "integrator: bs32, rtol = 1e-12, atol = 1e-09, largest step h = 0.002 s, eps = 1e-06, landing 'aim'"
    )
    code, out, err = run_cli(capsys, "orbit", "rimless_wheel", "--continue", "slope", "4", "5", "--steps", "1")
    assert code == 0, err
    assert out.splitlines()[1] == "integrator: rk4, h = 0.002 s, eps = 1e-06, landing 'halve'"


def test_continuation_follows_the_closed_form_family_and_plots_it(capsys, tmp_path):
    plot = tmp_path / "family.png"
    code, out, err = run_cli(
        capsys, "orbit", "rimless_wheel", "--continue", "slope", "3", "7", "--steps", "4", "--plot", str(plot), "--json"
    )
    assert code == 0, err
    data = json.loads(out)
    assert data["complete"] and data["parameter"] == "slope"
    assert data["integrator"] == {
        "method": "rk4",
        "h": 2e-3,
        "eps": 1e-6,
        "rtol": None,
        "atol": None,
        "landing": "halve",
        "max_halvings": 64,
    }
    values = [p["value"] for p in data["points"]]
    assert values == pytest.approx([3.0, 4.0, 5.0, 6.0, 7.0], abs=1e-12)
    for p in data["points"]:
        assert abs(p["fixed_point"][1] - omega_star(p["value"])) < 1e-9
        # The step-to-step contraction c^2 does not depend on the slope.
        assert abs(p["multipliers"][0][0] - C * C) < 1e-8
    assert data["stability_changes"] == []
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert [f.name for f in tmp_path.iterdir()] == ["family.png"]  # no partial file left


def test_continuation_locates_the_compass_gait_period_doubling(capsys):
    code, out, err = run_cli(
        capsys, "orbit", "compass_gait", "--continue", "slope", "4.25", "4.5", "--steps", "1", "--locate", "6", "--json"
    )
    assert code == 0, err
    data = json.loads(out)
    (change,) = data["stability_changes"]
    assert change["becomes"] == "unstable" and change["kind"].startswith("period doubling")
    lo, hi = change["between"]
    assert hi - lo <= 0.25 / 2**6 + 1e-12 and lo <= change["at"] <= hi
    # At the located slope the leading multiplier is real and at -1 (to the bracket's width).
    re, im = change["multiplier"]
    assert im == 0.0 and abs(re + 1.0) < 0.02
    # The independent point-mass computation (scipy DOP853, no Pinocchio, no legsim) has its
    # multiplier cross -1 inside the same bracket.
    from helpers.compass_gait_reference import STANDARD, PointMassCompassGait

    def leading(slope):
        mu = PointMassCompassGait(**dict(STANDARD, slope=slope)).gait(guess=(-0.3, 1.14, 0.22))["multipliers"]
        return float(np.min(mu.real))

    assert leading(lo) > -1.0 > leading(hi)


def test_continuation_text_table_and_change_report(capsys):
    code, out, err = run_cli(capsys, "orbit", "rimless_wheel", "--continue", "slope", "4", "6", "--steps", "2")
    assert code == 0, err
    lines = out.splitlines()
    assert lines[0] == "rimless_wheel: family of orbits over slope from 4 to 6 (2 steps)"
    # The unknowns (theta and thetad; foot_x is cyclic), then the orbit's figures.
    assert lines[2].split() == ["slope", "theta", "thetad", "period", "step", "max|mu|", "stable"]
    rows = [line.split() for line in lines[3:6]]
    assert [float(r[0]) for r in rows] == [4.0, 5.0, 6.0]
    for r in rows:
        assert abs(float(r[1]) + ALPHA) < 1e-5
        assert abs(float(r[2]) - omega_star(float(r[0]))) < 1e-5 and r[-1] == "yes"
    assert "stability change: none in this range" in out
    assert "complete: 3 orbit(s) from slope = 4 to 6" in out


def test_no_orbit_exits_3_with_the_reason(capsys):
    code, out, err = run_cli(capsys, "orbit", "rimless_wheel", "--set", "orbit.t_max=0.1", "--json")
    assert code == 3
    data = json.loads(out)
    assert data["status"] == "no_return" and data["multipliers"] is None
    assert "legsim: no orbit (no_return): " in err and "within t_max = 0.1 s" in err


@pytest.mark.parametrize(
    "argv, message",
    [
        (["orbit", "slip"], "the scene has no [orbit] section"),
        # the example names one of the scene's own transitions
        (["orbit", "pronk"], '[orbit] section = { after = "liftoff_left" } (its transitions: liftoff_left,'),
        (["orbit", "rimless_wheel", "--plot", "x.png"], "--plot draws a family: use it with --continue"),
        (["orbit", "rimless_wheel", "--steps", "3"], "--steps sets the family's parameter steps: use it with"),
        (["orbit", "rimless_wheel", "--locate", "3"], "--locate narrows the family's stability changes: use it with"),
        (
            ["orbit", "rimless_wheel", "--set", 'orbit.cyclic=["foot_x","theta"]', "--json"],
            "rimless_wheel.toml: orbit.cyclic: orbit problem: cyclic = ['foot_x', 'theta'] leaves none",
        ),
        (
            ["orbit", "rimless_wheel", "--set", "orbit.min_transitions=3"],
            "rimless_wheel.toml: orbit.min_transitions: counts crossings of a level section",
        ),
        (["orbit", "rimless_wheel", "--set", "orbit.nonsense=1"], "orbit.nonsense: unknown key(s) ['nonsense']"),
        (["orbit", "rimless_wheel", "--continue", "spokes", "8", "10"], "parameter 'spokes' is int-valued"),
        (["orbit", "rimless_wheel", "--continue", "mass", "1", "2"], "robot 'rimless_wheel' has no parameter 'mass'"),
        (["orbit", "rimless_wheel", "--continue", "slope", "a", "2"], "--continue FROM: expected a number, got 'a'"),
        (
            ["orbit", "slip_raibert", "--continue", "controller.parameters.speed", "1", "2"],
            "'controller.parameters.speed' is a controller's parameter; only the robot's parameters",
        ),
        (
            ["orbit", "rimless_wheel", "--continue", "robot.slope", "3", "4"],
            "unknown effect 'robot' in 'robot.slope': a parameter is the robot's (NAME: ",
        ),
        (
            ["orbit", "rimless_wheel", "--set", 'orbit.section={ after = "landing" }'],
            "no transition of that name in rimless_wheel; transitions: ['back_impact', 'impact']",
        ),
        (["orbit", "rimless_wheel", "--set", 'orbit.fixed=["phi"]'], "fixed coordinate(s) ['phi'] are not coordinates"),
        (
            ["orbit", "slip_orbit", "--continue", "damping.b", "0", "1"],
            "effect 'damping' is switched off in this scene",
        ),
        (
            ["orbit", "rimless_wheel", "--continue", "slope", "3", "4", "--plot", "out.txt"],
            "the file must end in .png, .pdf or .svg",
        ),
        # Checked before any orbit is searched for: found only after the family was computed, each
        # would waste the whole computation (or run for days).
        (
            ["orbit", "rimless_wheel", "--continue", "slope", "3", "4", "--plot", "/proc/no/such/folder/f.png"],
            "cannot create the folder /proc/no/such/folder",
        ),
        (
            ["orbit", "rimless_wheel", "--continue", "slope", "3", "4", "--plot", "/proc/f.png"],
            "cannot write in the folder /proc",
        ),  # even as root, whose permission bits say yes
        (
            ["orbit", "rimless_wheel", "--continue", "slope", "5", "1e300"],
            "--continue TO = 1e+300: orbit problem: no system for parameters",
        ),
        (
            ["orbit", "rimless_wheel", "--continue", "slope", "3", "4", "--steps", "1000000000"],
            "--steps must be in [1, 10000]",
        ),
        (["orbit", "rimless_wheel", "--continue", "slope", "3", "4", "--locate", "-1"], "--locate must be in [0, 50]"),
        (
            ["orbit", "rimless_wheel", "--continue", "nonsense", "3", "4"],
            "continued parameter: robot 'rimless_wheel' has no",
        ),
        (["orbit", "slip_orbit", "--continue", "psi", "0.6", "0.65"], "--continue psi: 'psi' is a free parameter"),
        # Absurd [orbit] values, named by their key.
        (
            ["orbit", "rimless_wheel", "--set", "orbit.fd_step=0", "--set", 'orbit.jacobian="fd"'],
            "orbit.fd_step: must be a relative step in (0, 0.1]",
        ),
        (["orbit", "rimless_wheel", "--set", "orbit.fd_step=10"], "orbit.fd_step: must be a relative step in (0, 0.1]"),
        (
            ["orbit", "rimless_wheel", "--set", "orbit.trivial_multipliers=1"],
            "orbit.trivial_multipliers: orbit problem: trivial_multipliers = 1 must be",
        ),
        (
            ["orbit", "rimless_wheel", "--set", 'orbit.cyclic=["nope"]'],
            "orbit.cyclic: orbit problem: cyclic coordinate(s)",
        ),
        (["orbit", "rimless_wheel", "--set", 'orbit.free=["slope"]'], "orbit.free: orbit problem: 3 unknowns"),
        # Tolerances need an embedded pair: refused by the setting's name, not run at fixed steps.
        (
            ["orbit", "compass_gait", "--set", "integrator.rtol=1e-10"],
            "integrator.rtol: error control needs a method with an embedded error estimate",
        ),
        (
            ["orbit", "compass_gait", "--set", 'integrator.landing="dense"'],
            "integrator.landing: 'dense' lands on the method's continuous extension",
        ),
        # The search's own integrator settings ([orbit.integrator]), checked as [integrator]'s and
        # named by their own path.
        (
            ["orbit", "compass_gait", "--set", "orbit.integrator.rtol=1e-10"],
            "orbit.integrator.rtol: error control needs a method with an embedded error estimate",
        ),
        (["orbit", "compass_gait", "--set", 'orbit.integrator.method="rk9"'], "orbit.integrator.method"),
        (
            ["orbit", "compass_gait", "--set", "orbit.integrator.t_final=3"],
            "orbit.integrator.t_final: not an integrator setting of the search; allowed: ['method', 'h', 'eps'",
        ),
        (["orbit", "compass_gait", "--set", "orbit.integrator=3"], "orbit.integrator: expected a table of"),
        (
            ["orbit", "rimless_wheel", "--set", "integrator.h=1e-9", "--set", "integrator.max_steps=100000000000"],
            "orbit.t_max: orbit problem: t_max / h = 3 s / 1e-09 s = 3e+09 steps per return, more than the limit",
        ),
    ],
)
def test_bad_requests_exit_2_with_a_message(capsys, argv, message):
    code, out, err = run_cli(capsys, *argv)
    assert code == 2, (out, err)
    assert message in err and err.startswith("legsim: error: ")
    assert out == ""  # refused before any table header or result


def test_a_failed_verdict_after_convergence_says_what_is_singular(capsys, monkeypatch):
    """A search that converges above what the map resolves and then finds no multipliers ends
    ``singular_jacobian``: its message keeps saying so rather than only how it converged. (The
    section coordinate as cyclic, refused by the problem now, is let through to reach it.)"""
    from legsim.orbits.problem import OrbitProblem

    monkeypatch.setattr(OrbitProblem, "_check_name_lists", lambda self: None, raising=False)
    argv = ["orbit", "slip_orbit", "--set", 'orbit.cyclic=["x","zd"]', "--set", "orbit.trivial_multipliers=0"]
    code, out, err = run_cli(capsys, *argv, "--json")
    data = json.loads(out)
    assert code == 3 and data["status"] == "singular_jacobian" and "no orbit (singular_jacobian)" in err
    assert "the Jacobian restricted to the section is singular" in data["message"]
    assert "zero off the cyclic coordinates" in data["message"]


def test_an_integrator_override_the_orbit_section_shadows_is_said(capsys):
    """``--set integrator.h`` changes the scene's runs; where the scene's ``[orbit.integrator]``
    sets h for the search, the search keeps its own, and the command says so, naming the key to
    set instead. A key the section does not set (t_final) and other fields say nothing."""
    from legsim.commands.orbit import _say_shadowed
    from legsim.scene import load_scene
    from legsim.scene.orbit import shadowed_integrator_keys

    overrides = ["integrator.h=1e-3", "integrator.t_final=2", "controller.parameters.speed=0.5"]
    scene = load_scene("quadruped_run", overrides)
    assert shadowed_integrator_keys(scene, overrides) == {"h": 2e-3}
    assert shadowed_integrator_keys(load_scene("compass_gait", ["integrator.h=1e-3"]), ["integrator.h=1e-3"]) == {}
    _say_shadowed(shadowed_integrator_keys(scene, overrides))
    err = capsys.readouterr().err
    assert err == (
        "legsim: note: --set integrator.h sets the scene's runs, not this search: its [orbit.integrator] "
        "gives h = 0.002; use --set orbit.integrator.h=... to change it\n"
    )
