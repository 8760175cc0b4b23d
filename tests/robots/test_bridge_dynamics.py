"""The contact-mode bridge on small models with closed forms: point-contact impacts and release,
KKT dynamics and impacts against Pinocchio's own solvers, lazy modes, bad input."""

import math

import numpy as np
import pinocchio as pin
import pytest

from legsim import ModelError, SceneError, simulate
from legsim.robots import pronk
from legsim.robots.bridge import ContactBridge, JointStop, PointContact, SpringLeg, add_point_frame, planar_floating_base

G = 9.81


def ball_model(m=1.0):
    model = pin.Model()
    jx = model.addJoint(0, pin.JointModelPX(), pin.SE3.Identity(), "x")
    jz = model.addJoint(jx, pin.JointModelPZ(), pin.SE3.Identity(), "z")
    model.appendBodyToJoint(jz, pin.Inertia(m, np.zeros(3), np.zeros((3, 3))), pin.SE3.Identity())
    add_point_frame(model, "ball", jz, (0, 0, 0))
    return model, jz


def rod_model(m=1.0, I=0.3, L=1.0):
    model = pin.Model()
    body = planar_floating_base(model)
    model.appendBodyToJoint(body, pin.Inertia(m, np.zeros(3), np.diag([I, I, I])), pin.SE3.Identity())
    add_point_frame(model, "tip", body, (L / 2, 0, 0))
    return model


def test_bouncing_point_is_the_closed_form_ball():
    c, z0 = 0.5, 1.0
    model, _ = ball_model()
    bridge = ContactBridge(model, [PointContact("floor", "ball", restitution=c, tangential=False)])
    system = bridge.system("free", [0.0, z0, 0.0, 0.0])
    assert [(tr.name, tr.target) for tr in system.outgoing("free")] == [("bounce_floor", "free")]
    t_zeno = math.sqrt(2 * z0 / G) * (1 + 2 * c / (1 - c))
    eps = 1e-3
    ex = simulate(system, [0.3, z0, 0.0, 0.0], "free", 2 * t_zeno, 1e-3, eps)
    assert ex.status == "finished"
    first = ex.transitions[0]
    assert first.time == pytest.approx(math.sqrt(2 * z0 / G), abs=1e-12)  # free fall: RK4 + Hermite exact
    assert first.state_after[3] == pytest.approx(-c * first.state_before[3], rel=1e-14)
    assert first.state_after[2] == first.state_before[2] == 0.0
    assert min(seg.x[:, 1].min() for seg in ex.segments) >= -eps
    assert len(ex.transitions) < 20_000


def test_point_contact_holds_a_base_until_the_swinging_pendulum_lifts_it():
    """A base (mass M on PX, PZ) on the ground carries a pendulum (bob m at L) swung over the top.
    With the base held, the bob is a simple pendulum: T = m g cos(phi) + m L phi'^2 and the
    ground holds it with (-T sin(phi), N = M g + T cos(phi)); N first vanishes at the root of
    3 m g c^2 + m (L w0^2 - 2 g) c + M g = 0, c = cos(phi), for a swing from phi = 0 at w0."""
    M, m, L, w0 = 0.2, 1.0, 1.0, 7.0
    model = pin.Model()
    jx = model.addJoint(0, pin.JointModelPX(), pin.SE3.Identity(), "x")
    jz = model.addJoint(jx, pin.JointModelPZ(), pin.SE3.Identity(), "z")
    model.appendBodyToJoint(jz, pin.Inertia(M, np.zeros(3), np.zeros((3, 3))), pin.SE3.Identity())
    jp = model.addJoint(jz, pin.JointModelRY(), pin.SE3(pin.utils.rotate("z", math.pi), np.zeros(3)), "phi")
    model.appendBodyToJoint(jp, pin.Inertia(m, np.array([0, 0, -L]), np.zeros((3, 3))), pin.SE3.Identity())
    add_point_frame(model, "base", jz, (0, 0, 0))
    model.gravity = pin.Motion(np.array([0, 0, -G, 0, 0, 0]))
    bridge = ContactBridge(model, [PointContact("foot", "base")], mode_names={(): "air", ("foot",): "ground"})
    x0 = [0.0, 0.0, 0.0, 0.0, 0.0, w0]
    system = bridge.system("ground", x0)
    for phi, w in [(0.3, 6.0), (2.0, 3.0)]:
        x = np.array([0, 0, phi, 0, 0, w])
        T = m * G * math.cos(phi) + m * L * w**2
        np.testing.assert_allclose(bridge.constraint_forces("ground", x)["foot"],
                                   [-T * math.sin(phi), M * G + T * math.cos(phi)], atol=1e-12)
    ex = simulate(system, x0, "ground", 1.0, 1e-3, 1e-3)
    lift = ex.transitions[0]
    assert lift.name == "liftoff_foot" and lift.target == "air"
    roots = np.roots([3 * m * G, m * (L * w0**2 - 2 * G), M * G])
    c = max(roots.real)  # phi grows from 0, cos(phi) falls from 1: the larger root comes first
    assert math.cos(lift.state_before[2]) == pytest.approx(c, abs=1e-8)
    ground = [seg for seg in ex.segments if seg.mode == "ground"][0]
    assert np.abs(ground.x[:, [0, 1, 3, 4]]).max() < 1e-12  # the contact held the base still


