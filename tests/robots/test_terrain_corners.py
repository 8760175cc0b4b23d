"""A sliding point passing a corner of a piecewise-linear terrain (``corner_<c>``, robots/bridge):
it leaves a convex corner in flight and strikes the new face at a concave one, against closed
forms.

The robot is a puck: one link of mass M, its point contact at its centre of mass (so friction
turns it not), sliding towards +x with Coulomb friction MU from x = 0 at V0. On the level it
decelerates at MU G, and reaches the corner at x = L at t_c = (V0 - v_c) / (MU G) with speed
v_c = sqrt(V0^2 - 2 MU G L).
"""

from __future__ import annotations

import math

import pytest

from legsim.scene import load_scene

G, M, MU, V0, L = 9.81, 2.0, 0.3, 3.0, 1.0
V_C = math.sqrt(V0**2 - 2 * MU * G * L)
T_C = (V0 - V_C) / (MU * G)

PUCK = (
    '<?xml version="1.0"?><robot name="puck"><link name="puck"><inertial><origin xyz="0 0 0"/>'
    f'<mass value="{M}"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>'
    "</link></robot>"
)


def puck(folder, points, t_final):
    (folder / "puck.urdf").write_text(PUCK)
    path = folder / "puck.toml"
    path.write_text(
        '[robot]\nname = "urdf"\n[robot.parameters]\nfile = "puck.urdf"\nroot = "planar"\n'
        f'contacts = [{{ name = "foot", frame = "puck", restitution = 0.0, friction = {MU} }}]\n'
        f'[terrain]\nkind = "profile"\npoints = {points}\n'
        f'[initial]\nmode = "foot>"\nstate = {{ xd = {V0} }}\n'
        f"[integrator]\nh = 1e-3\neps = 1e-6\nt_final = {t_final}\n"
    )
    return load_scene(path)


def corner_of(execution):
    (corner,) = [tr for tr in execution.transitions if tr.name.startswith("corner_foot")]
    return corner


def test_a_puck_sliding_over_a_convex_corner_leaves_it_and_lands_where_the_parabola_says(tmp_path):
    """Past a corner onto a 45-degree face falling away, the puck's velocity leaves the face: it
    flies from the corner at v_c and lands on the face after 2 v_c / G, at x = L + 2 v_c^2 / G."""
    ex = puck(tmp_path, [[-1.0, 0.0], [L, 0.0], [L + 5.0, -5.0]], T_C + 2 * V_C / G + 0.05).simulate()
    corner = corner_of(ex)
    assert corner.target == "flight" and corner.source == "foot>"
    assert abs(corner.time - T_C) < 1e-9  # rk4 integrates the constant deceleration exactly
    assert abs(corner.state_after[3] - V_C) < 1e-9 and abs(corner.state_after[4]) < 1e-9
    (landing,) = [tr for tr in ex.transitions if tr.source == "flight" and tr.name.startswith("touchdown_foot")]
    assert abs(landing.time - (T_C + 2 * V_C / G)) < 1e-5  # to the strip: eps over the closing speed
    assert abs(landing.state_before[0] - (L + 2 * V_C**2 / G)) < 1e-5
    assert ex.counters["guard_jumps"] >= 1


@pytest.mark.parametrize("degrees", [20.0, 30.0])
def test_a_puck_sliding_into_a_rising_face_strikes_it_with_the_sliding_impact(tmp_path, degrees):
    """At a concave corner onto a face rising at theta, the plastic impact takes the normal
    velocity v_c sin(theta) and, sliding on, MU times that impulse from the tangential one:
    v+ = v_c (cos(theta) - MU sin(theta)) along the face (closed form of the frictional impact)."""
    theta = math.radians(degrees)
    points = [[-1.0, 0.0], [L, 0.0], [L + 5.0, 5.0 * math.tan(theta)]]
    ex = puck(tmp_path, points, T_C + 0.05).simulate()
    assert ex.status == "finished", ex.message
    corner = corner_of(ex)
    assert abs(corner.time - T_C) < 1e-9
    assert corner.target == "foot>"
    v_plus = V_C * (math.cos(theta) - MU * math.sin(theta))
    xd, zd = corner.state_after[3], corner.state_after[4]
    assert abs(math.hypot(xd, zd) - v_plus) < 1e-9
    assert abs(zd - math.tan(theta) * xd) < 1e-12  # along the new face


# -- a point in a notch (a concave corner), held by both faces ------------------------------------


