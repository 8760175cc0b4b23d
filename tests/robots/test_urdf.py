"""Robots from URDF files (robots/urdf.py): the parsed quadruped against the same robot built by
hand with Pinocchio's API, its fields against crba and the nonlinear effects, its outlines against
closed forms, scene-declared contacts and stops, and bad files and tables named in errors."""

import math

import numpy as np
import pinocchio as pin
import pytest
from legsim.robots import urdf
from legsim.robots.bridge import planar_floating_base

from legsim.errors import ModelError, SceneError
from legsim.scene import load_scene

QUADRUPED = urdf.bundled("quadruped.urdf")
CONTACTS = [
    {"name": "hind", "frame": "hind_foot", "friction": 0.8},
    {"name": "front", "frame": "front_foot", "friction": 0.8},
]


def hand_built_quadruped() -> pin.Model:
    """The bundled quadruped from its numbers (scenarios/quadruped.urdf), with Pinocchio's API:
    body 5 kg (pitch inertia 0.45 kg m^2), thighs 0.4 kg and shanks 0.15 kg of 0.25 m, hips at x = -+0.3 m.
    Joints in the parser's order (front before hind: Pinocchio visits a link's children by name)."""
    model = pin.Model()
    body = planar_floating_base(model, names=("x", "z", "pitch"))
    model.appendBodyToJoint(body, pin.Inertia(5.0, np.zeros(3), np.diag([0.02, 0.45, 0.45])), pin.SE3.Identity())
    for side, x in (("front", 0.3), ("hind", -0.3)):
        hip = model.addJoint(body, pin.JointModelRY(), pin.SE3(np.eye(3), np.array([x, 0, 0])), f"{side}_hip")
        model.appendBodyToJoint(
            hip, pin.Inertia(0.4, np.array([0, 0, -0.125]), np.diag([0.0021, 0.0021, 0.0001])), pin.SE3.Identity()
        )
        knee = model.addJoint(hip, pin.JointModelRY(), pin.SE3(np.eye(3), np.array([0, 0, -0.25])), f"{side}_knee")
        model.appendBodyToJoint(
            knee, pin.Inertia(0.15, np.array([0, 0, -0.125]), np.diag([0.0008, 0.0008, 0.00002])), pin.SE3.Identity()
        )
    return model


def test_the_parsed_quadruped_has_the_hand_built_mass_matrix_and_gravity():
    parsed, names = urdf.load_model(QUADRUPED)
    assert names == ("x", "z", "pitch", "front_hip", "front_knee", "hind_hip", "hind_knee")
    assert parsed.nq == parsed.nv == 7
    reference = hand_built_quadruped()
    pd, rd = parsed.createData(), reference.createData()
    rng = np.random.default_rng(3)
    for _ in range(20):
        q = rng.uniform(-1.5, 1.5, 7)
        np.testing.assert_allclose(pin.crba(parsed, pd, q), pin.crba(reference, rd, q), atol=1e-14)
        g = np.array([0, 0, -9.81, 0, 0, 0])
        reference.gravity = pin.Motion(g)
        np.testing.assert_allclose(
            pin.computeGeneralizedGravity(parsed, pd, q), pin.computeGeneralizedGravity(reference, rd, q), atol=1e-12
        )


def test_the_urdf_robots_field_is_the_mass_matrix_solve_of_the_parsed_model():
    model = urdf.make({"file": str(QUADRUPED), "actuated": ["all"], "contacts": CONTACTS})
    bridge = model.info["bridge"]
    parsed, _ = urdf.load_model(QUADRUPED)
    data = parsed.createData()
    rng = np.random.default_rng(5)
    for _ in range(10):
        x = rng.uniform(-1, 1, 14)
        u = rng.normal(size=4)
        tau = np.concatenate([np.zeros(3), u[[0, 1]], u[[2, 3]]])  # actuated in the order front, hind
        M = pin.crba(parsed, data, x[:7])
        expected = np.linalg.solve(M, tau - pin.nonLinearEffects(parsed, data, x[:7], x[7:]))
        np.testing.assert_allclose(bridge.field("flight")(0.0, x, u)[7:], expected, atol=1e-10)


def test_the_outlines_follow_the_body_and_legs():
    model = urdf.make({"file": str(QUADRUPED), "contacts": CONTACTS})
    q = np.array([1.0, 0.6, 0.3, 0.0, 0.0, 0.4, -0.7])
    parts = model.geometry("flight", np.concatenate([q, np.zeros(7)]))
    assert set(parts) == {"body", "front_thigh", "front_shank", "front_foot", "hind_thigh", "hind_shank", "hind_foot"}
    c, s = math.cos(0.3), math.sin(0.3)
    # the 0.8 x 0.1 m torso pitched by 0.3 rad about +y (nose down) around (1.0, 0.6)
    corners = [(1.0 + c * dx + s * dz, 0.6 - s * dx + c * dz) for dx in (-0.4, 0.4) for dz in (-0.05, 0.05)]
    np.testing.assert_allclose(sorted(map(tuple, parts["body"][:-1])), sorted(corners), atol=1e-12)
    np.testing.assert_allclose(parts["body"][0], parts["body"][-1])  # closed
    # the hind foot's disc is centred on the foot frame
    foot = model.info["bridge"].frame_positions(q, ["hind_foot"])["hind_foot"]
    np.testing.assert_allclose(parts["hind_foot"][:-1].mean(axis=0), foot, atol=1e-12)
    assert np.allclose(np.linalg.norm(parts["hind_foot"][:-1] - foot, axis=1), 0.02)


