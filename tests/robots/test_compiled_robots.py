"""Robots written once: every bundled scene of a robot runs its steps in the compiled kernel, the
same source run as plain Python gives the same execution to the bit, and the model functions
(Pinocchio's C++ algorithms through the native library) agree with independent formulations:
Pinocchio's own ``forwardDynamics`` and ``impulseDynamics`` through its Python bindings, and the
closed form of a PD holding a pendulum against gravity."""

import functools
import math

import numba
import numpy as np
import pinocchio as pin
import pytest
from legsim.robots import _native, compass_gait, double_pendulum, rimless_wheel
from legsim.robots._native.calls import lsn_aba, lsn_frame_jacobian, lsn_frame_motion, lsn_frames
from legsim.robots.bridge import native
from legsim.robots.bridge.dynamics import bridge_field
from scipy.optimize import brentq

from helpers.compiled_scenes import ROBOT_SCENES, SYSTEM_SCENES
from legsim import relaxed
from legsim.model import evaluate_field, evaluate_guards, evaluate_reset
from legsim.prebuild import bundled_scenes
from legsim.scene import load_scene

from .test_collision_contacts import BALL_R
from .test_collision_contacts import ball as collision_ball

RNG = np.random.default_rng(18)


def close(a, b, rel=1e-12):
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    assert a.shape == b.shape
    assert np.all(np.abs(a - b) <= rel * (1.0 + np.abs(b))), (a, b)


def scene_of(name, t_final):
    return load_scene(name, [f"integrator.t_final={t_final}"] if t_final else [])


def test_every_bundled_scene_is_checked_on_the_compiled_path():
    # A scene added without its compiled-path test would go unchecked: every bundled scene is in
    # the robots' list or the systems'.
    listed = {name for name, _ in ROBOT_SCENES} | set(SYSTEM_SCENES)
    assert {path.stem for path in bundled_scenes()} == listed


@pytest.mark.parametrize("name,t_final", ROBOT_SCENES)
def test_every_robot_scene_runs_every_step_in_the_kernel(name, t_final):
    scene = scene_of(name, t_final)
    ex = scene.simulate()
    assert ex.status == "finished" and ex.counters["python_steps"] == 0
    assert ex.counters["compiled_steps"] == ex.counters["steps"] > 0


@pytest.mark.parametrize(
    "name,t_final",
    [
        ("double_pendulum_zeno", "3.0"),
        ("rod", None),
        ("slip", None),
        ("quadruped_bound", "0.5"),
        ("quadruped_gallop", "1.0"),
        ("biped_run", "0.5"),
    ],
)
def test_the_python_loop_runs_the_same_functions_to_the_bit(monkeypatch, name, t_final):
    """Stops, Zeno continuations, joint impacts, spring legs, friction events under a controller
    with memory (the gallop's phase term from its second touchdowns on): one source, two paths,
    one execution."""
    scene = scene_of(name, t_final)
    fast = scene.simulate()
    monkeypatch.setattr(relaxed, "simulate", functools.partial(relaxed.simulate, python=True))
    slow = scene.simulate()
    assert slow.counters["compiled_steps"] == 0 and slow.counters["python_steps"] == fast.counters["steps"]
    assert [tr.name for tr in slow.transitions] == [tr.name for tr in fast.transitions]
    assert [tr.time for tr in slow.transitions] == [tr.time for tr in fast.transitions]
    assert np.array_equal(slow.final_state, fast.final_state)


def test_a_pd_holds_the_pendulum_where_its_torque_balances_gravity():
    """double_pendulum_pd comes to rest on its stop where kp (target - theta1) equals the straight
    pendulum's gravity torque (m1 + m2) g L1 sin theta1 + m2 g L2 sin theta1 = 3 g sin theta1."""
    scene = load_scene("double_pendulum_pd")
    ex = scene.simulate()
    pd = scene.effects["controller"]
    kp, target = pd["kp"], pd["target"]
    rest = brentq(lambda th: kp * (target - th) - 3 * 9.81 * math.sin(th), 0.0, 1.0)
    assert ex.status == "finished" and ex.final_mode == "constrained"
    assert abs(ex.final_state[0] - rest) < 1e-6 and abs(ex.final_state[1]) < 1e-9
    assert ex.counters["actuation_evals"] >= ex.counters["field_evals"]  # the torque at every evaluation


