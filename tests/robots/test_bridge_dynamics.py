"""Dynamics of the bridge on small models with closed forms: constraint forces of a held
base, KKT dynamics and impacts against Pinocchio's own solvers, actuation."""

import math

import numpy as np
import pinocchio as pin
import pytest
from legsim.robots.bridge import ContactBridge, PointContact, add_point_frame

from helpers.bridge_models import G, ball_model, rod_model
from legsim import simulate


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
        np.testing.assert_allclose(
            bridge.constraint_forces("ground", x)["foot"], [-T * math.sin(phi), M * G + T * math.cos(phi)], atol=1e-12
        )
    ex = simulate(system, x0, "ground", 1.0, 1e-3, 1e-3)
    lift = ex.transitions[0]
    assert lift.name == "liftoff_foot" and lift.target == "air"
    roots = np.roots([3 * m * G, m * (L * w0**2 - 2 * G), M * G])
    c = max(roots.real)  # phi grows from 0, cos(phi) falls from 1: the larger root comes first
    assert math.cos(lift.state_before[2]) == pytest.approx(c, abs=1e-8)
    ground = next(seg for seg in ex.segments if seg.mode == "ground")
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


def test_actuation_adds_the_control_to_the_actuated_joints():
    model, _ = ball_model(m=2.0)
    model.gravity = pin.Motion(np.array([0, 0, -G, 0, 0, 0]))
    bridge = ContactBridge(model, [], actuated=("z",))
    f = bridge.field("free")
    np.testing.assert_allclose(f(0.0, np.zeros(4), None), [0, 0, 0, -G])
    np.testing.assert_allclose(f(0.0, np.zeros(4), [5.0]), [0, 0, 0, 5.0 / 2.0 - G])
    assert bridge.counters()["actuation_evals"] == 2  # without input the actuated joints get 0
    assert bridge.mode("free").functions.inputs == 1
    unactuated = ContactBridge(model, [])
    unactuated.field("free")(0.0, np.zeros(4), None)
    assert unactuated.counters()["actuation_evals"] == 0


@pytest.mark.parametrize("tangential", [True, False])
def test_contact_dynamics_do_not_depend_on_where_the_robot_is(tangential):
    """Moving the whole robot moves no acceleration, contact force or impact: the field, the
    constraint forces and the impact velocity at x + 1000 m are those at x, to the bit. (The
    constrained solve's articulated-body pass expresses every inertia at the world's origin, so
    it runs with the robot's translations at 0: computed where the robot is, its rounding grows
    with the square of the distance, 1e-8 of an acceleration of 50 m/s^2 at 1000 m.)"""
    model = rod_model()
    model.gravity = pin.Motion(np.array([0, 0, -G, 0, 0, 0]))
    bridge = ContactBridge(model, [PointContact("tip", "tip", tangential=tangential)])
    field = bridge.field("tip")
    rng = np.random.default_rng(1)
    for _ in range(5):
        q, v = rng.normal(size=3), rng.normal(size=3)
        far = q + np.array([1000.0, 0.0, 0.0])
        here, there = np.concatenate([q, v]), np.concatenate([far, v])
        assert np.array_equal(field(0.0, here, None)[3:], field(0.0, there, None)[3:])
        assert np.array_equal(
            bridge.constraint_forces("tip", here)["tip"], bridge.constraint_forces("tip", there)["tip"]
        )
        for c in (0.0, 0.4):
            assert np.array_equal(
                bridge.impact_velocity([("tip", c)], q, v), bridge.impact_velocity([("tip", c)], far, v)
            )
