"""Contacts from a URDF's <collision> shapes (robots/collisions.py), on robots written in the
test's folder (none bundled): a ball rolling out of a slip (the round contact's closed form), a
brick landing flat on two corners (one joint impact, its symmetry kept), a monoped and a biped
tipping over (no shape through the ground; without collisions the trunk goes through, and the
run says so), and the scene fields' checks."""

import math

import numpy as np
import pinocchio as pin
import pytest
from legsim.robots.bridge.dynamics import bridge_forces
from legsim.robots.collisions import collision_points
from legsim.robots.urdf import Outlines, load_model

from legsim.errors import ModelError, SceneError
from legsim.scene import load_scene

G = 9.81
INERTIA = '<inertia ixx="{i}" iyy="{i}" izz="{i}" ixy="0" ixz="0" iyz="0"/>'


def link(name, mass, inertia, collision="", visual="", origin="0 0 0"):
    """A URDF link: its inertial at ``origin``, and its collision and visual shapes (xml)."""
    return (
        f'<link name="{name}"><inertial><origin xyz="{origin}"/><mass value="{mass}"/>{INERTIA.format(i=inertia)}'
        f"</inertial>{collision}{visual}</link>"
    )


def shape(kind, geometry, origin="0 0 0", rpy="0 0 0"):
    """A <collision> and its <visual> twin, so that the drawn shape is the one that touches."""
    inner = f'<origin xyz="{origin}" rpy="{rpy}"/><geometry>{geometry}</geometry>'
    return f"<collision>{inner}</collision><visual>{inner}</visual>"


def write(folder, name, body, scene, extra=""):
    """<name>.urdf (a robot whose links and joints are ``body``) and <name>.toml; the scene's path."""
    (folder / f"{name}.urdf").write_text(f'<?xml version="1.0"?><robot name="{name}">{body}</robot>')
    path = folder / f"{name}.toml"
    path.write_text(f'[robot]\nname = "urdf"\n[robot.parameters]\nfile = "{name}.urdf"\n{scene}{extra}')
    return path


INTEGRATOR = "[initial]\nstate = { z = 0.5 }\n[integrator]\nh = 1e-3\neps = 1e-4\nt_final = 0.1\n"


# -- a ball: the round contact's rolling -----------------------------------------------------------
BALL_R, BALL_M = 0.1, 2.0
BALL_I = 0.4 * BALL_M * BALL_R**2  # solid sphere


def ball(folder, extra=""):
    body = link("ball", BALL_M, BALL_I, shape("sphere", f'<sphere radius="{BALL_R}"/>'))
    scene = "collisions = true\ncollision_contacts = { friction = 0.5 }\n"
    scene += "[integrator]\nh = 1e-3\neps = 1e-10\nt_final = 0.3\n"
    return write(folder, "ball", body, scene, extra)


def test_a_sliding_ball_rolls_at_five_sevenths_of_its_speed_where_the_closed_form_says(tmp_path):
    # Slipping on its lowest point, friction mu m g decelerates the centre and spins the ball up:
    # the slip velocity v - r w falls at 7 mu g / 2 and vanishes at t* = 2 v0 / (7 mu g); from
    # there it rolls at 5/7 v0 (a solid sphere, I = 2/5 m r^2). Pinning the centre instead of the
    # lowest point would never spin it.
    v0, mu = 1.0, 0.5
    state = f"{{ z = {BALL_R}, xd = {v0} }}"
    ex = load_scene(ball(tmp_path, f'[initial]\nmode = "ball>"\nstate = {state}\n')).simulate()
    assert ex.status == "finished", ex.message
    (stick,) = ex.transitions
    assert stick.target == "ball"
    t_star = 2 * v0 / (7 * mu * G)
    assert stick.exit_time == pytest.approx(t_star, abs=1e-9)
    x, z, _, xd, zd, pitchd = ex.final_state
    assert xd == pytest.approx(5 / 7 * v0, abs=1e-9)
    assert pitchd * BALL_R == pytest.approx(xd, abs=1e-9)  # rolling: the lowest point at rest
    assert z == pytest.approx(BALL_R, abs=1e-12) and zd == pytest.approx(0.0, abs=1e-12)
    t = ex.t_end
    x_star = v0 * t_star - 0.5 * mu * G * t_star**2
    assert x == pytest.approx(x_star + 5 / 7 * v0 * (t - t_star), abs=1e-9)