def test_the_scene_declares_contacts_and_stops_with_a_file_relative_to_it():
    scene = load_scene("quadruped_stand")
    bridge = scene.model.info["bridge"]
    assert [c.name for c in bridge.contacts] == ["hind", "front", "hind_knee_stop", "front_knee_stop"]
    assert bridge.contacts[0].friction == 0.8 and bridge.contacts[3].side == "upper"
    ex = scene.simulate()
    assert ex.status == "finished" and [tr.name for tr in ex.transitions] == ["joint_hind+front"]
    u = scene.controller.input_at(ex.final_mode, ex.t_end, ex.final_state)
    forces = bridge.constraint_forces(ex.final_mode, ex.final_state, u)
    total = pin.computeTotalMass(bridge.model) * 9.81
    assert forces["hind"][1] + forces["front"][1] == pytest.approx(total, rel=1e-6)  # standing still
    assert abs(ex.final_state[2]) < 1e-12  # symmetric legs: no pitch


def test_bad_urdfs_and_tables_are_named(tmp_path):
    continuous = tmp_path / "wheel.urdf"
    continuous.write_text(
        QUADRUPED.read_text().replace('name="hind_knee" type="revolute"', 'name="hind_knee" type="continuous"')
    )
    with pytest.raises(ModelError, match=r"joint 'hind_knee'.*nq = 2, nv = 1"):
        urdf.load_model(continuous)
    tilted = tmp_path / "tilted.urdf"
    tilted.write_text(
        QUADRUPED.read_text().replace(
            '<axis xyz="0 1 0"/>\n    <limit lower="0.0"', '<axis xyz="1 0 0"/>\n    <limit lower="0.0"'
        )
    )
    with pytest.raises(ModelError, match=r"joint 'hind_knee'.*does not move in the \(x, z\) plane"):
        urdf.load_model(tilted)
    with pytest.raises(ModelError, match=r"missing\.urdf: no such URDF file"):
        urdf.load_model(tmp_path / "missing.urdf")
    with pytest.raises(SceneError, match=r"contacts\[1\]: unknown key\(s\) \['mu'\]"):
        urdf.make({"file": str(QUADRUPED), "contacts": [CONTACTS[0], {"name": "f", "frame": "front_foot", "mu": 1.0}]})
    with pytest.raises(SceneError, match=r"actuated: joint\(s\) \['hind_hip'\] listed more than once"):
        urdf.make({"file": str(QUADRUPED), "actuated": ["hind_hip", "hind_knee", "hind_hip"]})
    # An index or an unknown name reached Pinocchio's getJointId: an ArgumentError over five
    # lines, or an IndexError naming nothing (found by the controller parameters' fuzzer).
    for actuated, message in (
        ([0], r"actuated: expected joint names \(strings\) or \['all'\], got \[0\]; joints: \['front_hip'"),
        (["nope"], r"actuated: unknown joint\(s\) \['nope'\]; joints: \['front_hip'"),
        (["root"], r"actuated: unknown joint\(s\) \['root'\]"),
    ):
        with pytest.raises(SceneError, match=message):
            urdf.make({"file": str(QUADRUPED), "actuated": actuated})
    # Contacts and stops name modes alike: a name twice is an error naming both tables.
    twice = [CONTACTS[0], {"name": CONTACTS[0]["name"], "frame": "front_foot"}]
    with pytest.raises(
        SceneError, match=r"contacts\[1\].name: duplicate contact name .* \(also robot.parameters.contacts\[0\]"
    ):
        urdf.make({"file": str(QUADRUPED), "contacts": twice})
    stop = {"name": CONTACTS[0]["name"], "joint": "hind_knee", "position": 0.1}
    with pytest.raises(
        SceneError, match=r"stops\[0\].name: duplicate contact name .* \(also robot.parameters.contacts\[0\]"
    ):
        urdf.make({"file": str(QUADRUPED), "contacts": CONTACTS[:1], "stops": [stop]})
    with pytest.raises(SceneError, match=r"stops\[0\].position: expected a float"):
        urdf.make({"file": str(QUADRUPED), "stops": [{"name": "s", "joint": "hind_knee", "position": "high"}]})
    # Values out of range are named by their field's path, not only by the bridge's contact name.
    with pytest.raises(SceneError, match=r"stops\[0\].side: expected 'lower' or 'upper', got 'lowr'"):
        urdf.make({"file": str(QUADRUPED), "stops": [{"name": "s", "joint": "hind_knee", "side": "lowr"}]})
    with pytest.raises(SceneError, match=r"contacts\[0\].restitution: expected a number in \[0, 1\], got 2"):
        urdf.make({"file": str(QUADRUPED), "contacts": [{**CONTACTS[0], "restitution": 2}]})
    scene = tmp_path / "robot.toml"
    text = urdf.bundled("quadruped_stand.toml").read_text().replace('file = "quadruped.urdf"', 'file = "nowhere.urdf"')
    scene.write_text(text)
    with pytest.raises(SceneError, match=r"robot.parameters.file: no such file 'nowhere.urdf'"):
        load_scene(str(scene))
