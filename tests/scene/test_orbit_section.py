"""The ``[orbit]`` section reader (legsim.scene.orbit): what it builds from a bundled scene, and
errors that name the file and the ``orbit.KEY`` at fault."""

import subprocess
import sys

import numpy as np
import pytest

import legsim.orbits
from legsim.errors import SceneError
from legsim.scene import load_scene
from legsim.scene.orbit import OrbitSettings, problem_from_scene


def test_the_rimless_wheel_section_becomes_a_problem_with_solver_settings_and_guess():
    scene = load_scene("rimless_wheel")
    settings = problem_from_scene(scene)
    assert isinstance(settings, OrbitSettings) and settings.scene is scene
    problem = settings.problem
    assert problem.section.label == "after impact" and problem.bound.mode == scene.initial_mode
    assert problem.cyclic == ("foot_x",) and problem.t_max == 3.0
    assert (problem.h, problem.eps) == (scene.integrator["h"], scene.integrator["eps"])
    assert settings.solver == {
        "tol": 1e-10,
        "max_iterations": 30,
        "jacobian": "saltation",
        "fd_step": None,
        "singular_tol": 1e-9,
    }
    assert np.array_equal(settings.guess, scene.initial_state)


def test_the_scenes_integrator_settings_reach_the_problem():
    scene = load_scene(
        "compass_gait",
        overrides=[
            'integrator.method="dopri5"',
            "integrator.rtol=1e-10",
            "integrator.atol=1e-12",
            "integrator.h=0.1",
            'integrator.landing="dense"',
            "integrator.max_halvings=20",
            "integrator.eps=1e-7",
        ],
    )
    problem = problem_from_scene(scene).problem
    assert problem.tableau.name == "dopri5"
    assert (problem.rtol, problem.atol, problem.h, problem.eps) == (1e-10, 1e-12, 0.1, 1e-7)
    assert (problem.landing, problem.max_halvings) == ("dense", 20)
    assert problem.integrator_settings == {
        "method": "dopri5",
        "h": 0.1,
        "eps": 1e-7,
        "rtol": 1e-10,
        "atol": 1e-12,
        "landing": "dense",
        "max_halvings": 20,
    }
    # Without tolerances the steps are fixed, as in `legsim run`.
    plain = problem_from_scene(load_scene("compass_gait")).problem
    assert (plain.rtol, plain.atol, plain.landing) == (None, None, "halve")


def test_an_integrator_setting_the_problem_refuses_is_named_as_an_integrator_field(monkeypatch):
    # The scene loader refuses rtol without an embedded pair itself; a setting that only the
    # orbit problem refuses is still named as the [integrator] field it came from.
    scene = load_scene("compass_gait")
    monkeypatch.setitem(scene.integrator, "rtol", 1e-8)
    with pytest.raises(SceneError) as info:
        problem_from_scene(scene)
    assert "compass_gait.toml: integrator.rtol: orbit problem: rtol/atol need a method with an embedded" in str(
        info.value
    ) and "got 'rk4'" in str(info.value)


def test_the_orbit_package_does_not_reach_up_to_the_scene_layer():
    assert not hasattr(legsim.orbits, "problem_from_scene") and not hasattr(legsim.orbits, "ORBIT_KEYS")


def test_the_algorithms_do_not_load_the_scene_layer():
    code = "import sys, legsim.orbits, legsim.certify, legsim.stochastic; print('legsim.scene' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"


@pytest.mark.parametrize(
    "override, message",
    [
        ('orbit.tol="small"', "orbit.tol: expected a number, got string 'small'"),
        ("orbit.max_iterations=2.5", "orbit.max_iterations: expected an integer, got float 2.5"),
        ('orbit.cyclic="foot_x"', "orbit.cyclic: expected a list of names, got string 'foot_x'"),
        ("orbit.guess={ nope = 1.0 }", "orbit.guess: unknown coordinate 'nope'"),
        ('orbit.section={ coordinate = "theta", value = "a" }', "orbit.section.value: expected a number"),
        ("orbit.section=3", "orbit.section: expected a table, got integer 3"),
        ('orbit.jacobian="exact"', "orbit.jacobian: expected 'saltation' or 'fd', got string 'exact'"),
    ],
)
def test_bad_values_are_named_by_their_key(override, message):
    scene = load_scene("rimless_wheel", overrides=[override])
    with pytest.raises(SceneError, match=r"rimless_wheel\.toml: ") as info:
        problem_from_scene(scene)
    assert message in str(info.value)


