"""Falls as a status (a scene's [fall] section) and links without a contact passing below the
ground, on a monoped written in the test's folder (a 10 kg box trunk on a prismatic leg, landing
pitched on its point foot and tipping over) and on the bundled quadruped dropped pitched. Every
time is checked against a root found independently on the run without the condition (its
samples, the trunk's corners in closed form)."""

import math
import subprocess
import sys

import numpy as np
import pytest
from scipy.optimize import brentq

from legsim.errors import SceneError
from legsim.scene import load_scene
from legsim.sweep.tasks import run_columns
from tests.helpers.urdf_robots import TRUNK_HALF_X, TRUNK_HALF_Z, monoped


def first_crossing(ex, fn):
    """The first time fn(state) < 0 along ex, root-found (brentq) on ex.sample between the stored
    points around it."""
    for seg in ex.segments:
        values = np.array([fn(x) for x in seg.x])
        below = np.flatnonzero(values < 0)
        if below.size:
            k = int(below[0])
            assert k > 0, "the crossing falls at a visit's start"
            return brentq(lambda t: fn(ex.sample([t]).states[0]), seg.t[k - 1], seg.t[k], xtol=1e-14, rtol=1e-15)
    raise AssertionError("never crossed")


def trunk_lowest(x):
    """The lowest corner (m) of the trunk box at state x (z, pitch: a rotation about +y)."""
    z, pitch = x[1], x[2]
    return z - TRUNK_HALF_X * abs(math.sin(pitch)) - TRUNK_HALF_Z * abs(math.cos(pitch))


@pytest.fixture(scope="module")
def free(tmp_path_factory):
    """The tipping monoped without any [fall] condition, and its scene's folder."""
    folder = tmp_path_factory.mktemp("monoped")
    ex = load_scene(monoped(folder)).simulate()
    return folder, ex


@pytest.mark.parametrize(
    ("section", "name", "condition"),
    [
        ("pitch_max = 1.0", "pitch_max", lambda x: 1.0 - abs(x[2])),
        ("height_min = 0.3", "height_min", lambda x: x[1] - 0.3),
    ],
)
def test_a_tipping_monoped_falls_where_its_condition_first_holds(free, tmp_path, section, name, condition):
    _, ex_free = free
    ex = load_scene(monoped(tmp_path, f"[fall]\n{section}\n")).simulate()
    expected = first_crossing(ex_free, condition)
    assert ex.status == "fell"
    assert name in ex.message and f"t={ex.t_end:.17g}" in ex.message
    assert ex.t_end == pytest.approx(expected, abs=1e-9)
    assert condition(ex.final_state) == pytest.approx(0.0, abs=1e-9)
    # the run up to the fall is the free run's
    assert np.allclose(ex.final_state, ex_free.sample([ex.t_end]).states[0], atol=1e-9)
    assert ex.counters["python_steps"] == 0 and ex.settings["path"] == "compiled"
    # it stopped soon after (the driver scans every 256 steps), not at t_final
    assert ex.counters["steps"] < ex_free.counters["steps"]
    assert all(tr.exit_time <= ex.t_end for tr in ex.transitions)


def test_a_monoped_landing_upright_stands_and_does_not_fall(tmp_path):
    path = monoped(tmp_path, "[fall]\npitch_max = 1.0\nheight_min = 0.3\n")
    ex = load_scene(path, ["initial.state.pitch=0.0"]).simulate()
    assert ex.status == "finished" and ex.message == ""
    assert ex.t_end == 1.5
    pitch = np.concatenate([seg.x[:, 2] for seg in ex.segments])
    z = np.concatenate([seg.x[:, 1] for seg in ex.segments])
    assert np.max(np.abs(pitch)) < 1e-9 and np.min(z) > 0.3
    assert not ex.warnings


def test_a_contact_touching_the_ground_is_a_fall_at_its_touchdown(tmp_path):
    nose = '[{ name = "foot", frame = "foot", friction = 1.0 }, { name = "nose", frame = "nose", friction = 1.0 }]'
    overrides = [f"robot.parameters.contacts={nose}"]
    ex_free = load_scene(monoped(tmp_path), overrides).simulate()
    touchdowns = [tr for tr in ex_free.transitions if "nose" in tr.target]
    assert touchdowns, "the nose lands in the free run"
    ex = load_scene(monoped(tmp_path, '[fall]\ncontacts = ["nose"]\n'), overrides).simulate()
    assert ex.status == "fell" and "'nose' touched the ground" in ex.message
    assert ex.t_end == touchdowns[0].exit_time
    assert "nose" in ex.final_mode and ex.transitions[-1].exit_time == ex.t_end


def test_a_trunk_through_the_ground_is_reported_with_its_time_and_depth(free):
    _, ex = free
    assert ex.status == "finished"
    (warning,) = [w for w in ex.warnings if w.kind == "below_ground"]
    assert warning.time == pytest.approx(first_crossing(ex, trunk_lowest), abs=1e-9)
    assert "'trunk'" in warning.message and "'leg'" not in warning.message  # the leg has the foot's contact
    deepest = min(trunk_lowest(x) for seg in ex.segments for x in seg.x)
    assert deepest < -0.1  # it went far through
    assert warning.details["least_value"] == pytest.approx(deepest, abs=1e-12)
    assert f"{-deepest:.3g} m deep" in warning.message