def test_constrained_dynamics_match_pinocchio_forward_dynamics():
    # The double pendulum held at its stop: J = e_2 (theta2 >= 0), no drift. Pinocchio's own
    # forwardDynamics solves the same KKT system by a different factorisation.
    system = double_pendulum.make(effects={"stop": {"restitution": 0.0}}).system
    functions = system.mode("constrained").functions
    pm = double_pendulum.pinocchio_model()
    pd = pm.createData()
    for q1, v1 in RNG.uniform(-1.0, 1.0, (10, 2)):
        x = np.array([q1, 0.0, v1, 0.0])
        a = evaluate_field(functions, 4, 0.0, x, None)[2:]
        expected = pin.forwardDynamics(pm, pd, x[:2], x[2:], np.zeros(2), np.array([[0.0, 1.0]]), np.zeros(1))
        close(a, expected, 1e-10)
        # The release guard is the stop's force, Pinocchio's multiplier (M a = tau + J^T lambda).
        assert evaluate_guards(functions, 1, 0.0, x, None)[0] == pytest.approx(pd.lambda_c[0], rel=1e-10, abs=1e-12)


def test_heel_strike_matches_pinocchio_impulse_dynamics():
    walker = compass_gait.CompassGait()
    model = compass_gait.floating_model(walker.m, walker.mH, walker.a, walker.b, walker.g, walker.slope)
    data = model.createData()
    foot2 = model.getFrameId("foot2")
    for th, ph, thd, phd in RNG.uniform(-0.4, 0.4, (10, 4)):
        x = np.array([th, ph, thd, phd, 0.0])
        after = evaluate_reset(walker.functions, 0, 5, x)
        leg = walker.l
        q = np.array([leg * math.sin(th), leg * math.cos(th), th, ph])
        v = np.array([leg * thd * math.cos(th), -leg * thd * math.sin(th), thd, phd])
        J = pin.computeFrameJacobian(model, data, q, foot2, pin.LOCAL_WORLD_ALIGNED)[[0, 2]]
        v_plus = pin.impulseDynamics(model, data, q, v, J, 0.0, 0.0)
        close(after[2:4], [v_plus[2] + v_plus[3], -v_plus[3]], 1e-10)
        close(after[:2], [th + ph, -ph])


def test_a_walker_thrown_backwards_falls_with_its_hip_below_the_slope():
    # The heel strike's guard is nan once the hip is below the slope: the step is shortened
    # there and the run ends as a model breakdown, on either path.
    scene = load_scene("compass_gait", ["initial.state.stanced=-3.0", "integrator.t_final=3.0"])
    ex = scene.simulate()
    assert ex.status == "model_breakdown" and ex.counters["python_steps"] == 0
    hip = ex.final_state[0]
    assert math.cos(hip) < 1e-3  # the stance leg lies (nearly) along the slope: the hip at the ground


@numba.njit
def _native_aba_and_motion(handle, q, v, tau, frame, a, motion):
    lsn_aba(handle, q.ctypes.data, v.ctypes.data, tau.ctypes.data, a.ctypes.data)
    lsn_frame_motion(handle, q.ctypes.data, v.ctypes.data, a.ctypes.data, frame, motion.ctypes.data)


@numba.njit
def _native_frame_and_jacobian(handle, q, v, frame, point, jacobian):
    frames = np.array([float(frame)])
    lsn_frames(handle, q.ctypes.data, v.ctypes.data, 1, frames.ctypes.data, point.ctypes.data)
    lsn_frame_jacobian(handle, q.ctypes.data, frame, jacobian.ctypes.data)


