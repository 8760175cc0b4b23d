"""Round contacts (collision spheres and cylinders, robots/collisions.py) on terrain that is not
level, on a ball written in the test's folder: on a slope and a sine, where the point nearest the
ground moves smoothly with the centre, and on a profile's faces and corners (steps), where it
rolls round a convex corner on an arc and strikes the next face at a concave one; each against
its closed form or a root-found reference."""

import math

import numpy as np
import pytest
from legsim.robots.urdf import load_model

from legsim.errors import ModelError, SceneError
from legsim.scene import load_scene

from .test_collision_contacts import BALL_I, BALL_M, BALL_R, G, ball


def test_a_round_contact_where_it_would_touch_a_trough_twice_is_refused_naming_it(tmp_path):
    # A sphere meets the ground at its point nearest it. In a sine's trough narrower than itself
    # it would touch two points at once (two contacts of one frame), which is not modelled:
    # refused rather than answered wrongly. Least radius of curvature 1 / (a k^2) = 0.00253 m.
    terrain = '[terrain]\nkind = "sine"\namplitude = 0.1\nwavelength = 0.1\n'
    with pytest.raises(
        (ModelError, SceneError), match=r"fit the troughs.*0.002533 m.*'ball' \(radius 0.1 m\) is wider"
    ):
        load_scene(ball(tmp_path, terrain))


def test_a_round_contact_on_steps_without_friction_is_refused_naming_it(tmp_path):
    # A ball passing a concave corner strikes the next face: an event of the friction law's,
    # which a robot whose contacts have no friction coefficient does not take.
    terrain = '[terrain]\nkind = "steps"\nheights = [0.05]\npositions = [0.5]\n'
    no_coefficient = ["robot.parameters.collision_contacts={ tangential = true }"]
    with pytest.raises(
        (ModelError, SceneError), match=r"round contacts \['ball'\] on the terrain 1 steps.*need the friction law"
    ):
        load_scene(ball(tmp_path, terrain), no_coefficient)


#: A step up at x = 0 (its riser a ramp of 1 mm run) and a step down at x = 0 (a 0.5 m drop).
STEP_UP = '[terrain]\nkind = "profile"\npoints = [[-0.001, 0.0], [0.0, 0.05]]\n'
STEP_DOWN = '[terrain]\nkind = "profile"\npoints = [[0.0, 0.0], [0.001, -0.5]]\n'
TIGHT = ['integrator.method="dopri5"', "integrator.rtol=1e-10", "integrator.atol=1e-10"]


def test_a_ball_dropped_beside_a_steps_edge_lands_on_the_edge_where_the_closed_form_says(tmp_path):
    # Falling straight down with its centre 2 cm short of the edge (0, 0.05), the ball meets the
    # edge, not a face, when its centre is r from it: at z = 0.05 + sqrt(r^2 - 0.02^2).
    x0, z0 = -0.02, 0.5
    ex = load_scene(ball(tmp_path, f"[initial]\nstate = {{ x = {x0}, z = {z0} }}\n{STEP_UP}"),
                    ["integrator.t_final=0.6", "integrator.eps=1e-9", *TIGHT]).simulate()  # fmt: skip
    assert ex.status == "finished" and ex.counters["python_steps"] == 0, ex.message
    t_land = math.sqrt(2 * (z0 - 0.05 - math.sqrt(BALL_R**2 - x0**2)) / G)
    landing = ex.transitions[0]
    assert landing.name == "touchdown_ball"
    # the crossing's strip is eps = 1e-9 m deep, crossed at about 2.6 m/s
    assert landing.time <= t_land + 1e-12 and landing.exit_time == pytest.approx(t_land, abs=1e-9)
    # then it rolls off the edge onto the lower floor, never into the step
    assert ex.final_state[0] < -BALL_R and ex.final_state[1] == pytest.approx(BALL_R, abs=1e-9)