def test_a_dropped_spinning_ball_lands_on_its_lowest_point(tmp_path):
    # A plastic landing with friction and no slip stops the lowest point: v+ = r w+, and the
    # angular momentum about the contact point is kept: m v r + I w = (m r^2 + I) w+.
    xd, w = 0.3, -2.0
    state = f"{{ z = 0.5, xd = {xd}, pitchd = {w} }}"
    sticking = ["robot.parameters.collision_contacts.friction=100.0"]
    scene = load_scene(ball(tmp_path, f"[initial]\nstate = {state}\n"), sticking)
    ex = scene.simulate()
    first = ex.transitions[0]
    assert first.target == "ball"
    t_land = math.sqrt(2 * (0.5 - BALL_R) / G)
    assert first.exit_time == pytest.approx(t_land, abs=1e-6)  # the gap is the centre's height minus r
    w_plus = (BALL_M * xd * BALL_R + BALL_I * w) / (BALL_M * BALL_R**2 + BALL_I)
    assert ex.final_state[5] == pytest.approx(w_plus, abs=1e-9)
    assert ex.final_state[3] == pytest.approx(w_plus * BALL_R, abs=1e-9)


# -- a brick landing flat: one joint impact ----------------------------------------------------------
BRICK_HX, BRICK_HZ = 0.3, 0.1


def brick_link():
    return link("brick", 4.0, 0.1, shape("box", f'<box size="{2 * BRICK_HX} 0.2 {2 * BRICK_HZ}"/>'))


def brick(folder, extra=""):
    body = brick_link()
    scene = "collisions = true\ncollision_contacts = { tangential = false }\n"
    scene += "[integrator]\nh = 1e-3\neps = 1e-6\nt_final = 0.6\n"
    return write(folder, "brick", body, scene, extra)


def test_a_brick_landing_flat_on_two_corners_takes_one_joint_impact_and_stays_symmetric(tmp_path):
    # Frictionless corners: two normal rows on three dofs. (Both corners stuck would pin x twice:
    # four rows on three dofs, a singular impact law; see test_..._with_friction below.)
    ex = load_scene(brick(tmp_path, "[initial]\nstate = { z = 0.4 }\n")).simulate()
    assert ex.status == "finished", ex.message
    # the corners, by increasing x then z: 0 and 2 are the bottom ones, which land together
    (landing,) = ex.transitions
    assert landing.name.startswith("joint_brick_0+brick_2") and landing.target == "brick_0+brick_2"
    assert landing.exit_time == pytest.approx(math.sqrt(2 * (0.4 - BRICK_HZ) / G), abs=1e-6)
    # one reset (one impact law for both corners), not two in turn; the impacts counter also
    # counts the solves of the guards' post-impact forces, so it is not the count here
    assert ex.counters["transitions"] == 1 and ex.counters["reset_evals"] == 1
    x, z, pitch, xd, zd, pitchd = ex.final_state
    assert z == pytest.approx(BRICK_HZ, abs=1e-12)
    for value in (x, pitch, xd, zd, pitchd):
        assert abs(value) <= 1e-12
    for seg in ex.segments:  # symmetric along the whole run
        assert np.max(np.abs(seg.x[:, [0, 2, 3, 5]])) <= 1e-12