def check_frames_against_pinocchio(bridge, q, v, offsets):
    """Each frame's position, velocity and world-aligned Jacobian from the library (x and z) equal
    Pinocchio's through its Python bindings; a round frame's (``offsets``: frame id -> (dx, dz), m)
    those of its contact point, the frame's origin shifted by the offset in the world's axes."""
    model, data = bridge.model, bridge.model.createData()
    pin.forwardKinematics(model, data, q, v)
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    lwa = pin.LOCAL_WORLD_ALIGNED
    for frame in range(1, model.nframes):
        point, jacobian = np.empty(4), np.empty(2 + 2 * model.nv)
        _native_frame_and_jacobian(np.int64(bridge.handle), q, v, np.int64(frame), point, jacobian)
        dx, dz = offsets.get(frame, (0.0, 0.0))
        d = np.array([dx, 0.0, dz])
        motion = pin.getFrameVelocity(model, data, frame, lwa)
        position, velocity = data.oMf[frame].translation + d, motion.linear + np.cross(motion.angular, d)
        close(point, [position[0], position[2], velocity[0], velocity[2]], 1e-10)
        J = pin.getFrameJacobian(model, data, frame, lwa)
        shifted = J[:3] + np.cross(J[3:].T, d).T
        close(jacobian[2:], np.concatenate([shifted[0], shifted[2]]), 1e-10)


def composite_root_model():
    """A body on a composite root (PX, PZ, RY) whose parts have non-trivial placements, and a
    leg below it, with a foot frame."""
    model = pin.Model()
    root = pin.JointModelComposite()
    root.addJoint(pin.JointModelPX(), pin.SE3(pin.utils.rpyToMatrix(0.0, 0.3, 0.0), np.array([0.1, 0.0, 0.2])))
    root.addJoint(pin.JointModelPZ(), pin.SE3(np.eye(3), np.array([0.0, 0.0, -0.3])))
    root.addJoint(pin.JointModelRY(), pin.SE3(pin.utils.rpyToMatrix(0.0, -0.2, 0.0), np.array([0.05, 0.0, 0.0])))
    body = model.addJoint(0, root, pin.SE3(np.eye(3), np.array([0.0, 0.0, 0.5])), "root")
    body_inertia = pin.Inertia(2.0, np.array([0.1, 0.0, 0.05]), np.diag([0.1, 0.2, 0.3]))
    model.appendBodyToJoint(body, body_inertia, pin.SE3.Identity())
    knee = model.addJoint(body, pin.JointModelRY(), pin.SE3(np.eye(3), np.array([0.2, 0.0, -0.1])), "knee")
    shank_inertia = pin.Inertia(0.5, np.array([0.0, 0.0, -0.2]), np.diag([0.01, 0.02, 0.01]))
    model.appendBodyToJoint(knee, shank_inertia, pin.SE3.Identity())
    foot = pin.SE3(np.eye(3), np.array([0.0, 0.0, -0.4]))
    model.addFrame(pin.Frame("foot", knee, foot, pin.FrameType.OP_FRAME), False)
    return model


def test_a_composite_root_moves_as_in_pinocchio():
    # The library builds a composite joint as the chain of its parts, each placed after the
    # previous one, with massless bodies between: Pinocchio's composite joint moves the same.
    model = composite_root_model()
    data = model.createData()
    handle = native.handle_for(model, "composite")
    foot = model.getFrameId("foot")
    for _ in range(5):
        q, v, tau = RNG.normal(size=(3, model.nv))
        a, motion = np.empty(model.nv), np.empty(4)
        _native_aba_and_motion(np.int64(handle), q, v, tau, np.int64(foot), a, motion)
        close(a, pin.aba(model, data, q, v, tau), 1e-10)
        pin.forwardKinematics(model, data, q, v, a)
        pin.updateFramePlacement(model, data, foot)
        vel = pin.getFrameVelocity(model, data, foot, pin.LOCAL_WORLD_ALIGNED).linear
        acc = pin.getFrameClassicalAcceleration(model, data, foot, pin.LOCAL_WORLD_ALIGNED).linear
        close(motion, [vel[0], vel[2], acc[0], acc[2]], 1e-10)


#: A scene of each robot model the bundled scenes build through the bridge.
BRIDGE_ROBOTS = ["pronk", "pronk_pitched", "double_pendulum_plastic", "rod", "slip", "quadruped_stand", "biped_run"]


