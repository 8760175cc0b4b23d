"""Scene loading: validation of every field before anything runs, overrides, name lookup."""

from __future__ import annotations

import math

import numpy as np
import pytest

from helpers.scenes import TINY_SCENE, register_tiny, write_scene
from legsim import ModelError, SceneError, simulate
from legsim.scene import apply_overrides, load_scene, parse_override, scene_files


@pytest.fixture(autouse=True)
def tiny(monkeypatch):
    register_tiny(monkeypatch)


def test_valid_scene_fields(tmp_path):
    path = write_scene(tmp_path, TINY_SCENE + '\n[output]\nrrd = "out/a.rrd"\n\n[orbit]\nperiod = 1.0\n')
    scene = load_scene(path)
    assert scene.path == path and scene.name == "tiny" and scene.description == "a tiny ball"
    assert scene.robot == "tinyball"
    assert scene.initial_mode == "flight"
    # z from the file, zd from the model's defaults.
    np.testing.assert_array_equal(scene.initial_state, [1.0, 0.0])
    assert scene.state_names == ("z", "zd")
    assert scene.integrator["h"] == 1e-3 and scene.integrator["eps"] == 1e-3
    assert scene.integrator["t_final"] == 1.0 and scene.integrator["method"] == "rk4"
    assert scene.integrator["max_transitions"] == 100_000 and scene.integrator["rtol"] is None
    assert scene.output == {"rrd": "out/a.rrd", "html": None, "plot": None}
    assert scene.sections == {"orbit": {"period": 1.0}}
    assert scene.parameters == {"g": 9.81}
    assert scene.effects == {"floor": {"restitution": 0.5}}
    assert [tr.name for tr in scene.model.system.transitions] == ["bounce"]


def test_simulate_equals_direct_simulate_and_hits_closed_form_impact(tmp_path):
    scene = load_scene(write_scene(tmp_path))
    ex = scene.simulate()
    direct = simulate(scene.model.system, [1.0, 0.0], "flight", 1.0, 1e-3, 1e-3, "rk4")
    np.testing.assert_array_equal(ex.final_state, direct.final_state)
    assert ex.mode_sequence == direct.mode_sequence
    # Free fall is cubic in t, so RK4 + Hermite crossing give the impact time to rounding.
    assert abs(ex.transitions[0].time - math.sqrt(2 * 1.0 / 9.81)) < 1e-12


def test_scene_with_dense_landing_lands_on_the_closed_form_impact(tmp_path):
    text = TINY_SCENE.replace('method = "rk4"', 'method = "dopri5"').replace(
        "t_final = 1.0", 't_final = 1.0\nlanding = "dense"\nrtol = 1e-8\natol = 1e-8'
    )
    scene = load_scene(write_scene(tmp_path, text))
    assert scene.integrator["landing"] == "dense"
    ex = scene.simulate()
    assert ex.status == "finished" and ex.transitions
    # dopri5 and its quartic interpolant are exact on the parabola of free fall.
    assert abs(ex.transitions[0].time - math.sqrt(2 * 1.0 / 9.81)) < 1e-12
    assert 0.0 <= ex.transitions[0].depth <= 1e-3


# -- effects switched on and off, visible in the evaluation counts ----------------------------
def test_effect_off_builds_no_guard_and_evaluates_none(tmp_path):
    scene = load_scene(write_scene(tmp_path), overrides=["effects.floor=false"])
    assert scene.model.system.transitions == ()
    ex = scene.simulate()
    assert ex.counters["guard_evals"] == 0 and ex.counters["reset_evals"] == 0
    assert ex.transitions == [] and ex.mode_sequence == ["flight"]
    # Without the floor it is free fall: z(1) = 1 - g/2.
    assert abs(ex.final_state[0] - (1.0 - 9.81 / 2)) < 1e-12


def test_model_counter_counts_only_when_the_effect_is_on(tmp_path):
    path = write_scene(tmp_path)
    off = load_scene(path).simulate()
    assert off.counters["drag_evals"] == 0
    on = load_scene(path, overrides=["effects.drag=true"]).simulate()
    # The drag term runs at every field evaluation; the integrator also evaluates the field a
    # couple of times per mode to check it (uncounted in field_evals), hence the small slack.
    assert on.counters["field_evals"] <= on.counters["drag_evals"] <= on.counters["field_evals"] + 4
    assert on.counters["field_evals"] > 1000


