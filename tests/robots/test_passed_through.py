"""An inactive contact carried through the ground by a coarse step (robots/bridge/guards.py,
``PastDepths`` and ``passed_through_watch``): a contact's guard ``max(height, dz/dt)`` is past
only while the point closes, so a step that takes a foot through the ground and leaves it rising
ends inside the domain. The run says so: a ``passed_through`` warning, or a stop under
``below_ground``, at the time the closed form gives, wherever in the step the foot dips.

The robot: a leg of length L on a hip fixed at height H < L, without gravity, swinging at a
constant rate w, so that its foot dips below the ground at the bottom of the swing: the angle is
linear in time, which rk4 and the watch's Hermite interpolant both follow exactly.
"""

import math

import numpy as np
import pytest
from legsim.robots.bridge.guards import THROUGH_DEPTH, PastDepths
from legsim.robots.watches import LinkHeights
from scipy.optimize import brentq, minimize_scalar

import legsim.relaxed.between as between
from legsim.relaxed.watches import refined
from legsim.scene import load_scene

from .test_collision_contacts import link, shape, write

L, H = 1.0, 0.9  # m: the leg's length and the hip's height
THETA0, RATE = -0.6, 10.0  # rad, rad/s: the foot 0.075 m up, swinging down
EPS = 1e-4  # m

LEG = (
    link("base", 1.0, 0.01)
    + link("leg", 1.0, 0.01, origin=f"0 0 {-L / 2}")
    + link("foot", 0.01, 1e-6)
    + f'<joint name="hip" type="revolute"><parent link="base"/><child link="leg"/><origin xyz="0 0 {H}"/>'
    '<axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="10" velocity="100"/></joint>'
    f'<joint name="ankle" type="fixed"><parent link="leg"/><child link="foot"/><origin xyz="0 0 {-L}"/></joint>'
)


def swing(folder, h, below_ground="warn", t_final=0.1, g=0.0):
    """The scene: the foot the leg's only contact, the run one rk4 step of h (s) or more."""
    scene = (
        f'root = "fixed"\ng = {g}\nbelow_ground = "{below_ground}"\n'
        'contacts = [{ name = "foot", frame = "foot", tangential = false }]\n'
        f"[initial]\nstate = {{ hip = {THETA0}, hipd = {RATE} }}\n"
        f'[integrator]\nmethod = "rk4"\nh = {h}\neps = {EPS}\nt_final = {t_final}\n'
    )
    return write(folder, "swing", LEG, scene)


def through_time():
    """When the foot, descending, first lies eps + THROUGH_DEPTH below the ground:
    L cos(theta) - H = eps + THROUGH_DEPTH, theta = THETA0 + RATE t < 0."""
    return (-math.acos((H + EPS + THROUGH_DEPTH) / L) - THETA0) / RATE


def test_a_step_through_the_ground_is_a_warning_at_the_closed_form_time(tmp_path):
    # One step of 0.1 s: theta from -0.6 to 0.4, the foot from 0.075 m up to 0.021 m below the
    # ground, rising; its guard never saw it.
    ex = load_scene(swing(tmp_path, 0.1)).simulate()
    assert ex.status == "finished" and not ex.transitions
    (warning,) = [w for w in ex.warnings if w.kind == "passed_through"]
    assert "'foot'" in warning.message and "below the ground" in warning.message
    assert warning.time == pytest.approx(through_time(), abs=1e-9)
    # The depth where it was deepest among the points checked (the stored ones and the step's
    # middle): the middle, theta = -0.1, L cos(0.1) - H.
    assert EPS + THROUGH_DEPTH - warning.details["least_value"] == pytest.approx(L * math.cos(0.1) - H, abs=1e-12)
    assert warning.details["least_time"] == pytest.approx(0.05, abs=1e-15)