@pytest.mark.parametrize("name", BRIDGE_ROBOTS)
def test_every_bundled_robot_has_the_planar_dynamics_of_pinocchio(name):
    # The library computes M and h of a robot moving in the x-z plane from its planar bodies
    # (planar_dynamics in pinlegsim.cpp): every bundled robot is one (the double pendulum's
    # first joint placed by a half turn that reverses its y axis), and its forward dynamics is
    # Pinocchio's ABA through its Python bindings, an independent implementation, to rounding.
    bridge = load_scene(name).model.info["bridge"]
    assert _native.planar(bridge.handle)
    check_aba_against_pinocchio(bridge.handle, bridge.model)
    for _ in range(5):
        check_frames_against_pinocchio(bridge, *RNG.normal(size=(2, bridge.model.nv)), {})


def test_a_round_contacts_point_has_the_planar_kinematics_of_pinocchio(tmp_path):
    # A ball's round contact on flat ground: the library's frame is the ball's lowest point, its
    # centre's frame shifted by (0, -r) in the world's axes, whose velocity and Jacobian carry the
    # ball's spin.
    bridge = load_scene(collision_ball(tmp_path, f"[initial]\nstate = {{ z = {2 * BALL_R} }}\n")).model.info["bridge"]
    offsets = bridge._model.round_offsets
    assert list(offsets.values()) == [(0.0, -BALL_R)] and _native.planar(bridge.handle)
    for _ in range(5):
        check_frames_against_pinocchio(bridge, *RNG.normal(size=(2, bridge.model.nv)), offsets)


@numba.njit
def _native_in_turn(handle, q, v_first, v_second, tau, frame, first, second, jacobian, a):
    frames = np.array([float(frame)])
    lsn_frames(handle, q.ctypes.data, v_first.ctypes.data, 1, frames.ctypes.data, first.ctypes.data)
    lsn_frames(handle, q.ctypes.data, v_second.ctypes.data, 1, frames.ctypes.data, second.ctypes.data)
    lsn_frame_jacobian(handle, q.ctypes.data, frame, jacobian.ctypes.data)
    lsn_aba(handle, q.ctypes.data, v_first.ctypes.data, tau.ctypes.data, a.ctypes.data)


def test_the_planar_frames_kept_for_a_state_serve_only_that_state():
    # The library keeps the planar frames of the last (q, v) and reuses them at the same state
    # (a Jacobian reads only positions, so those of q at any v): calls at one q with two v's, a
    # Jacobian and the forward dynamics at the first v again each equal Pinocchio's at their own
    # state. The double pendulum has no translation, so its dynamics run at this very q.
    bridge = load_scene("double_pendulum_plastic").model.info["bridge"]
    model, data, nv = bridge.model, bridge.model.createData(), bridge.model.nv
    frame = model.nframes - 1
    for _ in range(3):
        q, v_first, v_second, tau = RNG.normal(size=(4, nv))
        first, second, jacobian, a = np.empty(4), np.empty(4), np.empty(2 + 2 * nv), np.empty(nv)
        _native_in_turn(np.int64(bridge.handle), q, v_first, v_second, tau, np.int64(frame), first, second, jacobian, a)
        for v, point in ((v_first, first), (v_second, second)):
            pin.forwardKinematics(model, data, q, v)
            pin.updateFramePlacements(model, data)
            velocity = pin.getFrameVelocity(model, data, frame, pin.LOCAL_WORLD_ALIGNED).linear
            position = data.oMf[frame].translation
            close(point, [position[0], position[2], velocity[0], velocity[2]], 1e-10)
        pin.computeJointJacobians(model, data, q)
        J = pin.getFrameJacobian(model, data, frame, pin.LOCAL_WORLD_ALIGNED)
        close(jacobian, np.concatenate([[position[0], position[2]], J[0], J[2]]), 1e-10)
        close(a, pin.aba(model, data, q, v_first, tau), 1e-10)