def test_a_ball_rolling_over_an_edge_slips_where_the_closed_form_says_keeping_energy_and_distance(tmp_path):
    # Released at rest on the edge of a drop, its centre at theta0 from the vertical through the
    # edge, the ball rolls round the edge: its centre stays r from it, the energy is kept, and
    # (7/10) v^2 = g r (cos(theta0) - cos(theta)). Friction holds it while (2/7) m g sin(theta)
    # <= mu N, N = m g cos(theta) - m v^2 / r; it slips where that first fails.
    from scipy.optimize import brentq

    theta0, mu = 0.2, 100.0
    xc, zc = BALL_R * math.sin(theta0), BALL_R * math.cos(theta0)
    extra = f'[initial]\nmode = "ball"\nstate = {{ x = {xc!r}, z = {zc!r} }}\n{STEP_DOWN}'
    sets = ["integrator.t_final=0.3", f"robot.parameters.collision_contacts.friction={mu}", *TIGHT]
    ex = load_scene(ball(tmp_path, extra), sets).simulate()
    assert ex.status == "finished" and ex.counters["python_steps"] == 0, ex.message
    # on the corner's arc from the start (it leaves it by a slip and a liftoff, located events)
    assert [w.kind for w in ex.warnings] == ["round_corner"]
    slip = ex.transitions[0]
    assert slip.name == "slip_ball>"

    def margin(theta):
        return 2 / 7 * math.sin(theta) - mu * (17 / 7 * math.cos(theta) - 10 / 7 * math.cos(theta0))

    theta = brentq(margin, theta0, 1.5, xtol=1e-15)
    q = slip.state_before
    assert q[1] / BALL_R == pytest.approx(math.cos(theta), abs=1e-12)
    x = ex.segments[0].x
    energy = 0.5 * BALL_M * (x[:, 3] ** 2 + x[:, 4] ** 2) + 0.5 * BALL_I * x[:, 5] ** 2 + BALL_M * G * x[:, 1]
    assert np.ptp(energy) < 1e-12 * BALL_M * G * BALL_R
    np.testing.assert_allclose(np.hypot(x[:, 0], x[:, 1]), BALL_R, atol=1e-14)


@pytest.mark.parametrize("alpha_deg", [10.0, 20.0, 40.0])
def test_a_ball_rolling_off_a_ramp_onto_the_floor_keeps_the_closed_form_share_of_its_speed(tmp_path, alpha_deg):
    # Rolling down a ramp of angle alpha onto the floor, the ball strikes the floor where its
    # centre crosses the corner's bisector (its corner event). The impulse acts at the floor's
    # contact point, so the angular momentum about it is kept: m v r cos(alpha) + I v / r before,
    # (m r + I / r) v' after; rolling on, v' / v = (2 + 5 cos(alpha)) / 7 for a solid sphere.
    alpha = math.radians(alpha_deg)
    s0 = -0.5  # the contact point's x on the ramp
    xc, zc = s0 + BALL_R * math.sin(alpha), -math.tan(alpha) * s0 + BALL_R * math.cos(alpha)
    ramp = f'[terrain]\nkind = "profile"\npoints = [[-1.0, {math.tan(alpha)!r}], [0.0, 0.0]]\n'
    extra = f'[initial]\nmode = "ball"\nstate = {{ x = {xc!r}, z = {zc!r} }}\n{ramp}'
    ex = load_scene(
        ball(tmp_path, extra), ["integrator.t_final=1.0", "robot.parameters.collision_contacts.friction=100.0", *TIGHT]
    ).simulate()
    assert ex.status == "finished" and not ex.warnings and ex.counters["python_steps"] == 0, ex.message
    (strike,) = ex.transitions
    assert strike.name.startswith("corner_ball") and strike.target == "ball"
    before, after = strike.state_before, strike.state_after
    ratio = math.hypot(after[3], after[4]) / math.hypot(before[3], before[4])
    assert ratio == pytest.approx((2 + 5 * math.cos(alpha)) / 7, abs=1e-12)
    assert after[4] == pytest.approx(0.0, abs=1e-12) and ex.final_state[1] == pytest.approx(BALL_R, abs=1e-12)