def test_a_brick_landing_flat_with_friction_takes_one_joint_impact_and_shares_its_weight(tmp_path):
    # Both corners stuck pin x twice: four rows on three dofs, a statically indeterminate
    # support. The impulses and forces there are not unique; the bridge takes the least-norm ones
    # (the native library's least-norm rule, for impulses and forces alike), an equal share at
    # this symmetric support, so the brick lands in one joint impact and stays symmetric.
    path = brick(tmp_path, "[initial]\nstate = { z = 0.4 }\n")
    scene = load_scene(path, ["robot.parameters.collision_contacts={ friction = 0.8 }"])
    ex = scene.simulate()
    assert ex.status == "finished", ex.message
    (landing,) = ex.transitions
    assert landing.name == "joint_brick_0+brick_2" and landing.target == "brick_0+brick_2"
    assert landing.exit_time == pytest.approx(math.sqrt(2 * (0.4 - BRICK_HZ) / G), abs=1e-6)
    z = ex.final_state[1]
    assert z == pytest.approx(BRICK_HZ, abs=1e-12)
    for seg in ex.segments:  # symmetric along the whole run
        assert np.max(np.abs(seg.x[:, [0, 2, 3, 5]])) <= 1e-12
    # At rest each corner carries half the weight, without friction force: (x, z) rows of each
    forces = np.empty(4)
    functions = scene.model.system.mode("brick_0+brick_2").functions
    bridge_forces(0.0, ex.final_state.copy(), np.zeros(0), functions.call_params, forces)
    assert forces[[1, 3]] == pytest.approx([4.0 * G / 2, 4.0 * G / 2], rel=1e-12)
    assert np.abs(forces[[0, 2]]).max() <= 1e-12


@pytest.mark.parametrize("friction", ["friction = 0.8", ""])
def test_a_tall_box_dropped_flat_rests_on_both_corners_from_any_height(tmp_path, friction):
    # The impact left the box a rounding's spin (1e-15 rad/s); the stuck corners' forces then
    # divided by a zero pivot the LU's condition estimate missed, and the joint impact had no
    # outcome: from 0.41, 0.44, 0.47 and 0.51 m the corners landed one after the other and the
    # box tipped over (with friction) or the run broke down (without). It rests at z = 0.2 m.
    body = link("box", 1.0, 0.01, shape("box", '<box size="0.2 0.2 0.4"/>'))
    entries = ", ".join(["restitution = 0.0", friction] if friction else ["restitution = 0.0"])
    scene = f"collisions = true\ncollision_contacts = {{ {entries} }}\n"
    scene += '[integrator]\nmethod = "rk4"\nh = 1e-3\neps = 1e-7\nt_final = 0.5\n'
    for height in (0.41, 0.44, 0.47, 0.51):
        path = write(tmp_path, "box", body, scene, f"[initial]\nstate = {{ z = {height} }}\n")
        ex = load_scene(path).simulate()
        assert ex.status == "finished", (height, ex.message)
        assert [tr.name for tr in ex.transitions] == ["joint_box_0+box_2"], height
        x, z, pitch, xd, zd, pitchd = ex.final_state
        assert z == pytest.approx(0.2, abs=1e-12) and max(abs(v) for v in (x, pitch, xd, zd, pitchd)) <= 1e-12


def test_a_brick_landing_tilted_strikes_one_corner_then_the_other(tmp_path):
    ex = load_scene(brick(tmp_path, "[initial]\nstate = { z = 0.4, pitch = 0.05 }\n")).simulate()
    # pitch > 0 turns +x down: the corner at +x, -z (brick_2) lands first
    assert ex.transitions[0].target == "brick_2"
    assert ex.final_mode == "brick_0+brick_2"
    assert ex.final_state[2] == pytest.approx(0.0, abs=1e-9)  # it ends flat on its bottom face


# -- a monoped and a biped tipping over -------------------------------------------------------------
TRUNK_HX, TRUNK_HZ, FOOT_R, LEG = 0.3, 0.1, 0.03, 0.5
TRUNK = link("trunk", 10.0, 0.35, shape("box", f'<box size="{2 * TRUNK_HX} 0.2 {2 * TRUNK_HZ}"/>'))


