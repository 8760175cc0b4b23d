"""Compiled robot twins (robots/bridge/twins.py, walker_twins.py) against what they mirror.

The twins call Pinocchio's C++ algorithms through the native library; the Python bridge calls
the same algorithms through Pinocchio's Python bindings. Both do the same arithmetic in the same
order up to Eigen's and numpy's summation orders, so a twin's field, guards and resets agree with
the Python callables to rounding (1e-12 relative here), and whole runs take the same steps and
transitions, with times and states equal to rounding amplified over the run (1e-9 here). The
constrained dynamics and the impact law are also checked against Pinocchio's own solvers
(``forwardDynamics``, ``impulseDynamics``), an independent formulation of the same laws.
"""

import math

import numba
import numpy as np
import pinocchio as pin
import pytest
from legsim.robots import compass_gait, double_pendulum, pronk, rimless_wheel
from legsim.robots.bridge import twins, walker_twins

import legsim.compiled as compiled
from legsim import _native
from legsim._native.calls import lsn_aba, lsn_frame_motion
from legsim.scene import load_scene

pytestmark = pytest.mark.skipif(not _native.load(), reason=f"native library: {_native.status()}")

RNG = np.random.default_rng(18)


def close(a, b, rel=1e-12):
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    assert a.shape == b.shape
    assert np.all(np.abs(a - b) <= rel * (1.0 + np.abs(b))), (a, b)


def check_mode(system, mode, states):
    """The mode's twin against its Python field, guards and resets at each state."""
    data = system.mode_data(mode)
    twin = data.mode.compiled
    assert twin is not None, mode
    for x in states:
        x = np.ascontiguousarray(x, dtype=float)
        close(twin.field(0.0, x, twin.params), data.mode.field(0.0, x, None))
        close(twin.guards(x, twin.params), [g(x) for g in data.guards])
        if twin.resets is not None:
            for e, reset in enumerate(data.resets):
                close(twin.resets(x, twin.params, e), reset(x.copy()))


def test_compass_gait_twin_matches_its_python_callables():
    system = compass_gait.make().system
    states = [np.array([th, ph, thd, phd, 0.3]) for th, ph, thd, phd in RNG.uniform(-0.6, 0.6, (20, 4))]
    check_mode(system, "stance", states)


def test_rimless_wheel_twin_matches_its_python_callables():
    system = rimless_wheel.make({"I": 0.05}).system  # a hub with inertia exercises the centroidal term
    states = [np.array([th, thd, 1.0]) for th, thd in RNG.uniform(-0.5, 0.5, (20, 2))]
    check_mode(system, "stance", states)


@pytest.mark.parametrize("restitution", [0.0, 0.6])
def test_double_pendulum_twins_match_the_bridge_in_both_modes(restitution):
    model = double_pendulum.make(effects={"stop": {"restitution": restitution}, "damping": {"b1": 0.3, "b2": 0.2}})
    system = model.system
    states = [np.array([a, b, c, d]) for a, b, c, d in RNG.uniform(-1.0, 1.0, (12, 4))]
    check_mode(system, "unconstrained", states)
    if restitution == 0.0:
        # At the stop: theta2 = 0 (the constrained mode's states), any rates.
        check_mode(system, "constrained", [np.array([x[0], 0.0, x[2], 0.0]) for x in states])


def test_pronk_twins_match_the_bridge_in_every_mode():
    model = pronk.make(effects={"damping": {"b": 0.4}})
    system = model.system
    base = pronk.state()
    for mode, footholds in (("aerial", 0), ("left", 1), ("right", 1), ("both", 2)):
        states = []
        for _ in range(8):
            x = base + RNG.uniform(-0.1, 0.1, 6)
            x[1] = 0.9 + RNG.uniform(0.0, 0.1)  # legs compressed below the rest length of 1 m
            states.append(np.concatenate([x, x[0] + RNG.uniform(-0.4, 0.4, footholds)]))
        check_mode(system, mode, states)