def test_a_ball_struck_into_a_notch_stops_the_run_naming_it(tmp_path):
    # Rolling backwards into the foot of a riser (backspin), the ball strikes the riser and is
    # driven down into the floor, which it also touches there: a strike on two faces at once,
    # which the impact law taken one face after the other does not answer. The run stops there
    # rather than finish with one order's answer.
    extra = f'[initial]\nmode = "ball"\nstate = {{ x = -0.5, z = {BALL_R}, xd = 1.0, pitchd = -10.0 }}\n'
    riser = '[terrain]\nkind = "profile"\npoints = [[-0.001, 0.0], [0.0, 0.3]]\n'
    ex = load_scene(ball(tmp_path, extra + riser), ["integrator.t_final=1.0", *TIGHT]).simulate()
    assert ex.status == "model_breakdown" and "notch" in ex.message, ex.message
    # it stops where it touches both: r from the floor and from the riser z = 300 (x + 0.001)
    x_both = -0.001 + (BALL_R - BALL_R * math.sqrt(1 + 300**2)) / 300
    assert ex.final_state[0] == pytest.approx(x_both, abs=1e-6) and ex.final_state[1] == pytest.approx(BALL_R)


#: The sine of the rolling tests: least radius of curvature 1 / (a k^2) = 0.507 m.
SINE_A, SINE_WAVELENGTH = 0.05, 1.0
SINE_TERRAIN = f'[terrain]\nkind = "sine"\namplitude = {SINE_A}\nwavelength = {SINE_WAVELENGTH}\n'


def sine_height(s):
    return SINE_A * math.sin(2 * math.pi * s / SINE_WAVELENGTH)


def test_a_ball_dropped_on_a_sine_lands_where_its_centre_is_r_from_the_curve(tmp_path):
    # Thrown from (0.1, 0.5) m at 0.3 m/s, the centre flies a parabola; it lands when its
    # distance to the curve (minimised over the curve's points) is r, which a root finder gives.
    from scipy.optimize import brentq, minimize_scalar

    x0, z0, vx0 = 0.1, 0.5, 0.3
    extra = f"[initial]\nstate = {{ x = {x0}, z = {z0}, xd = {vx0} }}\n{SINE_TERRAIN}"
    ex = load_scene(ball(tmp_path, extra), ["integrator.t_final=0.3", "integrator.eps=1e-9"]).simulate()
    assert ex.status == "finished" and ex.counters["python_steps"] == 0, ex.message

    def gap(t):
        xc, zc = x0 + vx0 * t, z0 - 0.5 * G * t * t
        closest = minimize_scalar(lambda s: math.hypot(s - xc, sine_height(s) - zc), bounds=(xc - 0.5, xc + 0.5),
                                  method="bounded", options={"xatol": 1e-12})  # fmt: skip
        return closest.fun - BALL_R

    t_land = brentq(gap, 0.0, 0.29, xtol=1e-14)
    (landing,) = ex.transitions
    assert landing.name == "touchdown_ball"
    # the crossing's strip is eps = 1e-9 m deep, crossed at about 2.6 m/s
    assert landing.time <= t_land + 1e-12 and landing.exit_time == pytest.approx(t_land, abs=1e-9)


def resting_in_the_trough(offset):
    """The ball's centre (m) resting on the sine ``offset`` (m) along x from the bottom of a trough."""
    k = 2 * math.pi / SINE_WAVELENGTH
    s = -SINE_WAVELENGTH / 4 + offset
    grade = SINE_A * k * math.cos(k * s)
    norm = math.sqrt(1 + grade * grade)
    return s - BALL_R * grade / norm, sine_height(s) + BALL_R / norm