@pytest.mark.parametrize("h", [0.12, 0.24])
@pytest.mark.parametrize(("action", "status"), [("warn", "finished"), ("strict", "model_breakdown")])
def test_a_step_through_the_ground_and_out_again_is_seen_wherever_it_dips(tmp_path, h, action, status):
    # The foot is 0.1 m below the ground at theta = 0, t = 0.06 s, and 0.075 m up at theta = -0.6
    # and 0.6. One step of 0.12 s puts that at the step's middle, where the check sees it; one
    # of 0.24 s at a quarter of the step, 0.075 m up at its start and its middle (and high at its
    # end), where no checked point shows it: the depth's rate, -vz of the foot, makes the cubic
    # through the start and the middle dip, and the interpolant there confirms it.
    ex = load_scene(swing(tmp_path, h, action, t_final=h)).simulate()
    assert ex.status == status and not ex.transitions
    if action == "warn":
        (warning,) = [w for w in ex.warnings if w.kind == "passed_through"]
        assert warning.time == pytest.approx(through_time(), abs=1e-9)
        # the deepest point seen: the middle, or the cubic's least, at theta = 0 since the depth
        # and its rate are symmetric about it over the half step
        assert EPS + THROUGH_DEPTH - warning.details["least_value"] == pytest.approx(L - H, abs=1e-12)
        assert warning.details["least_time"] == pytest.approx(0.06, abs=1e-12)
    else:
        assert "'foot'" in ex.message and ex.t_end == pytest.approx(through_time(), abs=1e-9)


# Under "fall" too the run stops with model_breakdown: a foot the steps carried through the ground
# is a missed touchdown, not a fall of the robot (a sweep's fell column would count it).
@pytest.mark.parametrize(("action", "status"), [("strict", "model_breakdown"), ("fall", "model_breakdown")])
def test_below_ground_stops_the_run_where_the_foot_passed_the_allowance(tmp_path, action, status):
    ex = load_scene(swing(tmp_path, 0.1, action)).simulate()
    assert ex.status == status and "'foot'" in ex.message and "below the ground" in ex.message
    assert ex.t_end == pytest.approx(through_time(), abs=1e-9)
    assert L * math.cos(ex.final_state[0]) - H == pytest.approx(EPS + THROUGH_DEPTH, abs=1e-9)


def test_small_steps_land_the_foot_where_it_meets_the_ground_and_say_nothing(tmp_path):
    # At h = 1e-3 the step that reaches the ground lands in the strip, where L cos(theta) = H:
    # the plastic impact stops the leg, and gravity holds the foot down. No warning. (Without
    # gravity the post-impact force is 0 and both outcomes' guards sit at 0 all the way down.)
    ex = load_scene(swing(tmp_path, 1e-3, g=9.81)).simulate()
    assert ex.status == "finished"
    assert [tr.name for tr in ex.transitions] == ["touchdown_foot"]
    assert ex.final_state[1] == pytest.approx(0.0, abs=1e-12)
    assert L * math.cos(ex.transitions[0].state_before[0]) - H == pytest.approx(0.0, abs=EPS)
    assert not [w for w in ex.warnings if w.kind == "passed_through"]


def test_a_link_dipping_between_every_checked_point_is_seen_by_its_speed(tmp_path):
    # The leg without a contact, a 2 mm box drawn at its end: the same step of 0.24 s carries the
    # box 0.1 m below the ground and out again at a quarter of the step. The links' watch reads
    # the lowest point's vertical speed and finds the dip between the checked points, at the time
    # the box's lowest corner (1 mm behind and below the leg's end) reaches the ground:
    # H - (L + 0.001) cos(theta) - 0.001 |sin(theta)| = 0, theta < 0.
    box = f'<visual><origin xyz="0 0 {-L}"/><geometry><box size="0.002 0.002 0.002"/></geometry></visual>'
    leg = LEG.replace(
        link("leg", 1.0, 0.01, origin=f"0 0 {-L / 2}"), link("leg", 1.0, 0.01, visual=box, origin=f"0 0 {-L / 2}")
    )
    scene = (
        'root = "fixed"\ng = 0.0\ncontacts = []\n'
        f"[initial]\nstate = {{ hip = {THETA0}, hipd = {RATE} }}\n"
        f'[integrator]\nmethod = "rk4"\nh = 0.24\neps = {EPS}\nt_final = 0.24\n'
    )
    ex = load_scene(write(tmp_path, "swing", leg, scene)).simulate()
    (warning,) = [w for w in ex.warnings if w.kind == "below_ground"]
    assert "'leg'" in warning.message
    theta = brentq(lambda a: H - (L + 0.001) * math.cos(a) - 0.001 * abs(math.sin(a)), THETA0, 0.0, xtol=1e-15)
    assert warning.time == pytest.approx((theta - THETA0) / RATE, abs=1e-9)


