"""A terrain corner between a body's contacts (robots/watches.py, ``TerrainPiercing``): a brick
whose contacts are its collision box's corners, dropped flat over a bump narrower than itself,
lands on its corners with the bump inside it. The run says so (a warning naming the body and the
depth, or a stop under ``below_ground``), and the depth it measures is the closed form's."""

import numpy as np
import pytest
from legsim.robots.watches import PIERCING_DEPTH, TerrainPiercing

import legsim.relaxed.between as between
from legsim.errors import SceneError
from legsim.relaxed.watches import refined
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


#: A plate 2 cm thick, thrown down at 10 m/s (no gravity) over the bump 0.1 m high.
PLATE, SPEED = 0.02, 10.0


def plate(folder, h=0.01):
    """The plate's scene: its bottom face 0.12 m up; with steps of 0.01 s the checked points are
    5 ms apart, the bottom face at 0.12 and 0.07 m at the first two."""
    body = link("trunk", 4.0, 0.05, shape("box", f'<box size="{LENGTH} 0.1 {PLATE}"/>'))
    scene = (
        f'root = "planar"\ng = 0.0\ncollisions = true\ncollision_contacts = {{ friction = 0.8 }}\n'
        f"{BUMP.format(top=0.1)}[initial]\nstate = {{ z = {0.12 + PLATE / 2}, zd = {-SPEED} }}\n"
        f"[integrator]\nh = {h}\neps = 1e-4\nt_final = 0.02\n"
    )
    return write(folder, "plate", body, scene)


def test_a_plate_passing_the_bump_s_corners_inside_a_step_is_seen(tmp_path):
    # The bump's top corners enter the bottom face at t = 2 ms and leave the top face at 4 ms,
    # between the checked points 0 and 5 ms: their depth rises to PLATE / 2 at 3 ms, where the
    # nearest face changes, and falls again. The cubic through the checked points' depths and
    # rates does not show it (its peak is 1.4 mm outside); the change of nearest face does.
    ex = load_scene(plate(tmp_path)).simulate()
    (warning,) = [w for w in ex.warnings if w.kind == "terrain_inside"]
    assert "'trunk'" in warning.message
    # the corner PIERCING_DEPTH inside the bottom face: 0.12 - SPEED t = 0.1 - PIERCING_DEPTH
    assert warning.time == pytest.approx((0.02 + PIERCING_DEPTH) / SPEED, abs=1e-12)
    # the deepest point seen: next to where the nearest face changes (PLATE / 2 deep at 3 ms),
    # within the grid's 2^-12 of the half step there (1.2 us, 12 um at 10 m/s)
    assert PIERCING_DEPTH - warning.details["least_value"] == pytest.approx(PLATE / 2, abs=2e-5)
    assert warning.details["least_time"] == pytest.approx(0.003, abs=2e-6)


def test_without_the_corners_and_faces_the_plate_s_passage_is_not_seen(tmp_path, monkeypatch):
    # The premise of the test above: no checked point and no cubic shows the corners inside. (Nor
    # the cubic's misfit at the step's middle, switched off here: where the faces change the check
    # searches by them alone, and elsewhere the misfit may show the kink of the depth as well.)
    monkeypatch.setattr(TerrainPiercing, "cornered", property(lambda self: False))
    monkeypatch.setattr(between, "cubic_misfits", lambda t, v, r, unsmooth: np.zeros(unsmooth.shape))
    ex = load_scene(plate(tmp_path)).simulate()
    assert not [w for w in ex.warnings if w.kind == "terrain_inside"]


def test_a_body_ruled_clear_between_two_checked_points_has_no_terrain_inside(tmp_path):
    # ``TerrainPiercing.clear`` rules a stretch out where the body's lowest corner stays above
    # the highest terrain under the x its corners sweep. Along the plate's fall and landing
    # (steps of 1 ms), wherever it does, the depth stays below PIERCING_DEPTH on the interpolant
    # (200 samples a stretch); and it rules some stretches clear and some not.
    scene = load_scene(plate(tmp_path, h=1e-3))
    watch = next(w for w in scene.model.info["watches"](None, 1e-4) if w.name == "terrain_inside")
    ex = scene.simulate()
    ruled = stretches = 0
    for segment in ex.segments:
        if segment.t.shape[0] < 2:
            continue
        t, x = refined(segment.t, segment.x, segment.dx)
        cleared = watch.clear(segment.mode, t[:-1], x[:-1], t[1:], x[1:])[:, 0]
        ruled, stretches = ruled + int(cleared.sum()), stretches + cleared.shape[0]
        for j in np.flatnonzero(cleared):
            times = np.linspace(t[j], t[j + 1], 200)
            assert watch.parts(segment.mode, times, segment.interpolate(times))[:, 0].min() > 0.0
    assert 0 < ruled < stretches


def test_a_start_with_the_bump_inside_the_brick_is_refused_as_a_bad_start(tmp_path):
    # Bottom face at 0.12 - 0.06 = 0.06 m, the bump's top at 0.1: 0.04 m inside, the corners
    # above the floor. A contact below the ground at the start is refused; so is this.
    path = brick(tmp_path, BUMP.format(top=0.1))
    with pytest.raises(SceneError, match=r"initial\.state.*the terrain passes into.*'trunk' 0\.04 m deep"):
        load_scene(path, ["initial.state.z=0.12"])
    # Resting on the bump's top (bottom face 0.1 + PIERCING_DEPTH / 2 up) is a start like any other.
    assert load_scene(path, [f"initial.state.z={0.1 + HEIGHT / 2 + PIERCING_DEPTH / 2}"]).initial_state[1] > 0.16


def test_a_start_with_a_link_without_contacts_below_the_ground_is_refused(tmp_path):
    body = link("trunk", 4.0, 0.05, shape("box", f'<box size="{LENGTH} 0.1 {HEIGHT}"/>'))
    scene = 'root = "planar"\n[initial]\nstate = { z = 0.03 }\n[integrator]\nh = 1e-3\neps = 1e-4\nt_final = 0.1\n'
    with pytest.raises(SceneError, match=r"initial\.state.*link\(s\) without a contact below the ground.*'trunk'"):
        load_scene(write(tmp_path, "sunk", body, scene))