@pytest.mark.parametrize(
    "name, overrides, message",
    [
        # A verdict needs a multiplier: the wheel's section (theta, thetad, foot_x) has 3 - 1 - c.
        (
            "rimless_wheel",
            ['orbit.cyclic=["foot_x", "theta"]'],
            "orbit.cyclic: orbit problem: cyclic = ['foot_x', 'theta'] leaves none of the section's multipliers",
        ),
        ("slip_orbit", ['orbit.free=["psi", "psi"]'], "orbit.free: orbit problem: free lists ['psi'] more than once"),
        # The section's own coordinate is named as such, whatever trivial_multipliers says.
        ("slip_orbit", ['orbit.cyclic=["x", "zd"]'], "orbit.cyclic: orbit problem: 'zd' is the section's coordinate"),
        (
            "slip_orbit",
            ['orbit.cyclic=["x", "zd"]', "orbit.trivial_multipliers=0"],
            "orbit.cyclic: orbit problem: 'zd' is the section's coordinate",
        ),
        ("rimless_wheel", ['orbit.fixed=["foot_x"]'], "orbit.fixed: orbit problem: ['foot_x'] are both fixed and"),
        (
            "rimless_wheel",
            ['orbit.cyclic=["foot_x", "foot_x"]'],
            "orbit.cyclic: orbit problem: cyclic lists ['foot_x'] more than once",
        ),
        ("rimless_wheel", ["orbit.singular_tol=2"], "orbit.singular_tol: must be a ratio of singular values in (0, 1)"),
        ("rimless_wheel", ["orbit.singular_tol=0"], "orbit.singular_tol: must be a ratio of singular values in (0, 1)"),
        # Counts of crossings mean nothing after a transition: refused, not ignored.
        ("rimless_wheel", ["orbit.min_transitions=3"], "orbit.min_transitions: counts crossings of a level section"),
        ("rimless_wheel", ["orbit.min_time=100"], "orbit.min_time: counts crossings of a level section"),
    ],
)
def test_malformed_lists_and_settings_are_refused_by_their_key(name, overrides, message):
    scene = load_scene(name, overrides=overrides)
    with pytest.raises(SceneError, match=rf"{name}\.toml: ") as info:
        problem_from_scene(scene)
    assert message in str(info.value)


def test_a_level_section_takes_its_crossing_counts():
    problem = problem_from_scene(load_scene("slip_orbit", overrides=["orbit.min_transitions=2"])).problem
    assert problem.section.kind == "crossing" and problem.min_transitions == 2


def test_a_controller_that_does_not_declare_its_memory_is_refused(tmp_path, monkeypatch):
    # A controller keeping state the search cannot restore would make the return map depend on
    # where an earlier return left it: refused, naming the field and what to implement. (A
    # ControlLaw always declares its memory: a Python Controller stands in for the scene's.)
    from legsim.robots import raibert

    from legsim.control import Controller, ControllerSpec

    class Undeclared(Controller):
        def __call__(self, mode, t, x):
            return np.zeros(1)

    spec = ControllerSpec("raibert_slip", "", raibert.SLIP.parameters, lambda model, params: Undeclared())
    monkeypatch.setattr("legsim.scene.controller.get_controller", lambda name: spec)
    expected = r"slip_raibert\.toml: controller: orbit problem: controller Undeclared does not declare its memory"
    with pytest.raises(SceneError, match=expected) as info:
        problem_from_scene(load_scene("slip_raibert"))
    assert "memory_names, memory_units, memory() and restore(mode, memory)" in str(info.value)


def test_a_scene_with_a_controller_searches_its_memory_too():
    settings = problem_from_scene(load_scene("slip_raibert", overrides=["orbit.guess={ T_s = 0.2 }"]))
    problem = settings.problem
    assert problem.memory_names == ("T_s", "t_touchdown", "stance") and problem.memory_units == ("s", "s", "")
    assert problem.unknown_names == ["z", "psi", "xd", "T_s", "t_touchdown", "stance"]
    assert settings.solver["memory"].tolist() == [0.2, 0.0, 0.0]


def test_an_unknown_guess_name_lists_the_controller_memory():
    scene = load_scene("slip_raibert", overrides=["orbit.guess={ T_x = 0.2 }"])
    with pytest.raises(
        SceneError,
        match=r"orbit\.guess: unknown coordinate 'T_x'.*controller memory: \['T_s', 't_touchdown', 'stance'\]",
    ):
        problem_from_scene(scene)


@pytest.mark.parametrize(
    "section, message",
    [
        (
            '{ after = "touchdown_left" }',
            "orbit.section.mode: section after 'touchdown_left': "
            "transitions of that name lead to several modes ['both', 'left']; name the target mode",
        ),
        (
            '{ after = "touchdown_left", mode = "right" }',
            "orbit.section.mode: section after touchdown_left into right: "
            "no transition 'touchdown_left' leads to mode 'right'; it leads to ['both', 'left']",
        ),
        ('{ after = "touchdown_left", mode = 3 }', "orbit.section.mode: expected a mode name, got integer 3"),
        ('{ after = "touchdown_left", value = 3 }', "orbit.section: 'after' takes only 'mode' besides"),
    ],
)
def test_a_section_after_a_transition_into_several_modes_names_its_target(section, message):
    scene = load_scene("pronk_orbit", overrides=[f"orbit.section={section}"])
    with pytest.raises(SceneError, match=r"pronk_orbit\.toml: ") as info:
        problem_from_scene(scene)
    assert message in str(info.value)


def test_a_section_after_a_transition_takes_its_target_mode():
    scene = load_scene(
        "pronk_orbit",
        overrides=[
            'orbit.section={ after = "touchdown_left", mode = "both" }',
            'initial.mode="both"',
            "initial.state={ z = 1.0, left_foot_x = -0.5, right_foot_x = 0.5 }",
        ],
    )
    problem = problem_from_scene(scene).problem
    assert problem.bound.mode == "both" and problem.section.label == "after touchdown_left into both"