def pusher(folder):
    """The brick with an arm hinged at its front top edge, whose tip (a point contact, friction
    0.3) a joint PD presses into the ground ahead of the brick, so that the tip slides while the
    brick comes down on its corners (friction 1.0)."""
    arm = 0.3
    body = (
        brick_link()
        + f'<joint name="arm" type="revolute"><parent link="brick"/><child link="arm"/><origin xyz="{BRICK_HX} 0 '
        f'{BRICK_HZ}"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="500" velocity="10"/></joint>'
        + link("arm", 0.5, 0.005, origin=f"0 0 -{arm / 2}")
        + f'<joint name="tip_mount" type="fixed"><parent link="arm"/><child link="tip"/><origin xyz="0 0 -{arm}"/>'
        '</joint><link name="tip"/>'
    )
    touching = -math.acos(2 * BRICK_HZ / arm)  # the tip on the ground while the brick rests
    scene = (
        'actuated = ["arm"]\ncollisions = true\ncollision_contacts = { friction = 1.0 }\n'
        'contacts = [{ name = "tip", frame = "tip", friction = 0.3 }]\n'
        '[controller]\nname = "joint_pd"\n[controller.parameters]\nkp = 20.0\nkd = 1.0\ntargets = [-0.7]\n'
        f"[initial]\nstate = {{ z = 0.12, arm = {touching + 0.05} }}\n"
        "[integrator]\nh = 1e-3\neps = 1e-6\nt_final = 0.3\n"
    )
    return write(folder, "pusher", body, scene)


def test_a_brick_landing_on_its_second_corner_while_another_contact_slides_rests_on_both(tmp_path):
    # Both corners stuck have the same tangential row, a singular matrix beside the sliding tip:
    # the least-norm forces, as without a sliding contact (this ended model_breakdown, taken for
    # Painleve's paradox, at the landing).
    path = pusher(tmp_path)
    ex = load_scene(path).simulate()
    assert ex.status == "finished", ex.message
    landing = next(tr for tr in ex.transitions if tr.name.startswith("touchdown_brick_2"))
    assert landing.source.startswith("tip>") and landing.target == "brick_0+brick_2"
    # From the landing on the brick rests on its corners: its tip-side corner lifts and lands
    # again with the tip's touchdowns (an accumulation the run warns of), inside the strip of
    # eps = 1e-6 m that the relaxed integrator holds a guard to.
    eps = 1e-6
    for seg in ex.segments:
        after = seg.t >= landing.exit_time
        assert np.all(np.abs(seg.x[after, 1] - BRICK_HZ) <= eps)
        assert np.all(np.abs(seg.x[after, 2]) * 2 * BRICK_HX <= eps)
    assert min(lowest_points(path, ex).values()) >= -1e-6


def leg_links(name):
    """A leg: a rod down to a foot sphere's centre (inside the sphere, so the foot is its lowest
    part), and a frame at the foot's lowest point when upright, for a scene's point contact."""
    rod = f'<cylinder radius="0.02" length="{LEG}"/>'
    rod = f'<visual><origin xyz="0 0 -{LEG / 2}"/><geometry>{rod}</geometry></visual>'
    foot = shape("sphere", f'<sphere radius="{FOOT_R}"/>', origin=f"0 0 -{LEG}")
    return (
        link(name, 1.0, 0.02, foot + rod, origin=f"0 0 -{LEG / 2}")
        + f'<joint name="{name}_sole_mount" type="fixed"><parent link="{name}"/><child link="{name}_sole"/>'
        f'<origin xyz="0 0 -{LEG + FOOT_R}"/></joint><link name="{name}_sole"/>'
    )


MONOPED = (
    TRUNK + '<joint name="slide" type="prismatic"><parent link="trunk"/><child link="leg"/><origin xyz="0 0 -0.1"/>'
    '<axis xyz="0 0 1"/><limit lower="-0.5" upper="0.5" effort="500" velocity="10"/></joint>' + leg_links("leg")
)
BIPED = TRUNK + "".join(
    f'<joint name="{side}_hip" type="revolute"><parent link="trunk"/><child link="{side}"/>'
    f'<origin xyz="{x} 0 -0.1"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="500" velocity="10"/>'
    f"</joint>" + leg_links(side)
    for side, x in (("hind", -0.2), ("front", 0.2))
)