def test_with_strict_a_trunk_through_the_ground_ends_the_run_as_a_model_breakdown(free, tmp_path):
    _, ex_free = free
    ex = load_scene(monoped(tmp_path), ["robot.parameters.below_ground='strict'"]).simulate()
    assert ex.status == "model_breakdown"
    assert ex.t_end == pytest.approx(first_crossing(ex_free, trunk_lowest), abs=1e-9)
    assert trunk_lowest(ex.final_state) == pytest.approx(0.0, abs=1e-9)
    assert "'trunk'" in ex.message and "below the ground" in ex.message
    assert ex.counters["python_steps"] == 0


def test_a_sweep_row_says_fell_from_the_status(tmp_path):
    scene = load_scene(monoped(tmp_path, "[fall]\npitch_max = 1.0\n"))
    row = run_columns(scene, scene.simulate())
    assert row["status"] == "fell" and row["fell"] is True
    upright_scene = load_scene(scene.path, ["initial.state.pitch=0.0"])
    upright = run_columns(upright_scene, upright_scene.simulate())
    assert upright["status"] == "finished" and upright["fell"] is False


def test_legsim_run_exits_with_3_and_names_the_fall(tmp_path):
    path = monoped(tmp_path, "[fall]\npitch_max = 1.0\n")
    done = subprocess.run(
        [sys.executable, "-m", "legsim", "run", str(path), "--json"], capture_output=True, text=True, timeout=600
    )
    assert done.returncode == 3, done.stderr
    assert '"status": "fell"' in done.stdout
    assert "run stopped early (fell): fell: pitch_max" in done.stderr


@pytest.mark.parametrize(
    ("section", "match"),
    [
        ("pitch_max = 1.0\nroll_max = 1.0", r"fall: unknown key\(s\) \['roll_max'\]; allowed: \['pitch_max'"),
        ("pitch_max = -1.0", r"fall.pitch_max: -1.0 is out of range, allowed: float in \(0, inf\)"),
        ("pitch_max = true", r"fall.pitch_max: expected a finite number, got boolean True"),
        ('pitch_max = 1.0\npitch = "roll"', r"fall.pitch: string 'roll' is not a coordinate of mode 'flight'; "
                                            r"coordinates: \['x', 'z', 'pitch'"),
        ('height = "z"', r"fall.height: given without fall.height_min"),
        ('contacts = ["tail"]', r"fall.contacts: unknown contact\(s\) \['tail'\]; contacts: \['foot'\]"),
        ("contacts = []", r"fall.contacts: expected a non-empty list of contact names, got an empty array"),
    ],
)  # fmt: skip
def test_the_fall_section_is_checked_before_anything_runs(tmp_path, section, match):
    path = monoped(tmp_path, f"[fall]\n{section}\n")
    with pytest.raises(SceneError, match=rf"monoped.toml: {match}"):
        load_scene(path)


def test_fall_contacts_need_a_robot_that_names_its_contacts():
    with pytest.raises(SceneError, match=r"fall.contacts: robot 'bouncing ball' names no contacts"):
        load_scene("bouncing_ball", ['fall.contacts=["floor"]'])


TUMBLE = ["integrator.t_final=1.5", "initial.state.pitch=0.6", "initial.state.z=0.7"]


def test_the_bundled_quadruped_dropped_pitched_tumbles_and_falls_at_its_pitch_bound():
    free = load_scene("quadruped_stand", TUMBLE).simulate()
    assert free.status == "finished"  # without [fall] it tumbles on, its body through the ground
    (warning,) = [w for w in free.warnings if w.kind == "below_ground"]
    assert "'body'" in warning.message
    ex = load_scene("quadruped_stand", [*TUMBLE, "fall.pitch_max=1.2"]).simulate()
    assert ex.status == "fell" and "pitch_max" in ex.message
    assert ex.t_end == pytest.approx(first_crossing(free, lambda x: 1.2 - abs(x[2])), abs=1e-9)
    assert abs(ex.final_state[2]) == pytest.approx(1.2, abs=1e-9)
    assert ex.counters["python_steps"] == 0


def test_the_bundled_quadruped_standing_does_not_fall():
    ex = load_scene("quadruped_stand", ["fall.pitch_max=0.3", "fall.height_min=0.3"]).simulate()
    assert ex.status == "finished" and ex.t_end == 2.0
    assert not [w for w in ex.warnings if w.kind == "below_ground"]


def test_on_a_terrain_the_height_bound_is_above_the_ground_under_x(tmp_path):
    # On a slope rising at grade 0.2 the monoped tips towards +x, up the slope: its height above
    # the ground (z - 0.2 x) reaches 0.3 m before its z does.
    grade = 0.2
    terrain = f'[terrain]\nkind = "slope"\ngrade = {grade}\n'
    free = load_scene(monoped(tmp_path, terrain)).simulate()
    ex = load_scene(monoped(tmp_path, terrain + "[fall]\nheight_min = 0.3\n")).simulate()
    assert ex.status == "fell" and "z above the ground" in ex.message
    expected = first_crossing(free, lambda x: x[1] - grade * x[0] - 0.3)
    assert expected < first_crossing(free, lambda x: x[1] - 0.3)
    assert ex.t_end == pytest.approx(expected, abs=1e-9)
    x = ex.final_state
    assert x[1] - grade * x[0] == pytest.approx(0.3, abs=1e-9)


def test_a_bundled_runner_that_collapses_level_falls_at_its_height_bound():
    # Legs too soft to carry the bound: the body comes down level onto folded legs, its pitch
    # never near the 1 rad bound; this ran to t_final and `finished`.
    ex = load_scene("quadruped_bound_one_flight", ["controller.parameters.stiffness=100", "integrator.t_final=2"])
    ex = ex.simulate()
    assert ex.status == "fell" and "height_min" in ex.message
    assert ex.final_state[1] == pytest.approx(0.25, abs=1e-9)
    assert abs(ex.final_state[2]) < 0.5
