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