def tipping(folder, name, body, actuated, kp, kd, state, contacts):
    scene = (
        f"actuated = {actuated}\ncollisions = true\ncollision_contacts = {contacts}\n"
        f'[controller]\nname = "joint_pd"\n[controller.parameters]\nkp = {kp}\nkd = {kd}\n'
        f"[initial]\nstate = {state}\n[integrator]\nh = 1e-3\neps = 1e-4\nt_final = 1.0\n"
    )
    return write(folder, name, body, scene)


def monoped(folder):
    state = "{ z = 0.7, pitch = 0.3 }"
    return tipping(folder, "monoped", MONOPED, '["slide"]', 2000.0, 50.0, state, "{ friction = 1.0 }")


def biped(folder):
    # Friction on every corner, the trunk's included: a trunk corner lands with its contact force
    # outside the cone under the joint PD's input after the impact (its velocity term changed
    # with the impact), and the outcome is chosen under that input (slipping at once).
    contacts = "{ friction = 1.0 }"
    state = "{ z = 0.8, pitch = 0.6 }"
    return tipping(folder, "biped", BIPED, '["hind_hip", "front_hip"]', 200.0, 10.0, state, contacts)


def lowest_points(path, ex):
    """The lowest point (m) of each link's shapes over the run's stored states: the URDF's
    outlines (collision and visual alike) placed by Pinocchio, the spheres by their centres."""
    model, _ = load_model(path.with_suffix(".urdf"))
    outlines = Outlines(model, path.with_suffix(".urdf"))
    data = model.createData()
    lowest: dict[str, float] = {}
    spheres = [(obj.parentJoint, obj.placement.translation, obj.geometry.radius) for obj in _spheres(model, path)]
    for seg in ex.segments:
        for x in seg.x:
            q = x[: model.nq]
            for part, polygon in outlines(q).items():
                lowest[part] = min(lowest.get(part, np.inf), float(np.min(polygon[:, 1])))
            pin.forwardKinematics(model, data, q)
            for k, (joint, centre, r) in enumerate(spheres):
                z = (data.oMi[joint].act(centre))[2] - r
                lowest[f"sphere {k}"] = min(lowest.get(f"sphere {k}", np.inf), float(z))
    return lowest


def _spheres(model, path):
    geometry = pin.buildGeomFromUrdf(model, str(path.with_suffix(".urdf")), pin.GeometryType.COLLISION)
    return [obj for obj in geometry.geometryObjects if type(obj.geometry).__name__ == "Sphere"]


@pytest.mark.parametrize("robot", [monoped, biped])
def test_a_robot_tipping_over_on_its_collision_shapes_keeps_every_link_above_the_ground(tmp_path, robot):
    path = robot(tmp_path)
    ex = load_scene(path).simulate()
    assert ex.status == "finished", ex.message
    eps = 1e-4
    # its trunk came down on the ground: some trunk corner was active
    assert any("trunk" in tr.target for tr in ex.transitions), [tr.target for tr in ex.transitions]
    lowest = lowest_points(path, ex)
    assert min(lowest.values()) >= -eps, lowest
    assert not [w for w in ex.warnings if w.kind == "below_ground"]


@pytest.mark.parametrize("robot", [monoped, biped])
def test_without_collisions_the_trunk_goes_through_the_ground_and_the_run_says_so(tmp_path, robot):
    path = robot(tmp_path)
    legs = ["leg"] if robot is monoped else ["hind", "front"]
    contacts = ", ".join(f'{{ name = "{leg}", frame = "{leg}_sole", friction = 1.0 }}' for leg in legs)
    overrides = ["robot.parameters.collisions=false", "robot.parameters.collision_contacts={}"]
    ex = load_scene(path, [*overrides, f"robot.parameters.contacts=[{contacts}]"])
    ex = ex.simulate()
    (warning,) = [w for w in ex.warnings if w.kind == "below_ground"]
    assert "'trunk'" in warning.message
    assert lowest_points(path, ex)["trunk"] < -0.05


