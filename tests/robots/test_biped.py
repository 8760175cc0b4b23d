"""Raibert's planar biped (``raibert_biped``, robots/biped.py and robots/biped_laws.py) on the
bundled biped (scenarios/biped.urdf, scene ``biped_run``) and on a second biped of other
dimensions written here: one leg at a time, the mean forward speed after 5 s within 5% of the
command (the issue's measure), the trunk's pitch bounded, every step in the compiled kernel.

CI runs each speed for 8 s (the mean over 5 to 8 s); LEGSIM_FULL=1 (or -m slow) runs the
scene's 20 s and the second biped at 2.0 m/s."""

from __future__ import annotations

import math

import numpy as np
import pytest
from legsim.robots import biped

from legsim.control import available, get_controller
from legsim.errors import SceneError
from legsim.relaxed import simulate
from legsim.scene import bundled_dir, load_scene

SCENE = "biped_run"
#: The issue's bound on the mean speed's error after 5 s (relative), and the pitch (rad) a run
#: may not pass: the bundled biped's stays within 0.04 to 0.19 rad at 0.5 to 2.5 m/s (its start
#: included); the second biped's reaches -0.29 rad at its first touchdowns.
SPEED_BOUND = 0.05
PITCH_BOUND = 0.4
SETTLED = 5.0


def samples(ex, column: int) -> tuple[np.ndarray, np.ndarray]:
    """The run's stored times (s) and one state column, over every segment."""
    return np.concatenate([seg.t for seg in ex.segments]), np.concatenate([seg.x[:, column] for seg in ex.segments])


def mean_speed_after(ex, t0: float) -> float:
    """The mean forward speed (m/s) from t0 to the run's end: distance over time."""
    t, x = samples(ex, 0)
    return float((x[-1] - np.interp(t0, t, x)) / (t[-1] - t0))


def stances(scene, ex) -> list[str]:
    """The foot of each stance (a run of stance modes between flights), in order; AssertionError
    if a stance mode has both feet on the ground."""
    bridge = scene.model.info["bridge"]
    feet, last = [], "flight"
    for seg in ex.segments:
        if seg.mode != "flight":
            active = bridge.active_contacts(seg.mode)
            assert len(active) == 1, f"both feet down at t = {seg.t[0]} ({seg.mode})"
            if last == "flight":
                feet.append(active[0])
        last = seg.mode
    return feet


def check_runs_at(scene, speed: float) -> None:
    """The run finished without a warning, all compiled, one leg at a time in turn, at the
    commanded speed after 5 s with the pitch bounded."""
    ex = scene.simulate()
    assert ex.status == "finished" and not ex.warnings
    assert ex.counters["python_steps"] == 0
    feet = stances(scene, ex)
    first, second = feet[0], next(f for f in feet if f != feet[0])
    assert feet == [first if k % 2 == 0 else second for k in range(len(feet))]  # alternate
    achieved = mean_speed_after(ex, SETTLED)
    assert abs(achieved - speed) < SPEED_BOUND * speed, achieved
    _, pitch = samples(ex, 2)
    assert np.max(np.abs(pitch)) < PITCH_BOUND


def test_the_biped_controller_is_an_entry_point():
    assert "raibert_biped" in available()
    assert get_controller("raibert_biped") is biped.BIPED


def test_the_legs_are_the_scenes_in_its_order():
    """The controller's legs are the contacts the scene declares, in their order (the first
    lands first), with the URDF's segment lengths and knee sense."""
    law = load_scene(SCENE, ["integrator.t_final=0.1"]).control
    assert [leg.contact for leg in law.legs] == ["left", "right"]
    assert all((leg.thigh, leg.shank, leg.bend) == (0.25, 0.25, 1.0) for leg in law.legs)
    assert law.memory_names[:3] == ("next", "stance_left", "stance_right")


def test_a_biped_needs_two_legs(tmp_path):
    (tmp_path / "biped.urdf").write_text((bundled_dir() / "biped.urdf").read_text())
    text = (bundled_dir() / f"{SCENE}.toml").read_text()
    one_leg = text.replace('    { name = "right", frame = "right_foot", restitution = 0.0, friction = 1.0 },\n', "")
    assert one_leg != text
    (tmp_path / "one.toml").write_text(one_leg)
    with pytest.raises(SceneError, match=r"'raibert_biped' needs two articulated legs.*found 1: left"):
        load_scene(tmp_path / "one.toml")


def test_a_run_from_a_state_with_its_memory_continues_the_run():
    """The memory is all the state the controller carries from step to step: a run started at
    an apex of a run, at its time, with the state and memory there, reaches the run's next apex
    (measured: to rounding, its steps fall on the run's); with a fresh controller's memory (the
    first leg to land next, T_s 0.12 s, thrust 0.02 m, no apex time) the wrong leg lands."""
    scene = load_scene(SCENE, ["integrator.t_final=2.5"])
    s = scene.integrator
    ex = scene.simulate()
    apexes = []
    for seg in ex.segments[1:]:
        if seg.mode == "flight":
            k = int(np.argmax(seg.x[:, 1]))
            if 0 < k < len(seg.t) - 1:
                apexes.append((seg.t[k], seg.x[k]))
    (t1, x1), (t2, x2) = apexes[2:4]
    law = scene.control
    m = len(law.memory_names)
    assert x1[-m] == 1.0  # the right leg lands next there: the fresh memory says the left one
    resumed = simulate(scene.model.system, x1, "flight", t2, s["h"], s["eps"], s["method"], law, t0=t1)
    fresh_state = np.concatenate([x1[:-m], law.initial_memory])
    fresh = simulate(scene.model.system, fresh_state, "flight", t2, s["h"], s["eps"], s["method"], law, t0=t1)
    config = slice(0, 7)  # positions
    error = np.max(np.abs(resumed.final_state[config] - x2[config]))
    assert resumed.status == "finished" and error < s["eps"]
    assert np.max(np.abs(fresh.final_state[config] - x2[config])) > 100 * error