def test_a_round_foot_dipping_through_a_sine_between_every_checked_point_is_seen(tmp_path):
    # A 2 cm sphere at the leg's end, its contact from the collision, over a sine (amplitude
    # 5 cm, wavelength 1 m): the same step of 0.24 s takes its centre 0.1 m below the crest's
    # side at a quarter of the step and back up; no checked point shows it. Its depth's rate, the
    # centre's speed along the curve's normal at its nearest point, finds it where the centre
    # first lies r - eps - THROUGH_DEPTH from the curve (the distance minimised over the curve).
    radius, amplitude = 0.02, 0.05
    sphere = shape("sphere", f'<sphere radius="{radius}"/>', origin=f"0 0 {-L}")
    leg = LEG.replace(
        link("leg", 1.0, 0.01, origin=f"0 0 {-L / 2}"), link("leg", 1.0, 0.01, sphere, origin=f"0 0 {-L / 2}")
    )
    scene = (
        'root = "fixed"\ng = 0.0\ncollisions = true\n'
        f"[initial]\nstate = {{ hip = {THETA0}, hipd = {RATE} }}\n"
        f'[integrator]\nmethod = "rk4"\nh = 0.24\neps = {EPS}\nt_final = 0.24\n'
        f'[terrain]\nkind = "sine"\namplitude = {amplitude}\nwavelength = 1.0\n'
    )
    ex = load_scene(write(tmp_path, "swing", leg, scene)).simulate()
    assert ex.status == "finished" and not ex.transitions
    (warning,) = [w for w in ex.warnings if w.kind == "passed_through"]

    def past(t):
        theta = THETA0 + RATE * t
        xc, zc = -L * math.sin(theta), H - L * math.cos(theta)
        curve = lambda s: math.hypot(s - xc, amplitude * math.sin(2 * math.pi * s) - zc)  # noqa: E731
        closest = minimize_scalar(curve, bounds=(xc - 0.3, xc + 0.3), method="bounded", options={"xatol": 1e-13})
        distance = math.copysign(closest.fun, zc - amplitude * math.sin(2 * math.pi * xc))
        return radius - distance - (EPS + THROUGH_DEPTH)

    assert warning.time == pytest.approx(brentq(past, 0.0, 0.06, xtol=1e-14), abs=1e-8)


# Over a step: the hip 5 cm higher, so the foot clears the level ground, and the ground 10 cm higher
# behind x = -0.2 (the foot swings towards -x), its riser a ramp 1 mm long. Swinging up past the
# riser's foot at 7 cm, the foot passes through the riser and leaves the tread 3 cm higher up; at
# the checked points (theta = -0.6, 0, 0.6: the foot at x = 0.56, 0, -0.56) it is above the ground,
# and the cubic through its depths at them does not dip (the treads are level). Where the ground
# under the foot changes from one segment of the profile to the next, the check looks at both sides.
STEP_HIP, STEP_AT, STEP_RISE, RISER = 1.05, -0.2, 0.1, 1e-3