# -- the scene fields' checks --------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("override", "match"),
    [
        ("robot.parameters.collision_contacts={ friction = -1.0 }",
         r"collision_contacts.friction: -1.0 is out of range, allowed: float in \[0, inf\)"),
        ("robot.parameters.collision_contacts={ restitution = 2.0 }",
         r"collision_contacts.restitution: 2.0 is out of range, allowed: float in \[0, 1\]"),
        ("robot.parameters.collision_contacts={ mu = 1.0 }",
         r"collision_contacts: unknown key\(s\) \['mu'\]; allowed: \['restitution', 'friction', 'tangential', "
         r"'ground', 'links'\]"),
        ("robot.parameters.collision_contacts={ tangential = 1 }",
         r"collision_contacts.tangential: expected true or false, got 1"),
        ('robot.parameters.collision_contacts={ links = { wheel = "off" } }',
         r"collision_contacts.links: unknown link\(s\) \['wheel'\]; links with a <collision>: \['brick'\]"),
        ('robot.parameters.collision_contacts={ links = { brick = "of" } }',
         r"collision_contacts.links.brick: expected a table \{restitution, friction, tangential\} or 'off'"),
        ('robot.parameters.collision_contacts={ friction = "high" }',
         r"collision_contacts.friction: expected a finite number \(float in \[0, inf\) \(mu\)\), got 'high'"),
        ('robot.parameters.collision_contacts={ links = { brick = "off" } }',
         r"collisions: .*brick.urdf has no <collision> shape to take contacts from \(every link is off\)"),
        ("robot.parameters.collision_contacts={ friction = 1.0, tangential = false }",
         r"collision_contacts.friction: given with tangential = false \(a frictionless contact\); drop one"),
        ('robot.parameters.collision_contacts={ links = { brick = { friction = 1.0, tangential = false } } }',
         r"collision_contacts.links.brick.friction: given with tangential = false"),
        ("robot.parameters.collisions=false",
         r"collision_contacts: given with collisions = false"),
        ('robot.parameters.collisions="yes"', r"collisions: expected a boolean"),
    ],
)  # fmt: skip
def test_the_collision_fields_are_checked_before_anything_runs(tmp_path, override, match):
    path = brick(tmp_path)
    with pytest.raises(SceneError, match=rf"brick.toml: .*{match}"):
        load_scene(path, [override])


def test_a_link_turned_off_keeps_the_others_and_its_overrides_apply(tmp_path):
    body = link("brick", 4.0, 0.1, shape("box", '<box size="0.6 0.2 0.2"/>'))
    body += '<joint name="j" type="fixed"><parent link="brick"/><child link="knob"/><origin xyz="0 0 0.1"/></joint>'
    body += link("knob", 0.1, 0.001, shape("sphere", '<sphere radius="0.05"/>'))
    extra = "\n[robot.parameters.collision_contacts]\nfriction = 0.5\nlinks = { knob = { friction = 0.2 } }\n"
    path = write(tmp_path, "two", body, "collisions = true\n", extra + INTEGRATOR)
    bridge = load_scene(path).model.info["bridge"]
    contacts = {c.name: c for c in bridge.contacts}
    assert list(contacts) == ["brick_0", "brick_1", "brick_2", "brick_3", "knob"]
    assert contacts["knob"].radius == 0.05 and contacts["knob"].friction == 0.2
    assert contacts["brick_0"].radius == 0.0 and contacts["brick_0"].friction == 0.5


@pytest.mark.parametrize(
    ("geometry", "rpy", "match"),
    [
        ('<mesh filename="part.stl"/>', "0 0 0", r"is a mesh \(\w+\); contacts come from spheres"),
        ('<box size="0.2 0.2 0.2"/>', "0.3 0 0", r"is a Box tilted out of the \(x, z\) plane"),
        ('<cylinder radius="0.1" length="0.2"/>', "0.3 0 0", r"is a Cylinder tilted out of the \(x, z\) plane"),
    ],
)
def test_a_shape_the_planar_contacts_cannot_take_is_refused_naming_it(tmp_path, geometry, rpy, match):
    facet = "facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 0.1 0 0\nvertex 0 0.1 0\nendloop\nendfacet\n"
    (tmp_path / "part.stl").write_text(f"solid part\n{facet}endsolid part\n")
    body = link("part", 1.0, 0.01, f'<collision><origin rpy="{rpy}"/><geometry>{geometry}</geometry></collision>')
    path = write(tmp_path, "part", body, "collisions = true\n" + INTEGRATOR)
    with pytest.raises(ModelError, match=rf"part.urdf: collision 'part_0' {match}"):
        load_scene(path)