def resting_puck(folder, points, mode, t_final, mu):
    """The puck at rest at the profile's second point (a notch), in ``mode``."""
    (folder / "puck.urdf").write_text(PUCK)
    path = folder / "puck.toml"
    x0, z0 = points[1]
    path.write_text(
        '[robot]\nname = "urdf"\n[robot.parameters]\nfile = "puck.urdf"\nroot = "planar"\n'
        f'contacts = [{{ name = "foot", frame = "puck", restitution = 0.0, friction = {mu} }}]\n'
        f'[terrain]\nkind = "profile"\npoints = {points}\n'
        f'[initial]\nmode = "{mode}"\nstate = {{ x = {x0}, z = {z0} }}\n'
        f"[integrator]\nh = 1e-3\neps = 1e-6\nt_final = {t_final}\n"
    )
    return load_scene(path)


def v_notch(left_degrees, right_degrees):
    """A profile falling at left_degrees to a notch at (0, 0) and rising at right_degrees after it."""
    left, right = math.tan(math.radians(left_degrees)), math.tan(math.radians(right_degrees))
    return [[-2.0, 2.0 * left], [0.0, 0.0], [2.0, 2.0 * right]]


def test_a_puck_at_rest_in_a_v_notch_is_held_by_both_faces(tmp_path):
    """Faces at 40 degrees each side, MU = 0.3: either face alone lets the puck slide (tan 40 deg =
    0.84 > MU), but in the notch the ground pushes anywhere in the sum of the two cones, 40 + 16.7
    degrees about the vertical: gravity is held. The force is M G along the bisector (the
    vertical), the tangential part 0, and the puck never moves."""
    scene = resting_puck(tmp_path, v_notch(40.0, 40.0), "foot", 1.0, MU)
    ex = scene.simulate()
    assert ex.status == "finished" and not ex.warnings and not ex.transitions
    assert max(abs(v) for v in ex.final_state[3:6]) < 1e-12
    forces = scene.model.info["bridge"].constraint_forces("foot", ex.final_state)["foot"]
    assert forces == pytest.approx([0.0, M * G], abs=1e-9)


def test_a_puck_in_a_notch_whose_cones_miss_gravity_slides_out_along_the_gentler_face(tmp_path):
    """A face rising at 10 degrees into a notch, then one at 60: with MU = 0.1 the two cones span
    -65.7 to -4.3 degrees from the vertical, which gravity misses, so the puck cannot rest there
    (the initial check refuses it stuck); slipping, it slides down the 10-degree face (the one
    it slips onto) at G (sin 10 deg - MU cos 10 deg)."""
    points = v_notch(-10.0, 60.0)
    with pytest.raises(Exception, match="foot"):
        resting_puck(tmp_path, points, "foot", 0.5, 0.1).simulate()
    t_final = 0.5
    ex = resting_puck(tmp_path, points, "foot<", t_final, 0.1).simulate()
    assert ex.status == "finished" and not ex.warnings and not ex.transitions
    a = math.radians(10.0)
    accel = G * (math.sin(a) - 0.1 * math.cos(a))
    x = ex.final_state
    assert x[0] < 0.0 and math.hypot(x[0], x[1]) == pytest.approx(0.5 * accel * t_final**2, rel=1e-10)
    assert x[1] - math.tan(a) * x[0] == pytest.approx(0.0, abs=1e-12)


def test_a_puck_sliding_into_a_riser_comes_to_rest_in_its_notch(tmp_path):
    """A step 0.2 m high whose riser rises over 1 mm (88.9 degrees): the puck reaches the riser's
    foot at t_c with v_c, the plastic impact leaves v_c cos(88.9 deg) along the riser, which
    friction stops (cos < MU sin), and the notch holds it: one transition, then rest there."""
    riser = 1e-3
    points = [[-1.0, 0.0], [L - riser, 0.0], [L, 0.2], [L + 1.0, 0.2]]
    ex = puck(tmp_path, points, T_C + 0.5).simulate()
    assert ex.status == "finished" and not ex.warnings, ex.message
    (corner,) = ex.transitions
    assert corner.name.startswith("corner_foot") and corner.target == "foot"
    assert abs(corner.time - (V0 - math.sqrt(V0**2 - 2 * MU * G * (L - riser))) / (MU * G)) < 1e-9
    assert max(abs(v) for v in ex.final_state[3:6]) < 1e-9
    assert abs(ex.final_state[0] - (L - riser)) < 1e-9 and abs(ex.final_state[1]) < 1e-9