def test_a_ball_rolls_in_a_sines_trough_at_the_period_of_its_offset_curve(tmp_path):
    # Rolling without slip, the centre moves on the curve r from the sine, whose radius at the
    # trough's bottom is R - r, R = 1 / (a k^2): a pendulum of that length with the inertia
    # m + I / r^2, period 2 pi sqrt((1 + I / (m r^2)) (R - r) / g). Released 0.3 mm from the
    # bottom its period differs from that by the amplitude's square (measured 3.8e-7 relative;
    # 4.2e-6 from 1 mm). The rolling constraint does no work: the energy is kept, and the centre
    # stays r from the sine.
    from legsim.heights import nearest
    from legsim.terrain import sine_terrain

    x0, z0 = resting_in_the_trough(3e-4)
    extra = f'[initial]\nmode = "ball"\nstate = {{ x = {x0!r}, z = {z0!r} }}\n{SINE_TERRAIN}'
    ex = load_scene(ball(tmp_path, extra), ["integrator.t_final=6.5", "integrator.h=2e-3"]).simulate()
    assert ex.status == "finished" and not ex.transitions and ex.counters["python_steps"] == 0, ex.message
    (seg,) = ex.segments
    t, xd = seg.t, seg.x[:, 3]
    down = np.where((xd[:-1] > 0) & (xd[1:] <= 0))[0]  # the velocity's downward zero crossings
    crossings = t[down] - xd[down] * (t[down + 1] - t[down]) / (xd[down + 1] - xd[down])
    radius = 1 / (SINE_A * (2 * math.pi / SINE_WAVELENGTH) ** 2)
    period = 2 * math.pi * math.sqrt((1 + BALL_I / (BALL_M * BALL_R**2)) * (radius - BALL_R) / G)
    assert len(crossings) >= 4
    np.testing.assert_allclose(np.diff(crossings), period, rtol=1e-6)
    energy = (
        0.5 * BALL_M * (seg.x[:, 3] ** 2 + seg.x[:, 4] ** 2)
        + 0.5 * BALL_I * seg.x[:, 5] ** 2
        + BALL_M * G * seg.x[:, 1]
    )
    assert np.ptp(energy) < 1e-9 * energy[0]
    terrain = sine_terrain(SINE_A, SINE_WAVELENGTH).array
    distance = np.array([nearest(terrain, 0, x, z)[1] for x, z in seg.x[:, :2]])
    np.testing.assert_allclose(distance, BALL_R, atol=1e-11)


def test_a_ball_rolling_over_a_sines_crest_keeps_its_energy_and_its_distance(tmp_path):
    # Dropped onto a flank it lands (a plastic impact with friction, rolling at once), rolls
    # through the trough and over the next crest without leaving the sine (its speed there stays
    # below sqrt(g (R + r)), R the crest's radius of curvature): after the landing the energy is
    # kept and the centre stays r from the curve.
    from legsim.heights import nearest
    from legsim.terrain import sine_terrain

    extra = f"[initial]\nstate = {{ x = 0.1, z = 0.5, xd = 0.3 }}\n{SINE_TERRAIN}"
    sticking = ["robot.parameters.collision_contacts.friction=100.0", "integrator.t_final=3.0"]
    ex = load_scene(ball(tmp_path, extra), sticking).simulate()
    assert ex.status == "finished" and not ex.warnings, ex.message
    (landing,) = ex.transitions
    assert landing.target == "ball"
    x = np.concatenate([s.x for s in ex.segments[1:]])
    assert np.ptp(x[:, 0]) > 0.5  # over a crest and back
    energy = 0.5 * BALL_M * (x[:, 3] ** 2 + x[:, 4] ** 2) + 0.5 * BALL_I * x[:, 5] ** 2 + BALL_M * G * x[:, 1]
    assert np.ptp(energy) < 1e-8 * energy[0]
    terrain = sine_terrain(SINE_A, SINE_WAVELENGTH).array
    np.testing.assert_allclose([nearest(terrain, 0, a, b)[1] for a, b in x[:, :2]], BALL_R, atol=1e-10)


SLOPE_DEG = 10.0


def test_a_ball_dropped_on_a_slope_lands_where_its_centre_is_r_from_the_plane(tmp_path):
    # Falling straight down from z0 above the slope's origin, the centre is r from the plane
    # z = tan(theta) x when z cos(theta) = r: at t = sqrt(2 (z0 - r / cos(theta)) / g).
    theta, z0 = math.radians(SLOPE_DEG), 0.5
    extra = f'[initial]\nstate = {{ z = {z0} }}\n[terrain]\nkind = "slope"\nangle = {SLOPE_DEG}\n'
    ex = load_scene(ball(tmp_path, extra), ["integrator.t_final=0.35"]).simulate()
    assert ex.status == "finished", ex.message
    t_land = math.sqrt(2 * (z0 - BALL_R / math.cos(theta)) / G)
    assert ex.transitions[0].exit_time == pytest.approx(t_land, abs=1e-6)
    x, z = ex.final_state[:2]
    # at rest on the plane or rolling down it: the centre stays r from the plane
    assert (z - math.tan(theta) * x) * math.cos(theta) == pytest.approx(BALL_R, abs=1e-9)