def test_constrained_dynamics_match_pinocchio_forward_dynamics():
    # The double pendulum held at its stop: J = e_2 (theta2 >= 0), no drift. Pinocchio's own
    # forwardDynamics solves the same KKT system by a different factorisation.
    system = double_pendulum.make(effects={"stop": {"restitution": 0.0}}).system
    twin = system.mode_data("constrained").mode.compiled
    pm = double_pendulum.pinocchio_model()
    pd = pm.createData()
    for q1, v1 in RNG.uniform(-1.0, 1.0, (10, 2)):
        x = np.array([q1, 0.0, v1, 0.0])
        a = twin.field(0.0, x, twin.params)[2:]
        J = np.array([[0.0, 1.0]])
        expected = pin.forwardDynamics(pm, pd, x[:2], x[2:], np.zeros(2), J, np.zeros(1))
        close(a, expected, 1e-10)
        # The release guard is the stop's force, Pinocchio's multiplier (M a = tau + J^T lambda).
        assert twin.guards(x, twin.params)[0] == pytest.approx(pd.lambda_c[0], rel=1e-10, abs=1e-12)


def test_heel_strike_matches_pinocchio_impulse_dynamics():
    walker = compass_gait.CompassGait()
    twin = walker_twins.compass_gait_twin(walker)
    model = walker.impact_bridge.model
    data = model.createData()
    foot2 = model.getFrameId("foot2")
    for th, ph, thd, phd in RNG.uniform(-0.4, 0.4, (10, 4)):
        x = np.array([th, ph, thd, phd, 0.0])
        after = twin.resets(x, twin.params, 0)
        leg_length = walker.l
        q = np.array([leg_length * math.sin(th), leg_length * math.cos(th), th, ph])
        v = np.array([leg_length * thd * math.cos(th), -leg_length * thd * math.sin(th), thd, phd])
        J = pin.computeFrameJacobian(model, data, q, foot2, pin.LOCAL_WORLD_ALIGNED)[[0, 2]]
        v_plus = pin.impulseDynamics(model, data, q, v, J, 0.0, 0.0)
        close(after[2:4], [v_plus[2] + v_plus[3], -v_plus[3]], 1e-10)


# -- whole runs: the compiled path against the Python path -------------------------------------


def counted_run(monkeypatch, make_run, python):
    """``make_run()``'s execution with the twins (python=False) or without, and how many times
    the kernel was called from Python (for a mode visit Python entered, or an entry it hands
    over)."""
    calls = []
    real_visit, real_entry = compiled.run_visit_compiled, compiled.enter_compiled
    with monkeypatch.context() as m:
        m.setattr(compiled, "run_visit_compiled", lambda *a: calls.append(1) or real_visit(*a))
        m.setattr(compiled, "enter_compiled", lambda *a: calls.append(1) or real_entry(*a))
        if python:
            m.setattr(twins, "AVAILABLE", False)
        ex = make_run()
    return ex, len(calls)


def run(monkeypatch, scene, python, overrides=()):
    """The scene's execution with the twins (python=False) or without, and the kernel's calls."""
    return counted_run(monkeypatch, lambda: load_scene(scene, list(overrides)).simulate(), python)


def assert_same_run(a, b, tol=1e-9, handed_back=False):
    """Run a (compiled) is run b (Python) to ``tol``. ``handed_back``: a's twins hand steps to
    the Python loop (nan guards), which retakes each from its start, so a evaluated its field
    more often (the kernel's trial of those steps) than b."""
    assert a.status == b.status and a.message == b.message
    assert [t.name for t in a.transitions] == [t.name for t in b.transitions]
    for ta, tb in zip(a.transitions, b.transitions, strict=True):
        assert abs(ta.time - tb.time) <= tol and abs(ta.exit_time - tb.exit_time) <= tol
        close(ta.state_before, tb.state_before, tol)
        close(ta.state_after, tb.state_after, tol)
    for key in ("steps", "halvings", "error_rejections", "transitions"):
        assert a.counters[key] == b.counters[key], key
    if handed_back:
        assert a.counters["field_evals"] >= b.counters["field_evals"]
    else:
        assert a.counters["field_evals"] == b.counters["field_evals"]
    close(a.final_state, b.final_state, tol)
    assert [(s.mode, s.name) for s in a.strips] == [(s.mode, s.name) for s in b.strips]
    assert abs(a.counters["strip_time"] - b.counters["strip_time"]) <= tol * max(1, len(a.strips))
    assert [(w.kind, w.message) for w in a.warnings] == [(w.kind, w.message) for w in b.warnings]