# -- bad scene files: one test per class, asserting the message --------------------------------
def _replace(old: str, new: str) -> str:
    assert old in TINY_SCENE
    return TINY_SCENE.replace(old, new)


BAD = {
    "unknown section": (
        TINY_SCENE + "\n[camera]\nzoom = 2\n",
        ["unknown section(s) ['camera']", "allowed:", "'integrator'", "'orbit'"],
    ),
    "tool section not a table": (
        TINY_SCENE.replace("[scene]", "orbit = 3\n[scene]"),
        ["orbit: expected a table, got integer 3"],
    ),
    "core section not a table": (
        TINY_SCENE.replace("[scene]", 'output = "x.rrd"\n[scene]'),
        ["output: expected a table, got string 'x.rrd'"],
    ),
    "unknown scene key": (
        _replace('description = "a tiny ball"', 'descr = "x"'),
        ["scene: unknown key(s) ['descr']; allowed: ['description']"],
    ),
    "description not a string": (
        _replace('description = "a tiny ball"', "description = 3"),
        ["scene.description: expected a string, got integer 3"],
    ),
    "unknown robot": (
        _replace('name = "tinyball"', 'name = "tinybal"'),
        ["robot.name: unknown robot 'tinybal'; available: [", "'tinyball'"],
    ),
    "robot name missing": (_replace('name = "tinyball"', ""), ["robot.name: missing; available robots:"]),
    "robot name not a string": (
        _replace('name = "tinyball"', "name = 1"),
        ["robot.name: expected a string, got integer 1"],
    ),
    "unknown robot key": (
        _replace('name = "tinyball"', 'name = "tinyball"\nmass = 1'),
        ["robot: unknown key(s) ['mass']; allowed: ['name', 'parameters']"],
    ),
    "unknown parameter": (
        _replace('name = "tinyball"', 'name = "tinyball"\nparameters = { gravity = 9.8 }'),
        ["robot.parameters: unknown parameter(s) ['gravity']; allowed: ['g']"],
    ),
    "parameter wrong type": (
        _replace('name = "tinyball"', 'name = "tinyball"\nparameters = { g = "earth" }'),
        ["robot.parameters.g: expected a number (float in (0, inf) m/s^2), got 'earth'"],
    ),
    "parameter boolean": (
        _replace('name = "tinyball"', 'name = "tinyball"\nparameters = { g = true }'),
        ["robot.parameters.g: expected a number"],
    ),
    "parameter out of range": (
        _replace('name = "tinyball"', 'name = "tinyball"\nparameters = { g = -1 }'),
        ["robot.parameters.g: -1.0 is out of range, allowed: float in (0, inf) m/s^2"],
    ),
    "unknown effect": (
        _replace("floor = { restitution = 0.5 }", "wind = true"),
        ["effects: unknown effect(s) ['wind']; allowed: ['drag', 'floor']"],
    ),
    "effect neither bool nor table": (
        _replace("floor = { restitution = 0.5 }", "floor = 1"),
        ["effects.floor: expected true, false or a table of parameters, got 1"],
    ),
    "unknown effect parameter": (
        _replace("restitution = 0.5", "bounce = 0.5"),
        ["effects.floor: unknown parameter(s) ['bounce']; allowed: ['restitution']"],
    ),
    "restitution above 1": (
        _replace("restitution = 0.5", "restitution = 1.5"),
        ["effects.floor.restitution: 1.5 is out of range, allowed: float in [0, 1]"],
    ),
    "restitution below 0": (
        _replace("restitution = 0.5", "restitution = -0.1"),
        ["effects.floor.restitution: -0.1 is out of range, allowed: float in [0, 1]"],
    ),
    "unknown initial mode": (
        _replace("state = { z = 1.0 }", 'mode = "stance"'),
        ["initial.mode: unknown mode 'stance'; modes: ['flight']"],
    ),
    "initial mode not a string": (
        _replace("state = { z = 1.0 }", "mode = 2"),
        ["initial.mode: expected a mode name (string), got integer 2"],
    ),
    "unknown coordinate": (
        _replace("state = { z = 1.0 }", "state = { z = 1.0, y = 2.0 }"),
        ["initial.state: unknown coordinate(s) ['y'] of mode 'flight'; coordinates: ['z', 'zd']"],
    ),
    "coordinate wrong type": (
        _replace("state = { z = 1.0 }", 'state = { z = "high" }'),
        ["initial.state.z: expected a number, got string 'high'"],
    ),
    "coordinate not finite": (
        _replace("state = { z = 1.0 }", "state = { z = nan }"),
        ["initial.state.z: must be finite, got nan"],
    ),
    "state not a table": (
        _replace("state = { z = 1.0 }", "state = [1.0, 0.0]"),
        ["initial.state: expected a table of coordinate = number, got array"],
    ),
    "unknown initial key": (
        _replace("state = { z = 1.0 }", "state = { z = 1.0 }\nt = 0"),
        ["initial: unknown key(s) ['t']; allowed: ['mode', 'state']"],
    ),
    "initial state past the guard": (
        _replace("state = { z = 1.0 }", "state = { z = -0.5, zd = -1.0 }"),
        ["initial.state:", "lies past the guard of transition bounce by 0.5 > eps = 0.001"],
    ),
    "h zero": (_replace("h = 1e-3", "h = 0"), ["integrator.h: 0.0 is out of range, allowed: float in (0, inf) s"]),
    "h negative": (
        _replace("h = 1e-3", "h = -1e-3"),
        ["integrator.h: -0.001 is out of range, allowed: float in (0, inf) s"],
    ),
    "h not finite": (_replace("h = 1e-3", "h = inf"), ["integrator.h: must be finite, got inf"]),
    "h wrong type": (
        _replace("h = 1e-3", 'h = "small"'),
        ["integrator.h: expected a number (float in (0, inf) s), got 'small'"],
    ),
    "eps zero": (
        _replace("eps = 1e-3", "eps = 0.0"),
        ["integrator.eps: 0.0 is out of range, allowed: float in (0, inf) guard units"],
    ),
    "t_final zero": (
        _replace("t_final = 1.0", "t_final = 0"),
        ["integrator.t_final: 0.0 is out of range, allowed: float in (0, inf) s"],
    ),
    "t_final before t0": (
        _replace("t_final = 1.0", "t_final = 1.0\nt0 = 2.0"),
        ["integrator.t_final: 1.0 must be > integrator.t0 = 2.0"],
    ),
    "t_final missing": (
        _replace("t_final = 1.0", ""),
        ["integrator.t_final: missing; a scene must give ['t_final', 'h', 'eps']"],
    ),
    "unknown method": (
        _replace('method = "rk4"', 'method = "rk5"'),
        ["integrator.method: 'rk5' is not allowed, choose one of [", "'dopri5'", "'rk4'"],
    ),
    "max_transitions negative": (
        _replace("t_final = 1.0", "t_final = 1.0\nmax_transitions = -1"),
        ["integrator.max_transitions: -1 is out of range, allowed: int in [0, inf)"],
    ),
    "max_transitions not an integer": (
        _replace("t_final = 1.0", "t_final = 1.0\nmax_transitions = 1e5"),
        ["integrator.max_transitions: expected an integer (int in [0, inf)), got 100000.0"],
    ),
    "more steps than max_steps": (
        _replace("t_final = 1.0", "t_final = 1e12"),
        [
            "integrator.max_steps: t_final - t0 = 1e+12 s at h = 0.001 s is 1e+15 steps, "
            "more than max_steps = 10000000",
            "raise integrator.max_steps",
        ],
    ),
    "h below the time resolution": (
        _replace("t_final = 1.0", "t0 = 1e15\nt_final = 1.000000000000002e15"),
        [
            "integrator.h: 0.001 s is too small for times near 1e+15 s, where float64 times "
            "are 0.125 s apart; h must be >= 1.31e+05 s"
        ],
    ),
    "max_steps zero": (
        _replace("t_final = 1.0", "t_final = 1.0\nmax_steps = 0"),
        ["integrator.max_steps: 0 is out of range, allowed: int in [1, inf)"],
    ),
    "unknown integrator key": (
        _replace("t_final = 1.0", "t_final = 1.0\ndt = 1e-3"),
        ["integrator: unknown parameter(s) ['dt']; allowed: ["],
    ),
    "eps below float64's resolution": (
        _replace("eps = 1e-3", "eps = 1e-300"),
        ["integrator.eps: 1e-300 is thinner than float64 resolves next to the initial state", "give eps >= "],
    ),
    "a state too large to resolve a strip next to": (
        _replace("state = { z = 1.0 }", "state = { z = 1e308 }"),
        ["initial.state.z: 1e+308 is so large that float64 values next to it are 2e+292 apart"],
    ),
    "a fixed step longer than the run": (
        _replace("h = 1e-3", "h = 10.0"),
        ["integrator.h: 10 s is longer than the run (t_final - t0 = 1 s): with fixed steps it would be one step"],
    ),
    "rtol without an embedded method": (
        _replace("t_final = 1.0", "t_final = 1.0\nrtol = 1e-6"),
        ["integrator.rtol: error control needs a method with an embedded error estimate", "method = 'rk4'"],
    ),
    "dense landing without a continuous extension": (
        _replace("t_final = 1.0", 't_final = 1.0\nlanding = "dense"'),
        [
            "integrator.landing: 'dense' lands on the method's continuous extension, which method = 'rk4' has not",
            "landing = 'aim'",
        ],
    ),
    "unknown output": (
        TINY_SCENE + '\n[output]\ngif = "a.gif"\n',
        ["output: unknown key(s) ['gif']; allowed: ['rrd', 'html', 'plot']"],
    ),
    "output not a path": (
        TINY_SCENE + "\n[output]\nrrd = 3\n",
        ["output.rrd: expected a file path (string), got integer 3"],
    ),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_scene_is_rejected_naming_file_field_and_allowed(tmp_path, case):
    text, fragments = BAD[case]
    path = write_scene(tmp_path, text)
    with pytest.raises(SceneError) as info:
        load_scene(path)
    message = str(info.value)
    assert message.startswith(f"{path}: "), message
    for fragment in fragments:
        assert fragment in message, f"{fragment!r} not in {message!r}"


def test_max_steps_bounds_the_nominal_step_count_and_can_be_raised(tmp_path):
    # (t_final - t0) / h = 2e7 nominal steps: refused by default (1e7), accepted when the scene
    # says it means it; nothing is simulated either way.
    path = write_scene(tmp_path, _replace("t_final = 1.0", "t_final = 1.0\nt0 = -1.0").replace("h = 1e-3", "h = 1e-7"))
    with pytest.raises(SceneError, match=r"integrator.max_steps: t_final - t0 = 2 s at h = 1e-07 s is 2e\+07 steps"):
        load_scene(path)
    assert load_scene(path, overrides=["integrator.max_steps=20000000"]).integrator["max_steps"] == 20_000_000


def test_model_initial_check_refuses_states_the_guards_admit(tmp_path, monkeypatch):
    # max(z, zd) >= 0 holds for a ball 5 m under the floor at rest; the model's own check
    # (Model.info["initial_check"]) names it, and a check that fails is a ModelError.
    import dataclasses

    import helpers.scenes as support

    def build(params, effects):
        model = support._build(params, effects)
        model.info["initial_check"] = lambda mode, x, eps: f"z below -eps = {-eps:g}" if x[0] < -eps else None
        return model

    monkeypatch.setattr(support, "BUILDER", dataclasses.replace(support.BUILDER, build=build))
    path = write_scene(tmp_path)
    assert load_scene(path, overrides=["initial.state.z=-5e-4"]).initial_state[0] == -5e-4  # inside the strip
    with pytest.raises(
        SceneError, match=rf"^{path}: initial.state: \{{'z': -5.0, 'zd': 0.0\}}: z below -eps = -0.001$"
    ):
        load_scene(path, overrides=["initial.state.z=-5"])

    def broken(params, effects):
        model = support._build(params, effects)
        model.info["initial_check"] = lambda mode, x, eps: 1 / 0
        return model

    monkeypatch.setattr(support, "BUILDER", dataclasses.replace(support.BUILDER, build=broken))
    with pytest.raises(
        ModelError,
        match=r"initial-state check of robot model 'tinyball' failed on \[1.0, 0.0\]: "
        r"ZeroDivisionError",
    ):
        load_scene(path)


def test_toml_syntax_error_names_file_and_line(tmp_path):
    path = write_scene(tmp_path, TINY_SCENE.replace("h = 1e-3", "h = = 1e-3"))
    line = TINY_SCENE.splitlines().index("h = 1e-3") + 1
    with pytest.raises(SceneError, match=rf"^{path}: TOML syntax error: .*at line {line}, column"):
        load_scene(path)


def test_duplicate_key_is_a_syntax_error(tmp_path):
    path = write_scene(tmp_path, TINY_SCENE + "h = 2e-3\n")
    with pytest.raises(SceneError, match=rf"^{path}: TOML syntax error: .*line"):
        load_scene(path)


def test_missing_file(tmp_path):
    path = tmp_path / "none.toml"
    with pytest.raises(SceneError, match=rf"^{path}: no such scene file$"):
        load_scene(path)


def test_directory_is_not_a_scene(tmp_path):
    with pytest.raises(SceneError, match="not a scene file"):
        load_scene(tmp_path)


def test_unknown_scene_name_lists_known_scenes(tmp_path, monkeypatch):
    monkeypatch.setenv("LEGSIM_SCENE_PATH", str(tmp_path))
    write_scene(tmp_path, name="mine")
    with pytest.raises(SceneError, match=r"unknown scene 'mien': .*known scenes: \[.*'mine'"):
        load_scene("mien")


def test_builder_failure_is_a_model_error_naming_file_and_robot(tmp_path, monkeypatch):
    import dataclasses

    import helpers.scenes as support

    def broken(params, effects):
        raise ZeroDivisionError("division by zero")

    monkeypatch.setattr(support, "BUILDER", dataclasses.replace(support.BUILDER, build=broken))
    path = write_scene(tmp_path)
    with pytest.raises(ModelError, match=rf"^{path}: robot 'tinyball' could not be built: ZeroDivisionError"):
        load_scene(path)


def test_builder_returning_something_else_is_rejected(tmp_path, monkeypatch):
    import dataclasses

    import helpers.scenes as support

    monkeypatch.setattr(support, "BUILDER", dataclasses.replace(support.BUILDER, build=lambda p, e: 42))
    with pytest.raises(ModelError, match=r"returned int, expected legsim\.builders\.Model"):
        load_scene(write_scene(tmp_path))


# -- overrides ---------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "text, key, value",
    [
        ("integrator.h=1e-4", ["integrator", "h"], 1e-4),
        ("integrator.max_transitions=10", ["integrator", "max_transitions"], 10),
        ("effects.drag=true", ["effects", "drag"], True),
        ("integrator.method=dopri5", ["integrator", "method"], "dopri5"),
        ('integrator.method="bs32"', ["integrator", "method"], "bs32"),
        ("effects.floor={ restitution = 0.8 }", ["effects", "floor"], {"restitution": 0.8}),
        ("a.b=[1, 2]", ["a", "b"], [1, 2]),
        ("scene.description=two words", ["scene", "description"], "two words"),
        (" initial.state.z = 2 ", ["initial", "state", "z"], 2),
    ],
)
def test_parse_override_reads_toml_literals_else_strings(text, key, value):
    parsed_key, parsed = parse_override(text)
    assert parsed_key == key and parsed == value and type(parsed) is type(value)