def test_a_ball_on_a_slope_rolls_down_at_five_sevenths_of_g_sin_theta(tmp_path):
    # Resting on a slope of 10 degrees (friction 0.5 > 2/7 tan(theta): no slip), a solid sphere
    # rolls down at a = 5/7 g sin(theta) along the slope, its contact point at rest: after t its
    # centre has moved a t^2 / 2 down the slope and turns at a t / r. Tracking the lowest point
    # instead of the point on the plane would leave the ball off the plane or sliding.
    theta = math.radians(SLOPE_DEG)
    z_touch = BALL_R / math.cos(theta)
    extra = f'[initial]\nmode = "ball"\nstate = {{ z = {z_touch} }}\n[terrain]\nkind = "slope"\nangle = {SLOPE_DEG}\n'
    ex = load_scene(ball(tmp_path, extra)).simulate()
    assert ex.status == "finished" and not ex.transitions, ex.message
    t = ex.t_end
    a = 5 / 7 * G * math.sin(theta)
    x, z, _, xd, zd, pitchd = ex.final_state
    assert x == pytest.approx(-0.5 * a * t**2 * math.cos(theta), abs=1e-9)
    assert z == pytest.approx(z_touch - 0.5 * a * t**2 * math.sin(theta), abs=1e-9)
    assert math.hypot(xd, zd) == pytest.approx(a * t, abs=1e-9)
    assert abs(pitchd) * BALL_R == pytest.approx(a * t, abs=1e-9)


def test_a_frictionless_ball_slides_in_a_sines_trough_keeping_its_energy_spin_and_distance(tmp_path):
    # Without friction (the normal row alone: the sliding branch of the curvature term) the ball
    # slides on the curve r from the sine: its spin never changes, the energy m v^2 / 2 + m g z
    # is kept and the centre stays r from the curve.
    from legsim.heights import nearest
    from legsim.terrain import sine_terrain

    x0, z0 = resting_in_the_trough(0.1)
    extra = f'[initial]\nmode = "ball"\nstate = {{ x = {x0!r}, z = {z0!r}, pitchd = 3.0 }}\n{SINE_TERRAIN}'
    frictionless = ["robot.parameters.collision_contacts={ tangential = false }", "integrator.t_final=3.0"]
    ex = load_scene(ball(tmp_path, extra), [*frictionless, "integrator.h=2e-3"]).simulate()
    assert ex.status == "finished" and not ex.transitions and ex.counters["python_steps"] == 0, ex.message
    x = np.concatenate([s.x for s in ex.segments])
    assert np.ptp(x[:, 0]) > 0.15 and np.all(x[:, 5] == 3.0)
    energy = 0.5 * BALL_M * (x[:, 3] ** 2 + x[:, 4] ** 2) + BALL_M * G * x[:, 1]
    assert np.ptp(energy) < 1e-9 * energy[0]
    terrain = sine_terrain(SINE_A, SINE_WAVELENGTH).array
    np.testing.assert_allclose([nearest(terrain, 0, a, b)[1] for a, b in x[:, :2]], BALL_R, atol=1e-10)


def test_a_round_frame_on_a_sine_answers_nan_at_a_configuration_it_was_not_placed_at(tmp_path):
    # On a sine the offset from a ball's centre to its point nearest the ground moves with the
    # configuration, which the model functions place before each native call; a call at another
    # q answers nan (a breakdown the run reports), never the kinematics of a point left behind.
    from legsim.robots._native.calls import lsn_frames, lsn_round_place
    from legsim.robots.bridge import PointContact
    from legsim.robots.bridge.model import build_model

    from legsim.terrain import sine_terrain

    model, _ = load_model(ball(tmp_path).with_suffix(".urdf"))
    contact = PointContact("ball", "ball", radius=BALL_R, friction=0.5)
    bridge = build_model(model, [contact], coordinate_names=None, velocity_names=None, joint_damping=None,
                         actuated=(), name="ball", terrain=sine_terrain(SINE_A, SINE_WAVELENGTH))  # fmt: skip
    frame = bridge.rigid["ball"].frame_id
    q, v, ids, out = np.array([0.3, 0.2, 0.0]), np.zeros(3), np.array([float(frame)]), np.empty(4)

    def kinematics(at):
        lsn_frames(bridge.handle, at.ctypes.data, v.ctypes.data, 1, ids.ctypes.data, out.ctypes.data)
        return out.copy()

    assert np.all(np.isnan(kinematics(q)))  # never placed
    lsn_round_place(bridge.handle, q.ctypes.data, frame, 0.01, -0.0995)
    np.testing.assert_allclose(kinematics(q), [0.31, 0.1005, 0.0, 0.0], atol=1e-15)
    assert np.all(np.isnan(kinematics(q + np.array([1e-12, 0.0, 0.0]))))