def over_a_step(
    folder,
    h,
    below_ground="warn",
    leg=LEG,
    collisions='contacts = [{ name = "foot", frame = "foot", tangential = false }]',
    t_final=0.12,
):
    scene = (
        f'root = "fixed"\ng = 0.0\nbelow_ground = "{below_ground}"\n{collisions}\n'
        f"[initial]\nstate = {{ hip = {THETA0}, hipd = {RATE} }}\n"
        f'[integrator]\nmethod = "rk4"\nh = {h}\neps = {EPS}\nt_final = {t_final}\n'
        f'[terrain]\nkind = "steps"\npositions = [{STEP_AT}]\nheights = [0.0]\nbase = {STEP_RISE}\nriser = {RISER}\n'
    )
    return write(folder, "swing", leg.replace(f'xyz="0 0 {H}"', f'xyz="0 0 {STEP_HIP}"'), scene)


def ground_under(x):
    """The steps' height (m) at x: STEP_RISE behind the riser, 0 ahead of it, linear on it."""
    return STEP_RISE * min(1.0, max(0.0, (STEP_AT - x) / RISER))


def first_below(heights, low=0.0, high=0.6):
    """The first angle where the least of ``heights(theta)`` reaches 0: a 60,000-point scan
    brackets it, brentq finds it (the heights are continuous: the steps' riser is a ramp)."""
    grid = np.linspace(low, high, 60_001)
    k = int(np.argmax([min(heights(a)) < 0.0 for a in grid]))
    return brentq(lambda a: min(heights(a)), grid[k - 1], grid[k], xtol=1e-15)


def test_without_the_terrain_s_segments_the_riser_is_not_seen(tmp_path, monkeypatch):
    # The premise of the two tests below: the foot is above the ground at every checked point and
    # the cubics through them do not dip, so only the change of segment under the foot shows it.
    # (The cubic's misfit at the step's middle is switched off too: where the segment changes the
    # check searches by the segments alone, and elsewhere the misfit may show the kink as well.)
    monkeypatch.setattr(PastDepths, "cornered", property(lambda self: False))
    monkeypatch.setattr(between, "cubic_misfits", lambda t, v, r, unsmooth: np.zeros(unsmooth.shape))
    ex = load_scene(over_a_step(tmp_path, 0.12)).simulate()
    assert ex.status == "finished" and not [w for w in ex.warnings if w.kind == "passed_through"]


@pytest.mark.parametrize(("action", "status"), [("warn", "finished"), ("strict", "model_breakdown")])
def test_a_foot_carried_through_a_riser_inside_a_step_is_seen(tmp_path, action, status):
    ex = load_scene(over_a_step(tmp_path, 0.12, action)).simulate()
    assert ex.status == status and not ex.transitions
    # where the foot first lies eps + THROUGH_DEPTH below the ground under it, on the riser
    theta = first_below(lambda a: [STEP_HIP - L * math.cos(a) - ground_under(-L * math.sin(a)) + EPS + THROUGH_DEPTH])
    assert math.asin(-STEP_AT / L) < theta < math.asin((RISER - STEP_AT) / L)
    if action == "warn":
        (warning,) = [w for w in ex.warnings if w.kind == "passed_through"]
        assert "'foot'" in warning.message and warning.time == pytest.approx((theta - THETA0) / RATE, abs=1e-9)
    else:
        assert "'foot'" in ex.message and ex.t_end == pytest.approx((theta - THETA0) / RATE, abs=1e-9)


#: The leg without a contact, a 2 mm box drawn at its end.
BOX_LEG = LEG.replace(
    link("leg", 1.0, 0.01, origin=f"0 0 {-L / 2}"),
    link(
        "leg",
        1.0,
        0.01,
        visual=f'<visual><origin xyz="0 0 {-L}"/><geometry><box size="0.002 0.002 0.002"/></geometry></visual>',
        origin=f"0 0 {-L / 2}",
    ),
)


