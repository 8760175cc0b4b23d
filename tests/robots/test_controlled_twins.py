"""Controlled robots on the compiled path: an actuated robot's twin computes its controller's
torques itself (``robots.bridge.twins``: control records), Python enters every mode (resetting
the controller) and writes the record into the twin, and the kernel takes the steps between.

The reference is the Python path: the same controller evaluated by Python at every stage. Both
paths do the same arithmetic (the PD law element by element, Pinocchio's algorithms in C++), so
runs agree to rounding amplified over the run (1e-9, as the uncontrolled parity tests).
"""

import math

import numpy as np
import pytest
from legsim.robots import double_pendulum
from legsim.robots.bridge import control_records, twins
from legsim.robots.controllers import JointPD
from scipy.optimize import brentq

import legsim.compiled as compiled
from legsim import _native
from legsim.compiled import without_compiled
from legsim.errors import ModelError
from legsim.relaxed import simulate

from .test_twins import assert_same_run, close, run

pytestmark = pytest.mark.skipif(not _native.load(), reason=f"native library: {_native.status()}")

RNG = np.random.default_rng(25)
KP, KD, TARGET, G = 100.0, 20.0, 1.0, 9.81  # the double_pendulum_pd scene's controller (N m/rad, N m s/rad, rad)


def pendulum():
    return double_pendulum.make(
        effects={"gravity": {}, "stop": {"restitution": 0.0}, "controller": {"kp": KP, "kd": KD, "target": TARGET}}
    )


def kernel_calls(monkeypatch, system, control, t_final=4.0):
    """The run of ``system`` under ``control`` from the scene's start, and the kernel's calls."""
    calls = []
    real_visit, real_entry = compiled.run_visit_compiled, compiled.enter_compiled
    with monkeypatch.context() as m:
        m.setattr(compiled, "run_visit_compiled", lambda *a: calls.append(1) or real_visit(*a))
        m.setattr(compiled, "enter_compiled", lambda *a: calls.append(1) or real_entry(*a))
        x0 = np.array([math.radians(30.0), math.radians(25.0), 0.0, 0.0])
        ex = simulate(system, x0, "unconstrained", t_final, 1e-3, 1e-3, "rk4", control)
    return ex, len(calls)


@pytest.mark.parametrize("mode", ["unconstrained", "constrained"])
def test_actuated_twin_computes_the_controllers_torque_as_the_bridge(mode):
    model = pendulum()
    data = model.system.mode_data(mode)
    twin = data.mode.compiled
    twin.controls(model.control)(twin.params)  # the record, as Python writes it at an entry
    for a, b, c, d in RNG.uniform(-1.0, 1.0, (12, 4)):
        x = np.array([a, 0.0 if mode == "constrained" else b, c, 0.0 if mode == "constrained" else d])
        u = model.control(0.0, x)
        close(twin.field(0.0, x, twin.params), data.mode.field(0.0, x, u))
        close(twin.guards(x, twin.params), [tr.guard(0.0, x, u) for tr in data.transitions])
    # Past the stop (theta2 < 0), the plastic impact's guard takes the post-impact force under
    # the control at the state before the impact: the torque, not only the gap, decides it.
    x = np.array([0.4, -1e-4, 0.3, -0.8])
    if mode == "unconstrained":
        u = model.control(0.0, x)
        close(twin.guards(x, twin.params), [tr.guard(0.0, x, u) for tr in data.transitions])


def test_double_pendulum_pd_runs_compiled_and_rests_where_the_pd_balances_gravity(monkeypatch):
    fast, n_kernel = run(monkeypatch, "double_pendulum_pd", False)
    slow, n_python = run(monkeypatch, "double_pendulum_pd", True)
    assert n_python == 0 and n_kernel == len(fast.segments)  # every visit's steps in the kernel
    assert fast.status == "finished" and fast.transitions[-1].name == "impact_stop"
    assert_same_run(fast, slow)
    assert fast.counters["actuation_evals"] >= fast.counters["field_evals"]  # the twin's torques are counted
    # At rest on the stop the shoulder's PD balances the straight pendulum's gravity torque:
    # kp (target - theta1) = (m1 + m2) g L1 sin theta1 + m2 g L2 sin theta1 = 3 g sin theta1.
    rest = brentq(lambda th: KP * (TARGET - th) - 3 * G * math.sin(th), 0.0, 1.0)
    assert abs(fast.final_state[0] - rest) < 1e-6 and abs(fast.final_state[1]) < 1e-9


class SwitchingPD(JointPD):
    """A PD whose target the controller's reset changes at every mode entry (a stateful
    controller): the twin must get the new target at each entry to follow Python."""

    def __init__(self, bridge, targets):
        super().__init__(bridge, KP, KD, np.array([targets[0]]), gravity=False)
        self.choices, self.entries = targets, []

    def reset(self, mode, t, x):
        self.entries.append((mode, t))
        self.targets = np.array([self.choices[len(self.entries) % 2]])