def test_a_ball_rolling_round_a_corner_needs_error_control_says_so_and_keeps_near_its_path(tmp_path):
    # Rolling along a level top and over a 20 degree corner onto the slope below, the centre's
    # path turns from a line onto the arc of radius r about the corner and back: its curvature,
    # and the normal acceleration, jump at the arc's ends inside one contact mode, where no step
    # is landed. Fixed steps cross that to first order and leave the ball drifting off the
    # terrain (6.5e-5 m at h = 1e-3 s after one corner, growing with time): a scene with round
    # contacts on a profile is refused without error control, naming the field. Under dopri5 the
    # run says so in a warning and keeps the centre within 1e-8 m of r from the terrain.
    from legsim.heights import nearest
    from legsim.terrain import profile_terrain

    points = [[0.0, 0.0], [1.0, -math.tan(math.radians(20.0))]]
    terrain = f'[terrain]\nkind = "profile"\npoints = {points}\n'
    rolling = f"xd = 0.3, pitchd = {0.3 / BALL_R}"
    extra = f'[initial]\nmode = "ball"\nstate = {{ x = -0.2, z = {BALL_R}, {rolling} }}\n{terrain}'
    sticking = ["integrator.t_final=1.2", "robot.parameters.collision_contacts.friction=100.0"]
    with pytest.raises(SceneError, match=r"integrator.rtol: missing: fixed steps.*round contacts \['ball'\]"):
        load_scene(ball(tmp_path, extra), sticking)
    ex = load_scene(ball(tmp_path, extra), [*sticking, *TIGHT]).simulate()
    assert ex.status == "finished" and not ex.transitions, ex.message
    (warning,) = ex.warnings
    assert warning.kind == "round_corner" and "'ball' rolled on the arc round a corner" in warning.message
    # a yes-or-no condition: its warning says where it first held, once, not "the most" of it
    assert warning.message.count("rolled on the arc") == 1 and "the most at" not in warning.message
    assert warning.time == pytest.approx(0.2 / 0.3, abs=2e-3)  # the centre passes over the corner
    x = np.concatenate([s.x for s in ex.segments])
    assert x[-1, 0] > 0.3  # over the corner and down the slope
    array = profile_terrain(*zip(*points, strict=True)).array
    distance = np.array([nearest(array, 0, a, b)[1] for a, b in x[:, :2]])
    assert np.abs(distance - BALL_R).max() < 1e-8


def test_a_ball_rolls_across_a_breakpoint_between_level_faces_as_on_one_face(tmp_path):
    # A breakpoint between collinear faces is no corner: rolling across it (its centre passing
    # within rounding of the breakpoint, where the end of one piece and the inside of the next
    # are equally near) the ball rolls on at its speed, without a transition or a warning.
    terrain = '[terrain]\nkind = "profile"\npoints = [[-1.0, 0.0], [0.3, 0.0], [1.0, 0.0]]\n'
    for x0 in (0.3, 0.3 + 1e-10, 0.0):
        extra = f'[initial]\nmode = "ball"\nstate = {{ x = {x0!r}, z = {BALL_R}, xd = 0.5, pitchd = 5.0 }}\n{terrain}'
        ex = load_scene(ball(tmp_path, extra), ["integrator.t_final=1.0", *TIGHT]).simulate()
        assert ex.status == "finished" and not ex.transitions and not ex.warnings, ex.message
        assert ex.final_state[0] == pytest.approx(x0 + 0.5, abs=1e-12)
        assert ex.final_state[1] == pytest.approx(BALL_R, abs=1e-12)