@pytest.mark.parametrize(
    ("geometry", "rpy", "expected"),
    [
        # a cylinder along z: its outline's corners; along y (rpy roll pi/2): a disc, one round contact
        ('<cylinder radius="0.1" length="0.4"/>', "0 0 0",
         [((-0.1, -0.2), 0.0), ((-0.1, 0.2), 0.0), ((0.1, -0.2), 0.0), ((0.1, 0.2), 0.0)]),
        ('<cylinder radius="0.1" length="0.4"/>', f"{math.pi / 2} 0 0", [((0.0, 0.0), 0.1)]),
        # a box turned about y by pi/4: its outline's four corners
        ('<box size="0.2 0.2 0.2"/>', f"0 {math.pi / 4} 0",
         [((-0.1 * 2**0.5, 0.0), 0.0), ((0.0, -0.1 * 2**0.5), 0.0), ((0.0, 0.1 * 2**0.5), 0.0),
          ((0.1 * 2**0.5, 0.0), 0.0)]),
    ],
)  # fmt: skip
def test_cylinders_and_boxes_become_corners_or_round_contacts(tmp_path, geometry, rpy, expected):
    body = link("part", 1.0, 0.01, f'<collision><origin rpy="{rpy}"/><geometry>{geometry}</geometry></collision>')
    (tmp_path / "part.urdf").write_text(f'<?xml version="1.0"?><robot name="part">{body}</robot>')
    model, _ = load_model(tmp_path / "part.urdf")
    points = collision_points(model, tmp_path / "part.urdf")
    got = [((p.position[0], p.position[2]), p.radius) for p in points]
    assert len(got) == len(expected)
    for (xz, r), (xz_ref, r_ref) in zip(got, expected, strict=True):
        assert xz == pytest.approx(xz_ref, abs=1e-12) and r == r_ref


def slab(folder, mu, grade):
    """A brick resting on a slope of ``grade`` on its two bottom corners (point contacts of
    friction ``mu``), its bottom along the slope."""
    theta = math.atan(grade)
    corners = "".join(
        f'<joint name="{n}_mount" type="fixed"><parent link="brick"/><child link="{n}"/>'
        f'<origin xyz="{x} 0 -{BRICK_HZ}"/></joint><link name="{n}"/>'
        for n, x in (("a", -BRICK_HX), ("b", BRICK_HX))
    )
    scene = (
        f'contacts = [{{ name = "a", frame = "a", friction = {mu} }}, {{ name = "b", frame = "b", friction = {mu} }}]\n'
        f'[terrain]\nkind = "slope"\ngrade = {grade}\n[initial]\nmode = "a+b"\n'
        f"state = {{ x = {-BRICK_HZ * math.sin(theta)}, z = {BRICK_HZ * math.cos(theta)}, pitch = {-theta} }}\n"
        "[integrator]\nh = 1e-3\neps = 1e-6\nt_final = 0.5\n"
    )
    return write(folder, "slab", link("brick", 4.0, 0.1) + corners, scene)


def test_a_brick_on_a_slope_rests_on_its_corners_exactly_below_the_friction_angle(tmp_path):
    # Coulomb: a body on two stuck corners holds while some share of the friction force is
    # inside both cones, for equal mu while tan(theta) <= mu. The corner uphill carries less
    # normal force, and the least-norm (equal) share put it outside its cone below that angle:
    # this start was refused at grade 0.45 < mu = 0.5.
    mu = 0.5
    ex = load_scene(slab(tmp_path, mu, 0.49)).simulate()
    assert ex.status == "finished" and not ex.transitions and not ex.warnings
    start = ex.segments[0].x[0]
    assert np.max(np.abs(ex.final_state - start)) <= 1e-12
    with pytest.raises(SceneError, match=r"lies past the guard of transition slip_"):
        load_scene(slab(tmp_path, mu, 0.51))