def test_a_mass_matrix_the_factor_cannot_take_gives_nan_and_the_next_call_recovers():
    # M's Cholesky factor refuses a pivot that is not positive, or not a number (here M at a nan
    # angle): the acceleration is then nan, which a run reports as a model breakdown, and the
    # next call at a valid state is Pinocchio's ABA again.
    bridge = load_scene("double_pendulum_plastic").model.info["bridge"]
    model, nv = bridge.model, bridge.model.nv
    q, v, tau = RNG.normal(size=(3, nv))
    broken, a, motion = q.copy(), np.empty(nv), np.empty(4)
    broken[0] = np.nan
    _native_aba_and_motion(np.int64(bridge.handle), broken, v, tau, np.int64(1), a, motion)
    assert np.isnan(a).all()
    _native_aba_and_motion(np.int64(bridge.handle), q, v, tau, np.int64(1), a, motion)
    close(a, pin.aba(model, model.createData(), q, v, tau), 1e-10)


def check_aba_against_pinocchio(handle, model):
    """The library's forward dynamics at random states is Pinocchio's ABA through its Python
    bindings, to rounding."""
    data = model.createData()
    for _ in range(5):
        q, v, tau = RNG.normal(size=(3, model.nv))
        a, motion = np.empty(model.nv), np.empty(4)
        _native_aba_and_motion(np.int64(handle), q, v, tau, np.int64(1), a, motion)
        close(a, pin.aba(model, data, q, v, tau), 1e-10)


@pytest.mark.parametrize("walker", ["compass_gait", "rimless_wheel"])
def test_the_walkers_have_the_planar_dynamics_of_pinocchio(walker):
    # The walkers build their own Pinocchio models (gravity along the slope): planar too.
    robot = {"compass_gait": compass_gait, "rimless_wheel": rimless_wheel}[walker].make().info[walker]
    assert _native.planar(robot.handle)
    check_aba_against_pinocchio(robot.handle, robot._kin_model if walker == "compass_gait" else robot._model)


def test_a_model_out_of_the_plane_keeps_pinocchios_algorithms():
    # A joint about x takes the body out of the x-z plane: the library runs Pinocchio's crba and
    # RNEA for it, and its forward dynamics is Pinocchio's all the same.
    model = composite_root_model()
    roll = model.addJoint(
        model.getJointId("knee"), pin.JointModelRX(), pin.SE3(np.eye(3), np.array([0, 0, -0.4])), "roll"
    )
    model.appendBodyToJoint(roll, pin.Inertia(0.3, np.array([0.0, 0.1, -0.1]), np.diag([0.02, 0.01, 0.03])),
                            pin.SE3.Identity())  # fmt: skip
    handle = native.handle_for(model, "rolling")
    assert not _native.planar(handle)
    assert _native.planar(native.handle_for(composite_root_model(), "composite"))
    check_aba_against_pinocchio(handle, model)


@pytest.mark.parametrize("parts", [0.0, -1.0, math.nan, 1e300, 2.0**60, 4.0])
def test_the_library_refuses_a_composite_whose_part_count_its_description_cannot_hold(parts):
    # One composite joint of `parts` parts followed by 3 parts' worth of zeros (RX parts at the
    # identity would need 13 values each): every count here is refused, never read past the end
    # (2**60 parts overflow 13 * parts in long arithmetic: the bound must be divided, not multiplied).
    description = np.array([1.0, float(native.COMPOSITE), parts] + [0.0] * 39)
    with pytest.raises(ValueError, match="refused"):
        _native.create_model(description)


def test_the_library_refuses_a_composite_of_composites():
    part = [float(native.COMPOSITE)] + [0.0] * 12
    with pytest.raises(ValueError, match="refused"):
        _native.create_model(np.array([1.0, float(native.COMPOSITE), 1.0, *part] + [0.0] * 60))


def test_a_robots_evaluations_are_counted_whichever_path_ran_them():
    model = double_pendulum.make(effects={"gravity": {}, "stop": {"restitution": 0.0}, "damping": {}})
    bridge = model.info["bridge"]
    bridge.reset_counters()
    p = np.array(model.system.mode("unconstrained").functions.params)
    dx, x = np.empty(4), np.array([0.3, 0.2, 0.0, 0.1])
    bridge_field(0.0, x, np.zeros(0), p, dx)
    counts = bridge.counters()
    assert counts["aba"] == 1 and counts["kkt"] == 0 and counts["damping_evals"] == 1