def test_a_controller_reset_at_every_entry_gives_the_same_run_on_both_paths(monkeypatch):
    model = pendulum()
    system, bridge = model.system, model.info["bridge"]
    runs = []
    for sys_ in (system, without_compiled(system)):
        controller = SwitchingPD(bridge, (1.0, -0.5))
        ex, n_kernel = kernel_calls(monkeypatch, sys_, controller)
        runs.append((ex, n_kernel, controller.entries))
    (fast, n_fast, entries_fast), (slow, n_slow, entries_slow) = runs
    assert n_fast > 0 and n_slow == 0
    assert len(fast.transitions) >= 3  # the target flips make the pendulum hit and leave the stop
    assert_same_run(fast, slow)
    assert [m for m, _ in entries_fast] == [m for m, _ in entries_slow] == [s.mode for s in fast.segments]
    close([t for _, t in entries_fast], [t for _, t in entries_slow], 1e-9)


def test_gravity_compensation_is_computed_by_the_twin_as_by_pinocchio(monkeypatch):
    # u = kp (target - q) - kd dq/dt + g(q): the twin's generalised gravity is the native
    # library's computeGeneralizedGravity, the Python path's Pinocchio's own.
    model = pendulum()
    bridge = model.info["bridge"]
    data = model.system.mode_data("unconstrained")
    twin = data.mode.compiled
    pd = JointPD(bridge, KP, KD, np.array([TARGET]), gravity=True)
    twin.controls(pd)(twin.params)
    for a, b, c, d in RNG.uniform(-1.0, 1.0, (12, 4)):
        x = np.array([a, b, c, d])
        close(twin.field(0.0, x, twin.params), data.mode.field(0.0, x, pd("unconstrained", 0.0, x)))
    fast, n_kernel = kernel_calls(monkeypatch, model.system, pd)
    slow, _ = kernel_calls(
        monkeypatch, without_compiled(model.system), JointPD(bridge, KP, KD, np.array([TARGET]), True)
    )
    assert n_kernel > 0
    assert_same_run(fast, slow)
    # With gravity compensated the shoulder settles at its target once link 2 rests on the stop.
    assert abs(fast.final_state[0] - TARGET) < 1e-3


class NoRecord(JointPD):
    def compiled_record(self, pin_model):
        return None


@pytest.mark.parametrize(
    "make",
    [
        pytest.param(lambda b: _held(JointPD(b, KP, KD, np.array([TARGET]), gravity=False)), id="held"),
        pytest.param(lambda b: NoRecord(b, KP, KD, np.array([TARGET]), gravity=False), id="no-record"),
        pytest.param(lambda b: lambda t, x: np.array([KP * (TARGET - x[0]) - KD * x[2]]), id="plain-function"),
    ],
)
def test_a_control_the_twin_cannot_compute_runs_on_the_python_path(monkeypatch, make):
    # A held controller is sampled once per step (the kernel samples none), and the twin
    # computes only controls that give it a record.
    model = pendulum()
    control = make(model.info["bridge"])
    fast, n_kernel = kernel_calls(monkeypatch, model.system, control, t_final=1.0)
    slow, _ = kernel_calls(monkeypatch, without_compiled(model.system), make(model.info["bridge"]), t_final=1.0)
    assert n_kernel == 0 and fast.status == "finished"
    assert_same_run(fast, slow, tol=0.0)


def _held(controller):
    controller.hold = True
    return controller


def test_an_actuated_robot_without_control_runs_compiled_with_no_torque(monkeypatch):
    # The same robot, no control: the twin's record says so and adds no torque (Python: u = None).
    model = pendulum()
    fast, n_kernel = kernel_calls(monkeypatch, model.system, None)
    slow, _ = kernel_calls(monkeypatch, without_compiled(model.system), None)
    assert n_kernel > 0
    assert_same_run(fast, slow)
    twin = model.system.mode_data("unconstrained").mode.compiled
    assert control_records.CONTROL_KINDS[int(twin.params[int(twin.params[twins.P_CTRL])])] == "none"


def test_a_run_after_a_controlled_one_does_not_inherit_its_controller(monkeypatch):
    # The twins' parameters hold the last controller's record: a run without control on the
    # same system, whose entries the kernel takes itself, must write its own (no torque).
    model = pendulum()
    kernel_calls(monkeypatch, model.system, model.control)
    after, n_kernel = kernel_calls(monkeypatch, model.system, None)
    slow, _ = kernel_calls(monkeypatch, without_compiled(model.system), None)
    assert n_kernel > 0
    assert_same_run(after, slow)