def test_a_link_carried_through_a_riser_inside_a_step_is_seen(tmp_path):
    # The box's corners (+-1 mm along the leg and across it) go through the riser the same way.
    # The links' watch sees it where the first corner reaches the ground under it.
    ex = load_scene(over_a_step(tmp_path, 0.12, leg=BOX_LEG, collisions="contacts = []")).simulate()
    (warning,) = [w for w in ex.warnings if w.kind == "below_ground"]
    assert "'leg'" in warning.message

    def corners(a):  # a point (u, w) of the leg's frame at angle a: (u cos a + w sin a, hip - u sin a + w cos a)
        points = [(u, -L + w) for u in (-0.001, 0.001) for w in (-0.001, 0.001)]
        return [STEP_HIP - u * math.sin(a) + w * math.cos(a) - ground_under(u * math.cos(a) + w * math.sin(a))
                for u, w in points]  # fmt: skip

    theta = first_below(corners)
    assert warning.time == pytest.approx((theta - THETA0) / RATE, abs=1e-9)


def test_a_link_point_ruled_clear_between_two_checked_points_stays_above_the_ground(tmp_path):
    # The links' watch skips a change of segment where a point stays above the highest ground
    # under the x it sweeps (``LinkHeights.clear``, on the cubics of its height and x). Over a
    # whole turn of the leg (steps of 0.02 s), wherever it rules a stretch between two checked
    # points clear, every point's height above the ground under it stays positive on the
    # interpolant there (400 samples a stretch); and it rules some clear and some not.
    scene = load_scene(over_a_step(tmp_path, 0.02, leg=BOX_LEG, collisions="contacts = []", t_final=0.62))
    watch = next(w for w in scene.model.info["watches"](None, EPS) if w.name == "below_ground")
    ex = scene.simulate()
    (segment,) = ex.segments
    t, x = refined(segment.t, segment.x, segment.dx)
    cleared = watch.clear(segment.mode, t[:-1], x[:-1], t[1:], x[1:])
    assert cleared.any() and not cleared.all()
    for j, k in zip(*np.nonzero(cleared), strict=True):
        times = np.linspace(t[j], t[j + 1], 400)
        assert watch.parts(segment.mode, times, segment.interpolate(times))[:, k].min() > 0.0


# A foot whose x turns past a riser's corner and back between two checked points: the ground 20 cm
# higher behind x = -0.32 (the riser a 1 mm ramp), the hip 1.05 m up. The foot starts under the hip,
# 5 cm up, swinging towards -x at 5 rad/s against a constant torque (the PD saturated at the hip's
# effort limit, 10 N m), so that the angle is quadratic in time, which rk4 and the interpolant follow
# exactly. It turns at 0.34 rad (x = -0.33, 0.11 m up) at t = 0.135 s and lies past the corner, 9 cm
# inside the tread, for 0.05 s around the turn. One step of 0.4 s checks it at t = 0, 0.2 and 0.4:
# ahead of the riser, above the ground each time, on one segment of the profile, and the cubic through
# its depths does not dip. The watch's probe, the time of the foot's farthest x on the cubic of its x,
# finds it on the next segment, and the way out and back are searched across the change.
TURN_HIP, TURN_AT, TURN_RISE, TURN_RATE = 1.05, -0.32, 0.2, 5.0


def turning_past_a_corner(folder, below_ground="warn", leg=LEG, contacts='[{ name = "foot", frame = "foot" }]'):
    scene = (
        f'root = "fixed"\ng = 0.0\nactuated = ["hip"]\nbelow_ground = "{below_ground}"\ncontacts = {contacts}\n'
        '[controller]\nname = "joint_pd"\n[controller.parameters]\nkp = 1000.0\nkd = 0.0\ntargets = [-3.0]\n'
        f"[initial]\nstate = {{ hip = 0.0, hipd = {TURN_RATE} }}\n"
        f'[integrator]\nmethod = "rk4"\nh = 0.4\neps = {EPS}\nt_final = 0.4\n'
        f'[terrain]\nkind = "steps"\npositions = [{TURN_AT}]\nheights = [0.0]\nbase = {TURN_RISE}\nriser = {RISER}\n'
    )
    return write(folder, "turn", leg.replace(f'xyz="0 0 {H}"', f'xyz="0 0 {TURN_HIP}"'), scene)