SCENES = [
    ("compass_gait", ()),
    (
        "compass_gait",
        (
            'integrator.method="dopri5"',
            "integrator.rtol=1e-8",
            "integrator.atol=1e-8",
            "integrator.h=0.1",
            'integrator.landing="aim"',
        ),
    ),
    ("rimless_wheel", ()),
    (
        "rimless_wheel",
        (
            'integrator.method="dop853"',
            "integrator.rtol=1e-9",
            "integrator.atol=1e-9",
            "integrator.h=0.1",
            'integrator.landing="aim"',
        ),
    ),
    ("double_pendulum_plastic", ("integrator.t_final=4.0",)),
    (
        "double_pendulum_zeno",
        ("effects.zeno=false", "integrator.t_final=2.0", 'integrator.method="rk4"', "integrator.eps=1e-3"),
    ),
    ("pronk", ()),
    ("pronk_pitched", ()),
    (
        "pronk_pitched",
        (
            'integrator.method="dopri5"',
            "integrator.rtol=1e-7",
            "integrator.atol=1e-7",
            "integrator.h=0.1",
            'integrator.landing="aim"',
        ),
    ),
]


#: Runs that cross mode changes, Zeno continuations (on and off) and joint impacts, and whether
#: Python takes some of their crossings after each mode's first entry (the rod's joint impacts).
MODE_CHANGES = [
    ("pronk", (), False),
    ("double_pendulum_plastic", (), False),
    ("double_pendulum_zeno", ("integrator.t_final=12.0", 'integrator.method="rk4"', "integrator.eps=1e-3"), False),
    ("double_pendulum_zeno", ("integrator.t_final=2.0", "integrator.continuation=false", "integrator.eps=1e-3"), False),
    ("rod", (), True),
]


@pytest.mark.parametrize("scene,overrides,joint", MODE_CHANGES)
def test_mode_changes_are_crossed_in_the_kernel_as_in_python(monkeypatch, scene, overrides, joint):
    # Each mode's first entry in the process returns to Python (which checks its twin and its
    # field there, then hands the entry back); from then on the kernel crosses the run's
    # transitions itself, mode changes and Zeno continuations included, and returns only for
    # what Python decides: a joint impact of two rigid contacts (the rod's two ends).
    fast, n_kernel = run(monkeypatch, scene, False, overrides)
    slow, _ = run(monkeypatch, scene, True, overrides)
    assert fast.status == "finished"
    assert_same_run(fast, slow)
    modes = {s.mode for s in fast.segments}
    assert len(fast.transitions) > len(modes)
    if joint:
        assert n_kernel <= len(modes) + sum("+" in t.name for t in fast.transitions)
    else:
        assert n_kernel == len(modes)
    # The kernel's field evaluations count in the model's counters (each one an ABA or a KKT solve).
    assert fast.counters["aba"] + fast.counters["kkt"] >= fast.counters["field_evals"]
    if "rk4" in str(overrides):  # continuations into the resting mode, all but the first in the kernel
        assert sum(t.name == "rest_stop" for t in fast.transitions) >= 3


@pytest.mark.parametrize("scene,overrides", SCENES)
def test_robot_scene_same_on_both_paths(monkeypatch, scene, overrides):
    fast, n_kernel = run(monkeypatch, scene, False, overrides)
    slow, n_python = run(monkeypatch, scene, True, overrides)
    assert n_kernel > 0 and n_python == 0  # the comparison is between the two loops
    assert fast.status == "finished" and len(fast.transitions) >= 2
    assert_same_run(fast, slow)


def test_walker_that_falls_ends_alike_on_both_paths(monkeypatch):
    # Thrown backwards: the hip goes below the slope, where the twin's guard is nan and the
    # Python loop takes over, shortens the step and ends with the Python path's breakdown.
    overrides = ("initial.state.stanced=-3.0", "integrator.t_final=3.0")
    fast, _ = run(monkeypatch, "compass_gait", False, overrides)
    slow, _ = run(monkeypatch, "compass_gait", True, overrides)
    assert fast.status == "model_breakdown" and "the walker fell" in fast.message
    assert fast.message == slow.message and fast.t_end == pytest.approx(slow.t_end, abs=1e-9)


