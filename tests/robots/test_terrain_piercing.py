"""A terrain corner between a body's contacts (robots/watches.py, ``TerrainPiercing``): a brick
whose contacts are its collision box's corners, dropped flat over a bump narrower than itself,
lands on its corners with the bump inside it. The run says so (a warning naming the body and the
depth, or a stop under ``below_ground``), and the depth it measures is the closed form's."""

import numpy as np
import pytest
from legsim.robots.watches import PIERCING_DEPTH

from legsim.scene import load_scene

from .test_collision_contacts import link, shape, write

#: The brick: 0.4 m long, 0.12 m high (x, z), its centre at the joint.
LENGTH, HEIGHT = 0.4, 0.12
#: The bump: 0.1 m wide (x in [-0.05, 0.05]), 0.1 m high, with the steps' risers 1 mm wide.
BUMP = '[terrain]\nkind = "steps"\npositions = [-0.05, 0.05]\nheights = [{top}, 0.0]\n'


def brick(folder, terrain, below_ground="warn"):
    body = link("trunk", 4.0, 0.05, shape("box", f'<box size="{LENGTH} 0.1 {HEIGHT}"/>'))
    scene = (
        f'root = "planar"\ncollisions = true\ncollision_contacts = {{ friction = 0.8 }}\n'
        f'below_ground = "{below_ground}"\n{terrain}'
        "[initial]\nstate = { z = 0.4 }\n[integrator]\nh = 1e-3\neps = 1e-4\nt_final = 0.6\n"
    )
    return write(folder, "brick", body, scene)


def test_a_bump_between_the_corners_is_named_at_its_closed_form_depth(tmp_path):
    scene = load_scene(brick(tmp_path, BUMP.format(top=0.1)))
    ex = scene.simulate()
    assert ex.status == "finished" and ex.final_mode == "trunk_0+trunk_2"
    (warning,) = [w for w in ex.warnings if w.kind == "terrain_inside"]
    assert "'trunk'" in warning.message and "terrain passes into" in warning.message
    # At rest on its bottom corners (bottom face at z = 0) the bump's top corners (+-0.05, 0.1)
    # lie 0.1 above the bottom face, 0.02 below the top one and 0.15 inside the ends: 0.02 deep.
    z = ex.final_state[1]
    assert z == pytest.approx(HEIGHT / 2, abs=1e-6)
    piercing = next(w for w in scene.model.info["watches"](None, scene.integrator["eps"]) if w.name == "terrain_inside")
    depth = PIERCING_DEPTH - piercing.value(ex.final_mode, ex.t_end, ex.final_state[None, :])[0]
    assert depth == pytest.approx(HEIGHT - 0.1, abs=1e-6)
    # Falling past it, the bump is deepest with the bottom face 0.04 up: 0.06 inside both faces.
    assert PIERCING_DEPTH - warning.details["least_value"] == pytest.approx(0.06, abs=5e-3)


@pytest.mark.parametrize(("action", "status"), [("strict", "model_breakdown"), ("fall", "fell")])
def test_below_ground_stops_the_run_where_the_bump_enters(tmp_path, action, status):
    ex = load_scene(brick(tmp_path, BUMP.format(top=0.1), action)).simulate()
    assert ex.status == status and "terrain passes into" in ex.message and "'trunk'" in ex.message
    # The bump's corner reaches the falling brick's bottom face (z - 0.06 = 0.1) at the depth allowed.
    z = ex.final_state[1]
    assert z - HEIGHT / 2 == pytest.approx(0.1 - PIERCING_DEPTH, abs=1e-6)


def test_a_plateau_wider_than_the_brick_holds_it_with_no_warning(tmp_path):
    ex = load_scene(brick(tmp_path, '[terrain]\nkind = "steps"\npositions = [-1.0, 1.0]\nheights = [0.1, 0.0]\n'))
    ex = ex.simulate()
    assert ex.status == "finished" and ex.final_mode == "trunk_0+trunk_2"
    assert ex.final_state[1] == pytest.approx(0.1 + HEIGHT / 2, abs=1e-6)
    assert not [w for w in ex.warnings if w.kind == "terrain_inside"]


def test_the_depth_s_rate_is_its_derivative_along_the_motion(tmp_path):
    # The rate that checks between points (the deepest terrain point's distance inside its
    # nearest edge, as the edge moves and turns with the body) against the depth's central
    # difference along q' = v, at states where the bump lies inside the brick, moving and turning.
    scene = load_scene(brick(tmp_path, BUMP.format(top=0.1)))
    piercing = next(w for w in scene.model.info["watches"](None, 1e-4) if w.name == "terrain_inside")
    rng = np.random.default_rng(3)
    delta = 1e-6
    for _ in range(5):
        q = np.array([rng.uniform(-0.05, 0.05), rng.uniform(0.1, 0.14), rng.uniform(-0.2, 0.2)])
        v = rng.normal(size=3)
        states = np.array([np.concatenate([q + side * delta * v, v]) for side in (-1.0, 0.0, 1.0)])
        value = piercing.value("flight", np.zeros(3), states)[:, 0]
        assert PIERCING_DEPTH - value[1] > 0.0  # inside
        rate = piercing.rate("flight", np.zeros(3), states)[1, 0]
        # central difference: O(delta^2) truncation, rounding about 1e-16 / delta
        assert rate == pytest.approx((value[2] - value[0]) / (2 * delta), abs=1e-8)