@pytest.mark.parametrize("speed", [1.0, 2.0])
def test_the_biped_runs_at_the_commanded_speed(speed):
    scene = load_scene(SCENE, ["integrator.t_final=8", f"controller.parameters.speed={speed}"])
    check_runs_at(scene, speed)


@pytest.mark.slow
@pytest.mark.parametrize("speed", [1.0, 2.0])
def test_the_biped_runs_at_the_commanded_speed_for_twenty_seconds(speed):
    scene = load_scene(SCENE, [f"controller.parameters.speed={speed}"])
    assert scene.integrator["t_final"] == 20.0
    check_runs_at(scene, speed)


# -- a second biped: other lengths and masses, knees bending the other way, other names --------
THIGH, SHANK = 0.30, 0.28


def other_leg(side: str) -> str:
    """A leg of the second biped: thigh 0.30 m (0.7 kg), shank 0.28 m (0.25 kg), the knee
    bending backwards (negative angles), the foot frame ``<side>_sole``."""
    return f"""
  <joint name="{side}_hip_joint" type="revolute"><parent link="torso"/><child link="{side}_upper"/>
    <origin xyz="0 0 0"/><axis xyz="0 1 0"/><limit lower="-1.6" upper="1.6" effort="150" velocity="30"/></joint>
  <link name="{side}_upper"><inertial><origin xyz="0 0 {-THIGH / 2}"/><mass value="0.7"/>
    <inertia ixx="0.005" ixy="0" ixz="0" iyy="0.00525" iyz="0" izz="0.0003"/></inertial></link>
  <joint name="{side}_knee_joint" type="revolute"><parent link="{side}_upper"/><child link="{side}_lower"/>
    <origin xyz="0 0 {-THIGH}"/><axis xyz="0 1 0"/><limit lower="-2.8" upper="0.0" effort="150" velocity="30"/></joint>
  <link name="{side}_lower"><inertial><origin xyz="0 0 {-SHANK / 2}"/><mass value="0.25"/>
    <inertia ixx="0.002" ixy="0" ixz="0" iyy="0.0016" iyz="0" izz="0.0005"/></inertial></link>
  <joint name="{side}_sole_joint" type="fixed"><parent link="{side}_lower"/><child link="{side}_sole"/>
    <origin xyz="0 0 {-SHANK}"/></joint>
  <link name="{side}_sole"/>
"""


OTHER_URDF = f"""<?xml version="1.0"?>
<robot name="other_biped">
  <link name="torso"><inertial><origin xyz="0 0 0"/><mass value="9.0"/>
    <inertia ixx="0.3" ixy="0" ixz="0" iyy="0.35" iyz="0" izz="0.05"/></inertial></link>
{other_leg("b")}{other_leg("a")}
</robot>
"""

OTHER_SCENE = """
[scene]
description = "a second biped: a 9 kg torso, legs of 0.30 + 0.28 m bending backwards"

[robot]
name = "urdf"
[robot.parameters]
file = "other.urdf"
root = "planar"
actuated = ["a_hip_joint", "a_knee_joint", "b_hip_joint", "b_knee_joint"]
contacts = [{ name = "a", frame = "a_sole", friction = 1.0 }, { name = "b", frame = "b_sole", friction = 1.0 }]
stops = [
    { name = "a_stop", joint = "a_knee_joint", position = -0.15, side = "upper" },
    { name = "b_stop", joint = "b_knee_joint", position = -0.15, side = "upper" },
]

[controller]
name = "raibert_biped"
[controller.parameters]
speed = 1.0
leg_length = 0.5
height = 0.6
stiffness = 8000.0
swing_stiffness = 5000.0
swing_damping = 80.0

[initial]
mode = "flight"
[initial.state]  # leg a at 0.5 m, 0.15 rad ahead; leg b retracted to 0.3 m, 0.15 rad behind
z = 0.6
xd = 1.0
a_hip_joint = 0.3615
a_knee_joint = -1.0636
b_hip_joint = 1.1210
b_knee_joint = -2.0563

[integrator]
method = "rk4"
h = 1e-3
eps = 5e-5
t_final = 10.0
"""


def other_biped(folder, *overrides: str):
    (folder / "other.urdf").write_text(OTHER_URDF)
    (folder / "other.toml").write_text(OTHER_SCENE)
    return load_scene(folder / "other.toml", list(overrides))


def test_the_second_bipeds_legs_are_read_from_its_scene(tmp_path):
    law = other_biped(tmp_path).control
    assert [leg.contact for leg in law.legs] == ["a", "b"]
    for leg in law.legs:
        assert math.isclose(leg.thigh, THIGH) and math.isclose(leg.shank, SHANK) and leg.bend == -1.0


def test_the_controller_runs_a_second_biped(tmp_path):
    check_runs_at(other_biped(tmp_path), 1.0)


@pytest.mark.slow
def test_the_controller_runs_a_second_biped_at_two_metres_per_second(tmp_path):
    check_runs_at(other_biped(tmp_path, "controller.parameters.speed=2.0"), 2.0)