@pytest.mark.parametrize("tangential", [True, False])
def test_kkt_dynamics_and_impact_equal_pinocchio_solvers(tangential):
    model = rod_model()
    model.gravity = pin.Motion(np.array([0, 0, -G, 0, 0, 0]))
    bridge = ContactBridge(model, [PointContact("tip", "tip", tangential=tangential)])
    pm, pd = bridge.model, bridge.model.createData()
    fid = pm.getFrameId("tip")
    rng = np.random.default_rng(0)
    for _ in range(5):
        q, v = rng.normal(size=3), rng.normal(size=3)
        x = np.concatenate([q, v])
        J6 = pin.computeFrameJacobian(pm, pd, q, fid, pin.LOCAL_WORLD_ALIGNED)
        pin.forwardKinematics(pm, pd, q, v, np.zeros(3))
        acc = pin.getFrameClassicalAcceleration(pm, pd, fid, pin.LOCAL_WORLD_ALIGNED).linear
        rows = [0, 2] if tangential else [2]
        J, gamma = J6[rows], acc[rows]  # the tip's Jacobian and its drift dJ/dt v
        a = pin.forwardDynamics(pm, pd, q, v, np.zeros(3), J, gamma)
        np.testing.assert_allclose(bridge.field("tip")(0.0, x, None)[3:], a, atol=1e-10)
        np.testing.assert_allclose(bridge.constraint_forces("tip", x)["tip"], pd.lambda_c, atol=1e-10)
        for c in (0.0, 0.4):
            v_after = pin.impulseDynamics(pm, pd, q, v, J, c)
            np.testing.assert_allclose(bridge.impact_velocity([("tip", c)], q, v), v_after, atol=1e-12)
            np.testing.assert_allclose(J @ bridge.impact_velocity([("tip", c)], q, v), -c * (J @ v), atol=1e-12)


def test_many_contacts_build_only_the_modes_reached():
    model = rod_model()
    body = model.getJointId("theta")
    names = []
    for i in range(12):  # a rimless wheel's spokes: 2^12 contact subsets
        a = 2 * math.pi * i / 12
        add_point_frame(model, f"spoke{i}", body, (math.sin(a), 0, -math.cos(a)))
        names.append(f"s{i}")
    bridge = ContactBridge(model, [PointContact(n, f"spoke{i}") for i, n in enumerate(names)])
    system = bridge.system("free", [0, 2.0, 0, 0, 0, 0])
    # the initial mode and the targets of its transitions, nothing else
    assert sorted(system.modes) == sorted(["free"] + names)
    assert system.mode("s0+s6").dim == 6 and "s0+s6" in system.modes and len(system.modes) == 14
    assert bridge.active_contacts("s0+s6") == ("s0", "s6")
    with pytest.raises(ModelError, match="is called 's0\\+s6'"):
        system.mode("s6+s0")
    with pytest.raises(ModelError, match="'wheel' is not a mode"):
        system.mode("wheel")


def test_spring_leg_and_joint_stop_resets_change_the_state_dimension():
    model = pronk.make()
    system = model.system
    td = [tr for tr in system.outgoing("aerial") if tr.name == "touchdown_left"][0]
    x = pronk.state({"z": math.cos(math.pi / 5)})
    after = td.reset(x)
    assert after.shape == (7,) and after[6] == pytest.approx(-0.5 + math.sin(math.pi / 5), abs=1e-12)
    lo = [tr for tr in system.outgoing("left") if tr.name == "liftoff_left"][0]
    np.testing.assert_array_equal(lo.reset(after), x)


def test_actuation_adds_the_control_to_the_actuated_joints():
    model, _ = ball_model(m=2.0)
    model.gravity = pin.Motion(np.array([0, 0, -G, 0, 0, 0]))
    bridge = ContactBridge(model, [], actuated=("z",))
    f = bridge.field("free")
    np.testing.assert_allclose(f(0.0, np.zeros(4), None), [0, 0, 0, -G])
    np.testing.assert_allclose(f(0.0, np.zeros(4), [5.0]), [0, 0, 0, 5.0 / 2.0 - G])
    assert bridge.counters()["actuation_evals"] == 1
    with pytest.raises(ModelError, match="control u has 2 entries, the robot has 1 actuated"):
        f(0.0, np.ones(4), [1.0, 2.0])