def turning_reference(ex, heights):
    """The first time the least of ``heights(theta)`` reaches 0 on the way out, theta = w t + a t^2 / 2,
    a the (constant) angular acceleration of the run's field; and the angle of the turn."""
    (segment,) = ex.segments
    accelerations = segment.dx[:, 1]
    assert np.ptp(accelerations) < 1e-9 * abs(accelerations[0])  # the torque saturated throughout
    a = float(accelerations[0])
    turn = -(TURN_RATE**2) / (2 * a)
    theta = first_below(heights, 0.0, turn)
    return (-TURN_RATE + math.sqrt(TURN_RATE**2 + 2 * a * theta)) / a, turn


def turning_ground(x):
    return TURN_RISE * min(1.0, max(0.0, (TURN_AT - x) / RISER))


@pytest.mark.parametrize(("action", "status"), [("warn", "finished"), ("strict", "model_breakdown")])
def test_a_foot_turning_past_a_corner_and_back_inside_a_step_is_seen(tmp_path, action, status):
    ex = load_scene(turning_past_a_corner(tmp_path, action)).simulate()
    assert ex.status == status and not ex.transitions
    depth = lambda a: [TURN_HIP - L * math.cos(a) - turning_ground(-L * math.sin(a)) + EPS + THROUGH_DEPTH]  # noqa: E731
    when, turn = turning_reference(ex, depth)
    assert -L * math.sin(turn) < TURN_AT and depth(turn)[0] < -0.05  # at the turn: past the corner, in the tread
    if action == "warn":
        # the premise: at the checked points (t = 0, 0.2, 0.4) it is ahead of the corner, above the ground
        (segment,) = ex.segments
        checked = refined(segment.t, segment.x, segment.dx)[1][:, 0]
        assert checked.shape == (3,)
        assert all(depth(a)[0] > 0.0 and -L * math.sin(a) > TURN_AT for a in checked)
        (warning,) = [w for w in ex.warnings if w.kind == "passed_through"]
        assert "'foot'" in warning.message and warning.time == pytest.approx(when, abs=1e-9)
    else:
        assert "'foot'" in ex.message and ex.t_end == pytest.approx(when, abs=1e-9)


def test_without_the_probe_a_foot_turning_past_a_corner_is_not_seen(tmp_path, monkeypatch):
    # the premise of the test above: no checked point and no change of segment between them shows it
    monkeypatch.setattr(PastDepths, "turns", lambda self, mode, t, states: np.full((len(t) - 1, 1), np.nan))
    ex = load_scene(turning_past_a_corner(tmp_path)).simulate()
    assert ex.status == "finished" and not [w for w in ex.warnings if w.kind == "passed_through"]


@pytest.mark.parametrize("probed", [True, False])
def test_a_link_turning_past_a_corner_and_back_inside_a_step_is_seen(tmp_path, monkeypatch, probed):
    # The leg without a contact, the 2 mm box at its end, turning the same way: the links' watch
    # sees it where the box's first corner reaches the ground under it; without the probe it does not.
    if not probed:
        no_turns = lambda self, t, states: np.full((len(t) - 1, self.owner.size), np.nan)  # noqa: E731
        monkeypatch.setattr(LinkHeights, "turns", no_turns)
    ex = load_scene(turning_past_a_corner(tmp_path, leg=BOX_LEG, contacts="[]")).simulate()
    below = [w for w in ex.warnings if w.kind == "below_ground"]
    if not probed:
        assert ex.status == "finished" and not below
        return

    def corners(a):  # as in test_a_link_carried_through_a_riser_inside_a_step_is_seen
        points = [(u, -L + w) for u in (-0.001, 0.001) for w in (-0.001, 0.001)]
        return [TURN_HIP - u * math.sin(a) + w * math.cos(a) - turning_ground(u * math.cos(a) + w * math.sin(a))
                for u, w in points]  # fmt: skip

    (warning,) = below
    assert "'leg'" in warning.message
    assert warning.time == pytest.approx(turning_reference(ex, corners)[0], abs=1e-9)