@pytest.mark.parametrize("text", ["integrator.h", "=1", "integrator..h=1", ".h=1"])
def test_malformed_override(text):
    with pytest.raises(SceneError, match=r"^--set .*(expected key.path=value|dotted path)"):
        parse_override(text)


def test_overrides_apply_before_validation(tmp_path):
    path = write_scene(tmp_path, _replace("floor = { restitution = 0.5 }", "floor = true"))
    scene = load_scene(
        path,
        overrides=[
            "integrator.h=1e-4",
            "effects.floor.restitution=0.8",
            "initial.state.zd=2",
            "integrator.method=dopri5",
        ],
    )
    assert scene.integrator["h"] == 1e-4 and scene.integrator["method"] == "dopri5"
    # An effect given as `true` becomes a table when one of its parameters is set.
    assert scene.effects["floor"] == {"restitution": 0.8}
    np.testing.assert_array_equal(scene.initial_state, [1.0, 2.0])
    assert scene.overrides == [
        "integrator.h=1e-4",
        "effects.floor.restitution=0.8",
        "initial.state.zd=2",
        "integrator.method=dopri5",
    ]
    # The reset uses the overridden restitution: an impact at speed v leaves at 0.8 v.
    ex = scene.simulate()
    tr = ex.transitions[0]
    assert tr.state_after[1] == pytest.approx(-0.8 * tr.state_before[1], rel=1e-15)