def test_bench_case_double_pendulum_pd_runs_compiled_to_its_reference(monkeypatch):
    # `legsim bench robots --case double-pendulum-pd`: the scene's control is the robot's own (an
    # effect, no [controller] section); its compiled family runs in the kernel and meets the
    # solve_ivp reference (DOP853 at 1e-12) at the transitions.
    from legsim.bench import robots

    case = robots.make_robot_case("double-pendulum-pd", quick=True)
    assert robots.takes_compiled_path(case.system, case.new_control())
    calls = []
    real = compiled.run_visit_compiled
    monkeypatch.setattr(compiled, "run_visit_compiled", lambda *a: calls.append(1) or real(*a))
    row = robots.run_one(case, robots.RunSpec("relaxed", "relaxed-dopri5", 0.1, 1e-10, 1e-8, "aim"), 1)
    assert calls and row.status == "finished" and row.transitions == 2
    assert row.error < 1e-6


class HalvedPD(JointPD):
    """A law the twin does not know: the PD's torque halved in ``__call__`` (the record's gains
    are the base class's)."""

    def __call__(self, mode, t, x):
        return 0.5 * super().__call__(mode, t, x)


@pytest.mark.parametrize("checked", [False, True], ids=["first-visit", "after-a-checked-run"])
def test_a_joint_pd_whose_subclass_changes_the_law_runs_on_the_python_path(monkeypatch, checked):
    # The twin computes JointPD's law from the record: a subclass overriding __call__ must not
    # get a record, else the kernel computes the base class's torque -- refused by the twin
    # check at a mode's first visit, silently wrong once an earlier run has checked the mode.
    model = pendulum()
    bridge = model.info["bridge"]
    if checked:
        kernel_calls(monkeypatch, model.system, model.control, 1.0)
    fast, n_kernel = kernel_calls(monkeypatch, model.system, HalvedPD(bridge, KP, KD, np.array([TARGET]), False), 1.0)
    slow, _ = kernel_calls(
        monkeypatch, without_compiled(model.system), HalvedPD(bridge, KP, KD, np.array([TARGET]), False), 1.0
    )
    assert n_kernel == 0 and fast.status == "finished"
    assert_same_run(fast, slow, tol=0.0)


class MisrecordedPD(JointPD):
    """A record that does not say the law: twice the controller's kp (the twin's check at a
    mode's first controlled visit is what finds such a record)."""

    def compiled_record(self, pin_model):
        record = super().compiled_record(pin_model)
        return None if record is None else [record[0], 2.0 * record[1], *record[2:]]


def test_the_twin_is_checked_under_control_after_a_run_without_one_checked_it(monkeypatch):
    # A run without control checks each mode's twin without torque; the first controlled visit
    # must check it again with the controller's record, not take the earlier check for it.
    model = pendulum()
    bridge = model.info["bridge"]
    kernel_calls(monkeypatch, model.system, None, 1.0)
    with pytest.raises(ModelError, match="compiled twin of mode 'unconstrained' disagrees"):
        kernel_calls(monkeypatch, model.system, MisrecordedPD(bridge, KP, KD, np.array([TARGET]), False), 1.0)


def test_a_zeno_continuation_in_a_controlled_run_is_the_python_paths(monkeypatch):
    # A bouncing stop under the PD: the bounces accumulate and the run rests by the continuation
    # (rest_stop). In a controlled run the kernel hands every crossing to Python, which decides
    # the continuation as on the Python path.
    def bouncing():
        effects = {"gravity": {}, "stop": {"restitution": 0.6}, "zeno": {"window": 1e-3}}
        model = double_pendulum.make(effects=effects | {"controller": {"kp": KP, "kd": 2.0, "target": TARGET}})
        for mode in ("unconstrained", "constrained"):  # built before without_compiled copies the modes
            model.system.mode_data(mode)
        return model

    model = bouncing()
    fast, n_kernel = kernel_calls(monkeypatch, model.system, model.control, 3.0)
    slow_model = bouncing()
    slow, _ = kernel_calls(monkeypatch, without_compiled(slow_model.system), slow_model.control, 3.0)
    assert n_kernel > 0 and fast.status == "finished"
    assert [t.name for t in fast.transitions][-1] == "rest_stop" and len(fast.transitions) > 5
    assert_same_run(fast, slow)


def test_a_failing_compiled_record_is_a_model_error_naming_the_controller():
    class Broken(JointPD):
        def compiled_record(self, pin_model):
            raise ValueError("no record today")

    model = pendulum()
    x0 = np.array([0.5, 0.4, 0.0, 0.0])
    control = Broken(model.info["bridge"], KP, KD, np.array([TARGET]), gravity=False)
    with pytest.raises(ModelError, match="could not take the control Broken: ValueError: no record today"):
        simulate(model.system, x0, "unconstrained", 0.1, 1e-3, 1e-3, "rk4", control)


def test_a_joint_pd_whose_joints_are_reordered_runs_on_the_python_path(monkeypatch):
    # The record lists targets in the robot's actuated order; a controller driving other joints
    # (or the same ones in another order) has none, and its runs take the Python path.
    model = pendulum()
    pd = JointPD(model.info["bridge"], KP, KD, np.array([TARGET]), gravity=False)
    assert pd.compiled_record(model.info["bridge"].model) is not None
    pd.dofs = np.array([1])  # the elbow, not the actuated shoulder
    assert pd.compiled_record(model.info["bridge"].model) is None