def test_bad_models_and_contacts_are_named():
    model, _ = ball_model()
    with pytest.raises(ModelError, match="unknown frame 'nope'"):
        ContactBridge(model, [PointContact("foot", "nope")])
    with pytest.raises(ModelError, match="duplicate contact name 'foot'"):
        ContactBridge(model, [PointContact("foot", "ball"), PointContact("foot", "ball")])
    with pytest.raises(ModelError, match="contact 'foot': restitution must be <= 1"):
        ContactBridge(model, [PointContact("foot", "ball", restitution=1.5)])
    with pytest.raises(ModelError, match="contact 'leg': stiffness must be > 0"):
        ContactBridge(model, [SpringLeg("leg", "ball", stiffness=0.0, rest_length=1.0)])
    with pytest.raises(ModelError, match="contact 'stop': unknown joint 'elbow'"):
        ContactBridge(model, [JointStop("stop", "elbow")])
    with pytest.raises(ModelError, match="side must be 'lower' or 'upper'"):
        ContactBridge(model, [JointStop("stop", "z", side="left")])
    with pytest.raises(ModelError, match="releases unknown contact 'heel'"):
        ContactBridge(model, [PointContact("toe", "ball", releases=("heel",))])
    with pytest.raises(ModelError, match="contacts must be PointContact, JointStop or SpringLeg"):
        ContactBridge(model, ["foot"])
    with pytest.raises(ModelError, match="mode_names names unknown contact"):
        ContactBridge(model, [], mode_names={("foot",): "stance"})
    unbounded = pin.Model()
    unbounded.addJoint(0, pin.JointModelRUBY(), pin.SE3.Identity(), "wheel")
    with pytest.raises(ModelError, match="nq == model.nv"):
        ContactBridge(unbounded)
    with pytest.raises(ModelError, match="pinocchio.Model"):
        ContactBridge("robot.urdf")
    # builder parameters are checked before anything is built
    with pytest.raises(SceneError, match=r"robot.parameters.k: -1.0 is out of range"):
        pronk.make({"k": -1.0})


def test_release_under_a_time_varying_control_is_located_exactly():
    """A point mass resting on the floor is lifted by an actuator force u = F t: the floor force
    m g - F t vanishes at t* = m g / F. The release guard of an actuated robot is declared on
    (t, x, u), so the crossing search evaluates the force with the control at each interpolated
    time (with the control of the last field evaluation it would be found O(h) early)."""
    model, _ = ball_model()
    model.gravity = pin.Motion(np.array([0, 0, -G, 0, 0, 0]))
    bridge = ContactBridge(model, [PointContact("floor", "ball", tangential=False)], actuated=("z",))
    F = 2.9
    ex = simulate(bridge.system(), np.zeros(4), "floor", 5.0, 1e-3, 1e-3, control=lambda t, x: np.array([F * t]))
    assert ex.transitions[0].name == "liftoff_floor"
    assert ex.transitions[0].time == pytest.approx(G / F, abs=1e-9)


def test_a_striking_contact_releases_the_ones_it_names():
    """Two spokes of a wheel: spoke b striking (c = 0) releases spoke a, as a walker's heel
    strike releases its stance foot; both are declared in either order."""
    model = rod_model()
    body = model.getJointId("theta")
    add_point_frame(model, "end_b", body, (-0.5, 0, 0))
    contacts = [PointContact("a", "tip", releases=("b",)), PointContact("b", "end_b", releases=("a",))]
    bridge = ContactBridge(model, contacts)
    system = bridge.system("a", [0.0, math.sin(0.3) * 0.5, -0.3, 0.0, 0.0, 0.0])
    assert {(tr.name, tr.target) for tr in system.outgoing("a")} == {
        ("liftoff_a", "free"), ("touchdown_b", "b"), ("graze_b", "free")}
    # the impact solves only the striking contact: the released one may move
    q, v = np.array([0.0, 0.0, 0.0]), np.array([0.0, -1.0, 0.5])
    reset = [tr for tr in system.outgoing("a") if tr.name == "touchdown_b"][0].reset
    v_after = reset(np.concatenate([q, v]))[3:]
    np.testing.assert_allclose(v_after, bridge.impact_velocity([("b", 0.0)], q, v), atol=1e-15)
    with pytest.raises(ModelError, match="releases must be a tuple of contact names"):
        ContactBridge(rod_model(), [PointContact("a", "tip", releases="b")])