@pytest.mark.parametrize(
    "points",
    [
        [[-1.0, 0.5], [0.0, 0.0], [1.0, 0.5]],  # a V: both faces at once
        [[0.0, 0.0], [0.001, -0.2], [0.099, -0.2], [0.1, 0.0]],  # a pit narrower than the ball: both edges
    ],
)
def test_a_ball_landing_on_two_points_at_once_stops_the_run_naming_it(tmp_path, points):
    # Dropped straight onto the middle of a V notch or of a pit narrower than itself, the ball
    # meets the terrain at two points at once; struck at the one taken first, it is driven into
    # the other: a strike on two points at once, which the impact law taken at one point does
    # not answer. The run stops there rather than finish with one order's answer.
    x0 = 0.0 if len(points) == 3 else 0.05
    extra = f'[initial]\nstate = {{ x = {x0}, z = 0.5 }}\n[terrain]\nkind = "profile"\npoints = {points}\n'
    sets = ["integrator.t_final=0.5", "robot.parameters.collision_contacts.friction=100.0", *TIGHT]
    ex = load_scene(ball(tmp_path, extra), sets).simulate()
    assert ex.status == "model_breakdown" and "notch" in ex.message, ex.message
    assert not ex.transitions


def test_a_monoped_with_a_ball_foot_tips_over_onto_a_lower_step_and_stays_above_it(tmp_path):
    # The tipping monoped of test_collision_contacts (a box trunk's corners and a ball foot) with
    # a step 5 cm down at x = 0.2 m: built (its checks evaluate the foot's centre deep under the
    # step's edge, where the nearest point is the edge), it tips over onto the lower step, and no
    # shape goes below the lower step, nor any link below the terrain under it.
    from .test_collision_contacts import lowest_points, monoped

    path = monoped(tmp_path)
    path.write_text(path.read_text() + '[terrain]\nkind = "steps"\npositions = [0.2]\nheights = [-0.05]\n')
    ex = load_scene(path, ['integrator.method="dopri5"', "integrator.rtol=1e-8", "integrator.atol=1e-8"]).simulate()
    assert ex.status == "finished", ex.message
    assert any("trunk" in tr.target for tr in ex.transitions), [tr.target for tr in ex.transitions]
    assert min(lowest_points(path, ex).values()) >= -0.05 - 1e-4
    assert not [w for w in ex.warnings if w.kind in ("below_ground", "terrain_inside", "passed_through")]


def test_past_a_corner_the_ball_is_steered_back_onto_its_path_and_keeps_its_energy(tmp_path):
    # Past a corner's arc the steps leave an error in the velocity along the normal. Held at
    # d'' = 0 the centre would drift off the curve r from the terrain at a constant rate (2.3e-3 m
    # in 20 s at rtol 1e-6 over a 5 degree corner at 0.3 m/s, its energy up by 0.045 J); steered
    # back at ROUND_RETURN_RATE the error dies out: the centre is back on its path to rounding,
    # and the energy keeps to the size of the error at the corner.
    from legsim.heights import nearest
    from legsim.terrain import profile_terrain

    points = [[0.0, 0.0], [1000.0, -1000.0 * math.tan(math.radians(5.0))]]
    terrain = f'[terrain]\nkind = "profile"\npoints = {points}\n'
    extra = f'[initial]\nmode = "ball"\nstate = {{ x = -0.2, z = {BALL_R}, xd = 0.3, pitchd = 3.0 }}\n{terrain}'
    sets = ["integrator.t_final=5.0", "integrator.h=0.01", "robot.parameters.collision_contacts.friction=100.0"]
    method = ['integrator.method="dopri5"', "integrator.rtol=1e-6", "integrator.atol=1e-6"]
    ex = load_scene(ball(tmp_path, extra), [*sets, *method]).simulate()
    assert ex.status == "finished" and not ex.transitions, ex.message
    assert [w.kind for w in ex.warnings] == ["round_corner"]
    x = np.concatenate([s.x for s in ex.segments])
    array = profile_terrain(*zip(*points, strict=True)).array
    off = np.array([nearest(array, 0, a, b)[1] for a, b in x[:, :2]]) - BALL_R
    assert np.abs(off).max() < 1e-5 and abs(off[-1]) < 1e-12  # 6.3e-6 m at the corner
    energy = 0.5 * BALL_M * (x[:, 3] ** 2 + x[:, 4] ** 2) + 0.5 * BALL_I * x[:, 5] ** 2 + BALL_M * G * x[:, 1]
    assert abs(energy[-1] - energy[0]) < 1e-4