def test_override_creating_an_unknown_key_is_rejected_by_validation(tmp_path):
    path = write_scene(tmp_path)
    with pytest.raises(SceneError, match=rf"^{path}: integrator: unknown parameter\(s\) \['dt'\]"):
        load_scene(path, overrides=["integrator.dt=1e-3"])
    with pytest.raises(SceneError, match=rf"^{path}: unknown section\(s\) \['integrater'\]"):
        load_scene(path, overrides=["integrater.h=1e-3"])


def test_override_with_a_bad_value(tmp_path):
    path = write_scene(tmp_path)
    with pytest.raises(SceneError, match=rf"^{path}: integrator.h: expected a number .*got 'abc'"):
        load_scene(path, overrides=["integrator.h=abc"])
    with pytest.raises(SceneError, match=rf"^{path}: effects.floor.restitution: 2.0 is out of range"):
        load_scene(path, overrides=["effects.floor.restitution=2.0"])


def test_override_into_a_switched_off_effect_or_a_value_is_refused(tmp_path):
    data = {"effects": {"floor": False}, "integrator": {"h": 1e-3}}
    with pytest.raises(SceneError, match=r"effects.floor is false \(switched off\)"):
        apply_overrides(data, ["effects.floor.restitution=0.8"])
    with pytest.raises(SceneError, match=r"integrator.h is 0.001, not a table"):
        apply_overrides(data, ["integrator.h.x=1"])