def test_a_rod_landing_on_a_frictionless_floor_ends_lying_with_its_weight_shared():
    """Both ends land plastically (c = 0, z only): no horizontal impulse ever acts, so the
    horizontal momentum is kept; at rest on both ends each carries m g / 2 and the energy left
    is the sliding m xd^2 / 2."""
    m, xd = 1.0, 0.5
    model = rod_model(m=m, I=0.1)
    model.gravity = pin.Motion(np.array([0, 0, -G, 0, 0, 0]))
    body = model.getJointId("theta")
    add_point_frame(model, "tail", body, (-0.5, 0, 0))
    bridge = ContactBridge(model, [PointContact("a", "tip", tangential=False),
                                   PointContact("b", "tail", tangential=False)], mode_names={(): "air"})
    x0 = [0.0, 1.0, 0.3, xd, 0.0, 0.0]
    system = bridge.system("air", x0)
    ex = simulate(system, x0, "air", 1.5, 1e-3, 1e-3)
    assert [tr.name for tr in ex.transitions] == ["touchdown_a", "touchdown_b"] and ex.final_mode == "a+b"
    x = ex.final_state
    np.testing.assert_allclose(x[3:], [xd, 0.0, 0.0], atol=1e-9)
    forces = bridge.constraint_forces("a+b", x)
    assert forces["a"][0] == pytest.approx(m * G / 2, abs=1e-9) and forces["b"][0] == pytest.approx(m * G / 2, abs=1e-9)
    assert system.energy("a+b", x) == pytest.approx(0.5 * m * xd**2, abs=1e-9)
    # the constraint is kept at the acceleration level; the ends stay on the floor to RK4 accuracy
    assert abs(x[1]) < 1e-9 and abs(x[2]) < 1e-9


def test_an_armed_contact_lands_only_where_it_is_armed():
    """The floor only counts for x >= 1 m (armed = x - 1). A ball thrown from x = 0 comes back to
    z = 0 at x = 1.22 m, armed: it lands at the ballistic time. Below the floor at x = 0.5, not
    armed, the guard is 0.5 (inside the domain)."""
    model, _ = ball_model()
    model.gravity = pin.Motion(np.array([0, 0, -G, 0, 0, 0]))
    floor = PointContact("floor", "ball", restitution=0.5, tangential=False, armed=lambda q, v: q[0] - 1.0)
    bridge = ContactBridge(model, [floor])
    x0 = [0.0, 0.0, 2.0, 3.0]  # flight time 2 * 3 / g = 0.61 s, landing at x = 1.22 m
    ex = simulate(bridge.system("free", x0), x0, "free", 0.7, 1e-3, 1e-3)
    assert ex.transitions[0].time == pytest.approx(2 * 3.0 / G, abs=1e-12)
    np.testing.assert_allclose(bridge.system().guard_values("free", np.array([0.5, -0.1, 2.0, -1.0])), [0.5])
    with pytest.raises(ModelError, match="armed must be callable"):
        ContactBridge(model, [PointContact("floor", "ball", armed=1.0)])


def test_initial_check_measures_a_point_below_the_ground_and_a_stop_from_its_side():
    # The rod's tip at (L/2) from the base, pitched by theta about +y: its height is
    # z - (L/2) sin(theta) (RY turns +x towards -z); ground at 0.2 m.
    model = rod_model(L=1.0)
    bridge = ContactBridge(model, [PointContact("tip", "tip", ground=0.2)], mode_names={(): "air"})
    check = bridge.initial_check()
    theta = 0.5
    depth = 0.2 - (0.1 - 0.5 * math.sin(theta))
    msg = check("air", np.array([0.0, 0.1, theta, 0, 0, 0]), 0.01)
    assert msg is not None and "'tip'" in msg and f"by {depth:.3g} >" in msg
    assert check("air", np.array([0.0, 0.1, theta, 0, 0, 0]), depth * 1.001) is None
    assert check("tip", np.array([0.0, 0.1, theta, 0, 0, 0]), 0.01) is None  # active: on the ground
    # An upper stop at 0.3 m on z: the domain is z <= 0.3.
    ball, _ = ball_model()
    stop = ContactBridge(ball, [JointStop("lid", "z", position=0.3, side="upper")], mode_names={(): "free"})
    msg = stop.initial_check()("free", np.array([0.0, 0.8, 0.0, -1.0]), 0.1)
    assert msg is not None and "upper stop 'lid'" in msg and "by 0.5 >" in msg
    assert stop.initial_check()("free", np.array([0.0, -5.0, 0.0, 0.0]), 0.1) is None