def test_without_the_native_library_robots_run_in_python_and_say_so_once(tmp_path):
    # LEGSIM_NATIVE=0 stands for an install without a compiler: no twin is attached, one
    # warning names the reason, and the runs finish on the Python path with the same result.
    import json
    import os
    import subprocess
    import sys

    script = (
        "import json\n"
        "from legsim.scene import load_scene\n"
        "out = {}\n"
        "for name in ('compass_gait', 'double_pendulum_plastic', 'pronk'):\n"
        "    scene = load_scene(name, ['integrator.t_final=1.0'])\n"
        "    ex = scene.simulate()\n"
        "    out[name] = [ex.status, ex.final_state.tolist(), scene.model.system.modes and\n"
        "                 any(m.compiled is not None for m in scene.model.system.modes.values())]\n"
        "print(json.dumps(out))\n"
    )
    env = {**os.environ, "LEGSIM_NATIVE": "0", "LEGSIM_CACHE_DIR": str(tmp_path)}
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=300)
    assert done.returncode == 0, done.stderr
    assert done.stderr.count("compiled robot twins unavailable (switched off by LEGSIM_NATIVE=0)") == 1
    results = json.loads(done.stdout)
    for name, (status, final, any_twin) in results.items():
        assert status == "finished" and not any_twin
        reference = load_scene(name, ["integrator.t_final=1.0"]).simulate()  # with the twins, in this process
        close(final, reference.final_state, 1e-9)


@pytest.mark.parametrize("scene,overrides,joint", MODE_CHANGES)
def test_a_later_run_enters_every_mode_in_the_kernel_and_repeats_the_first(monkeypatch, scene, overrides, joint):
    # The first run of a system returns to Python at each mode's first entry; a second run of
    # the same system does not (its modes are checked), yet gives the same execution to the
    # bit: both runs enter every mode with the kernel's arithmetic (the twin's field, guards and
    # starting step), never the Python callables', which differ from the twin's by rounding.
    model = load_scene(scene, list(overrides))
    calls = []
    real_visit, real_entry = compiled.run_visit_compiled, compiled.enter_compiled
    monkeypatch.setattr(compiled, "run_visit_compiled", lambda *a: calls.append(1) or real_visit(*a))
    monkeypatch.setattr(compiled, "enter_compiled", lambda *a: calls.append(1) or real_entry(*a))
    first = model.simulate()
    n_first = len(calls)
    second = model.simulate()
    n_second = len(calls) - n_first
    assert first.status == "finished"
    assert_same_run(first, second, tol=0.0)
    for a, b in zip(first.segments, second.segments, strict=True):
        assert a.mode == b.mode and np.array_equal(a.t, b.t) and np.array_equal(a.x, b.x)
    modes = {s.mode for s in first.segments}
    if joint:  # the joint impacts return to Python in every run
        assert n_second <= 1 + sum("+" in t.name for t in second.transitions)
    else:
        assert n_first == len(modes) and n_second == 1


@numba.njit
def _native_aba_and_motion(h, q, v, tau, frame, a, motion):
    """The library's ABA into a (nv,), then the frame's (vx, vz, ax, az) at (q, v, a) into motion."""
    lsn_aba(h, q.ctypes.data, v.ctypes.data, tau.ctypes.data, a.ctypes.data)
    lsn_frame_motion(h, q.ctypes.data, v.ctypes.data, a.ctypes.data, frame, motion.ctypes.data)


def composite_root_model():
    """A planar body on a composite root (PX, PZ, RY) whose parts are placed off the identity
    (rotated, offset), a knee (RY) below it and a foot frame on the shank."""
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


def test_a_composite_root_with_offset_parts_moves_as_in_pinocchio():
    # Each part's placement is relative to the previous part: the library must compose them as
    # Pinocchio does, or every acceleration and foot motion of such a robot differs.
    model = composite_root_model()
    data = model.createData()
    handle = twins.handle_for(model)
    assert handle is not None
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


@pytest.mark.parametrize("parts", [0.0, -1.0, math.nan, 1e300, 2.0**60, 4.0])
def test_the_library_refuses_a_composite_whose_part_count_its_description_cannot_hold(parts):
    # One composite joint of `parts` parts followed by 3 parts' worth of zeros (RX parts at the
    # identity would need 13 values each): every count here is refused, never read past the end
    # (2**60 parts overflow 13 * parts in long arithmetic: the bound must be divided, not multiplied).
    description = np.array([1.0, float(twins.COMPOSITE), parts] + [0.0] * 39)
    with pytest.raises(ValueError, match="refused"):
        _native.create_model(description)


def test_the_library_refuses_a_composite_of_composites():
    part = [float(twins.COMPOSITE)] + [0.0] * 12
    with pytest.raises(ValueError, match="refused"):
        _native.create_model(np.array([1.0, float(twins.COMPOSITE), 1.0, *part] + [0.0] * 60))