# -- finding scenes by name --------------------------------------------------------------------
def test_scene_path_env_is_searched_first(tmp_path, monkeypatch):
    first, second = tmp_path / "a", tmp_path / "b"
    first.mkdir(), second.mkdir()
    write_scene(first, TINY_SCENE.replace("a tiny ball", "from a"), name="ball_x")
    write_scene(second, TINY_SCENE.replace("a tiny ball", "from b"), name="ball_x")
    write_scene(second, name="only_b")
    monkeypatch.setenv("LEGSIM_SCENE_PATH", f"{first}{__import__('os').pathsep}{second}")
    assert load_scene("ball_x").description == "from a"
    assert load_scene("only_b").path == second / "only_b.toml"
    files = scene_files()
    assert files["ball_x"] == first / "ball_x.toml" and files["only_b"] == second / "only_b.toml"


def test_missing_toml_file_named_like_a_known_scene_gets_a_hint(tmp_path, monkeypatch):
    scenes, elsewhere = tmp_path / "scenes", tmp_path / "cwd"
    scenes.mkdir(), elsewhere.mkdir()
    write_scene(scenes, name="hinted")
    monkeypatch.setenv("LEGSIM_SCENE_PATH", str(scenes))
    monkeypatch.chdir(elsewhere)
    with pytest.raises(
        SceneError,
        match=rf"^hinted.toml: no such scene file \(the scene named 'hinted' is "
        rf"{scenes / 'hinted.toml'}: run it by name\)$",
    ):
        load_scene("hinted.toml")


def test_scipys_method_names_mean_error_control_in_a_scene_as_in_simulate(tmp_path):
    """``method = "RK45"`` (scipy's spelling) runs error-controlled steps with solve_ivp's default
    tolerances, as ``simulate(method="RK45")`` does, where legsim's ``rk45`` (dopri5) steps by h;
    with error control h is the largest step, so it may exceed the run."""
    path = write_scene(tmp_path, TINY_SCENE.replace('method = "rk4"', 'method = "RK45"').replace("h = 1e-3", "h = 2.0"))
    ex = load_scene(path).simulate()
    assert (ex.settings["method"], ex.settings["rtol"], ex.settings["atol"]) == ("dopri5", 1e-3, 1e-6)
    fixed = load_scene(write_scene(tmp_path, TINY_SCENE.replace('method = "rk4"', 'method = "rk45"'), "fixed"))
    ex = fixed.simulate()
    assert (ex.settings["method"], ex.settings["rtol"]) == ("dopri5", None)