def test_a_ball_in_contact_off_its_path_is_reported_naming_it(tmp_path):
    # The safety net past the steering: a contact that lies off the curve r from the terrain by
    # more than eps + 1e-4 m while in contact is reported, naming it and the offset.
    points = [[0.0, 0.0], [1.0, -0.2]]
    terrain = f'[terrain]\nkind = "profile"\npoints = {points}\n'
    extra = f'[initial]\nmode = "ball"\nstate = {{ x = -0.5, z = {BALL_R} }}\n{terrain}'
    scene = load_scene(ball(tmp_path, extra), TIGHT)
    (watch,) = [w for w in scene.watches(None) if w.name == "round_drift"]
    states = np.zeros((3, 6))
    states[:, 0] = -0.5
    states[:, 1] = BALL_R + np.array([0.0, 5e-5, 2e-3])  # on its path, within, 2 mm above
    value = watch.value("ball", np.zeros(3), states)
    np.testing.assert_allclose(value[:, 0], 1e-10 + 1e-4 - np.array([0.0, 5e-5, 2e-3]), atol=1e-15)
    assert "'ball' is 0.002 m off the terrain" in watch.message(0.0, "ball", states[2])
    # in flight the contact is not held to the terrain
    assert np.all(watch.value("flight", np.zeros(3), states) > 0)


def test_the_terrain_top_that_ends_the_search_for_a_centre_far_up():
    # A round contact's centre more than 2 r above the terrain's highest point is far from the
    # ground, without a search over the pieces under it: the highest point of each kind.
    from legsim.terrain import flat_terrain, profile_terrain, sine_terrain, slope_terrain
    from legsim.terrain import top as terrain_top

    assert terrain_top(profile_terrain([0.0, 1.0, 2.0, 3.0], [0.1, 0.7, -0.2, 0.3]).array) == 0.7
    assert terrain_top(sine_terrain(0.05, 1.0, z0=0.2).array) == pytest.approx(0.25, abs=1e-15)
    assert terrain_top(flat_terrain(0.3).array) == 0.3
    assert terrain_top(slope_terrain(10.0).array) == math.inf and terrain_top(None) == math.inf


def test_a_dumbbell_landing_with_one_ball_in_a_notch_stops_the_run_naming_it(tmp_path):
    # A bar with a ball at each end, dropped level: the left ball lands in a 90 degree V (its
    # centre then r sqrt(2) above the bottom, 0.1 m down) at the very time the right one lands
    # on the ground beyond a step down, a joint landing of the two. The left ball strikes two
    # faces at once, which the impact law does not answer, joint or not: the run stops there,
    # where both balls touch.
    from .test_collision_contacts import link, shape, write

    spheres = "".join(shape("sphere", f'<sphere radius="{BALL_R}"/>', origin=f"{x} 0 0") for x in (-0.3, 0.3))
    centre = -0.1 + BALL_R * math.sqrt(2.0)
    points = [[-0.4, 0.0], [-0.3, -0.1], [-0.2, 0.0], [-0.1, 0.0], [-0.099, centre - BALL_R]]
    scene = (
        "collisions = true\ncollision_contacts = { friction = 100.0 }\n"
        f'[integrator]\nh = 1e-3\neps = 1e-10\nt_final = 0.5\nmethod = "dopri5"\nrtol = 1e-10\natol = 1e-10\n'
        f'[initial]\nstate = {{ z = 0.5 }}\n[terrain]\nkind = "profile"\npoints = {points}\n'
    )
    ex = load_scene(write(tmp_path, "dumbbell", link("bar", 2.0, 0.05, spheres), scene)).simulate()
    assert ex.status == "model_breakdown" and "notch" in ex.message, ex.message
    # its last state the last point stored before the strike: within a landing step of it
    assert not ex.transitions and ex.final_state[1] == pytest.approx(centre, abs=1e-6)
