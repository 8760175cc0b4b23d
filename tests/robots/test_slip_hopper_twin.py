"""The SLIP hopper's compiled twins (robots/slip_hopper_twin.py) and Raibert's foot placement
computed by them (raibert.SlipRaibert.compiled_record).

The reference is the Python path: the hopper's Python callables, the controller evaluated by
Python at every stage. The twins do the same arithmetic in the same order, so their values
agree to 1e-12 and runs to rounding amplified over the run (1e-9, as the other parity tests).
"""

import itertools
import math

import numpy as np
import pytest
from legsim.robots import raibert, slip_hopper, slip_hopper_twin
from legsim.robots.controllers import JointPD

import legsim.compiled as compiled
from legsim.bench import robots as bench_robots
from legsim.bench.cases import BenchError
from legsim.compiled import without_compiled
from legsim.relaxed import simulate
from legsim.scene import load_scene

from .test_slip_hopper import assert_tracks_the_commanded_speed
from .test_twins import assert_same_run, close

RNG = np.random.default_rng(18)
M, K, L, G = 1.0, 500.0, 1.0, 9.81  # the slip_raibert scene's hopper (kg, N/m, m, m/s^2)


def controller(l=L, stance_time=0.14):  # noqa: E741 -- the scene's parameter name
    """The slip_raibert scene's controller (speed 1.5 m/s, k_x 0.1 s, k_swing 20 1/s)."""
    return raibert.SlipRaibert(l, 1.5, 0.1, 20.0, stance_time)


def flight_states(n):
    """Flight states (x, z, psi, xd, zd): rising and falling, legs forward and back, speeds
    whose foot placement reaches the 0.9 l cap."""
    x, z, psi, xd, zd = RNG.uniform([-1.0, 0.6, -0.7, -2.0, -3.0], [1.0, 1.5, 0.7, 6.0, 3.0], (n, 5)).T
    return np.column_stack([x, z, psi, xd, zd])


def stance_states(n):
    """Stance states (x, z, xd, zd, foot_x): compressed and stretched, compressing and
    extending, and feet farther than l ahead or behind (the liftoff angle's clip)."""
    x, z, xd, zd, ahead = RNG.uniform([-1.0, 0.3, -3.0, -3.0, -1.4], [1.0, 1.2, 3.0, 3.0, 1.4], (n, 5)).T
    return np.column_stack([x, z, xd, zd, x + ahead])


@pytest.mark.parametrize("mode, states", [("flight", flight_states(40)), ("stance", stance_states(40))])
@pytest.mark.parametrize("control", [None, "raibert"])
def test_twins_match_the_python_callables(mode, states, control):
    system = slip_hopper.make_system(M, K, L, G)
    data = system.mode_data(mode)
    twin = data.mode.compiled
    for stance_time in (0.1, 0.14, 0.3):
        made = None if control is None else controller(stance_time=stance_time)
        twin.controls(made)(twin.params)  # the record, as Python writes it at an entry
        for x in states:
            u = None if made is None else made(mode, 0.0, x)
            close(twin.field(0.0, x, twin.params), data.mode.field(0.0, x, u))
            close(twin.guards(x, twin.params), [g(x) for g in data.guards])
            close(twin.resets(x, twin.params, 0), data.resets[0](x.copy()))
    if mode == "flight" and control is not None:  # the law is on: the swing rate is not 0
        assert np.count_nonzero([twin.field(0.0, x, twin.params)[2] for x in states]) == len(states)


def test_the_twins_foot_placement_is_touchdown_angle_compiled_from_its_source():
    # One rule: the compiled function is numba's compilation of raibert.touchdown_angle itself.
    assert raibert.touchdown_angle_compiled.py_func is raibert.touchdown_angle
    for xd, stance_time, speed in RNG.uniform([-2.0, 0.05, 0.0], [8.0, 0.4, 3.0], (50, 3)):
        expected = raibert.touchdown_angle(xd, stance_time, 0.1, speed, L)
        assert raibert.touchdown_angle_compiled(xd, stance_time, 0.1, speed, L) == pytest.approx(expected, abs=1e-15)


def scene_run(monkeypatch, python, overrides=()):
    """The slip_raibert scene (or an override of it) with the twins (python=False) or without,
    and how many times Python called the kernel for a visit it entered."""
    calls = []
    real_visit = compiled.run_visit_compiled
    with monkeypatch.context() as m:
        m.setattr(compiled, "run_visit_compiled", lambda *a: calls.append(1) or real_visit(*a))
        if python:
            m.setattr(slip_hopper, "hopper_twins", lambda *a: {"flight": None, "stance": None})
        scene = load_scene("slip_raibert", list(overrides))
        ex = scene.simulate()
    return scene, ex, len(calls)


def test_slip_raibert_runs_compiled_as_on_the_python_path_and_reaches_the_commanded_speed(monkeypatch):
    scene, fast, n_kernel = scene_run(monkeypatch, False)
    _, slow, n_python = scene_run(monkeypatch, True)
    # A controlled run: Python enters every mode (resetting the controller), the kernel steps.
    assert n_python == 0 and n_kernel == len(fast.segments) == len(fast.transitions) + 1
    assert_same_run(fast, slow)
    assert_tracks_the_commanded_speed(scene, fast)


def stance_times(execution):
    """Each stance's duration (s): liftoff exit time minus the touchdown's before it."""
    events = [(tr.name, tr.exit_time) for tr in execution.transitions]
    return np.array([b[1] - a[1] for a, b in itertools.pairwise(events) if (a[0], b[0]) == ("touchdown", "liftoff")])


def test_the_record_is_written_at_every_entry(monkeypatch):
    """T_s, measured at each liftoff, changes from hop to hop (from the 0.3 s assumed before the
    first liftoff to the stances' 0.154 s, then by 1e-4 .. 1e-8 s as the speed converges): a
    twin whose record were written once (the first entry's T_s for the whole run) places the
    feet elsewhere; the twin written at every entry follows the Python path."""
    overrides = ["integrator.t_final=6.0", "controller.parameters.stance_time=0.3"]
    _, fast, n_kernel = scene_run(monkeypatch, False, overrides)
    _, slow, _ = scene_run(monkeypatch, True, overrides)
    durations = stance_times(slow)
    assert len(durations) >= 8 and abs(durations[0] - 0.3) > 0.1 and np.all(np.diff(durations) != 0.0)
    assert n_kernel > 0
    assert_same_run(fast, slow)

    real_write, written = slip_hopper_twin.write_record, set()

    def first_write_only(p, record):
        if id(p) not in written:
            written.add(id(p))
            real_write(p, record)

    monkeypatch.setattr(slip_hopper_twin, "write_record", first_write_only)
    _, frozen, _ = scene_run(monkeypatch, False, overrides)
    assert len(written) == 2  # each mode's record written once
    first_td = [tr.time for tr in slow.transitions if tr.name == "touchdown"]
    frozen_td = [tr.time for tr in frozen.transitions if tr.name == "touchdown"]
    assert first_td[0] == pytest.approx(frozen_td[0], abs=1e-12)  # the first flight's T_s is the scene's
    assert max(abs(a - b) for a, b in zip(first_td, frozen_td, strict=False)) > 1e-3


@pytest.mark.parametrize(
    "method, settings",
    [("rk4", {}), ("dopri5", {"landing": "aim", "rtol": 1e-8, "atol": 1e-8}), ("dop853", {"rtol": 1e-6, "atol": 1e-6})],
)
def test_uncontrolled_hopper_runs_compiled_as_on_the_python_path(monkeypatch, method, settings):
    """Without control the leg keeps its angle (u = 0, the record CTRL_NONE); the default
    hopper (k = 60 N/m) bounces through touchdowns and liftoffs on both paths alike."""
    system = slip_hopper.make_system(1.0, 60.0, 1.0, 9.81)
    x0 = np.array([slip_hopper.INITIAL_STATE[n] for n in slip_hopper.FLIGHT_NAMES])
    calls = []
    real_visit, real_entry = compiled.run_visit_compiled, compiled.enter_compiled
    monkeypatch.setattr(compiled, "run_visit_compiled", lambda *a: calls.append(1) or real_visit(*a))
    monkeypatch.setattr(compiled, "enter_compiled", lambda *a: calls.append(1) or real_entry(*a))
    fast = simulate(system, x0.copy(), "flight", 1.0, 1e-3, 1e-7, method, None, **settings)
    kernel = len(calls)
    slow = simulate(without_compiled(system), x0.copy(), "flight", 1.0, 1e-3, 1e-7, method, None, **settings)
    assert kernel > 0 and len(calls) == kernel
    assert fast.status == "finished" and [tr.name for tr in fast.transitions] == ["touchdown", "liftoff"]
    assert_same_run(fast, slow)
    twin = system.mode_data("flight").mode.compiled
    assert slip_hopper_twin.CONTROL_KINDS[int(twin.params[slip_hopper_twin.P_CTRL])] == "none"
    # With u = 0 the leg leaves the flight at its initial angle: the touchdown's foot is l sin(psi0) ahead.
    td = fast.transitions[0]
    assert td.state_after[4] - td.state_after[0] == pytest.approx(math.sin(x0[2]), abs=1e-14)


def run_with(system, control, t_final=3.0):
    scene = load_scene("slip_raibert")
    return simulate(system, scene.initial_state.copy(), "flight", t_final, 1e-3, 1e-7, "rk4", control, landing="aim")


def test_a_controller_for_another_leg_length_is_computed_with_its_own(monkeypatch):
    """A SlipRaibert made for l = 0.9 m on the 1 m hopper places the foot for 0.9 m on the
    Python path; the record carries its l, so the twin does too (and not the hopper's)."""
    system = load_scene("slip_raibert").model.system
    fast = run_with(system, controller(l=0.9))
    slow = run_with(without_compiled(system), controller(l=0.9))
    assert_same_run(fast, slow)
    own = run_with(system, controller(l=L))
    assert abs(fast.transitions[2].time - own.transitions[2].time) > 1e-3


class ReversedSwing(raibert.SlipRaibert):
    """A law the twin does not know: the swing's sign reversed."""

    def __call__(self, mode, t, x):
        return -super().__call__(mode, t, x)


class CountingEntries(raibert.SlipRaibert):
    """The same law, its entries counted: the twin still computes it."""

    def reset(self, mode, t, x):
        self.entries = getattr(self, "entries", 0) + 1
        super().reset(mode, t, x)


def _held(made):
    made.hold = True
    return made


@pytest.mark.parametrize(
    "make, kernel",
    [
        pytest.param(lambda: ReversedSwing(L, 1.5, 0.1, 20.0, 0.14), False, id="changed-law"),
        pytest.param(lambda: _held(controller()), False, id="held"),
        pytest.param(lambda: lambda t, x: np.array([0.5 - x[2]]), False, id="plain-function"),
        pytest.param(lambda: CountingEntries(L, 1.5, 0.1, 20.0, 0.14), True, id="reset-only-subclass"),
    ],
)
def test_the_twin_computes_only_slip_raibert_and_the_rest_runs_on_the_python_path(monkeypatch, make, kernel):
    system = load_scene("slip_raibert").model.system
    calls = []
    real_visit = compiled.run_visit_compiled
    monkeypatch.setattr(compiled, "run_visit_compiled", lambda *a: calls.append(1) or real_visit(*a))
    fast = run_with(system, make(), 1.0)
    assert (len(calls) > 0) == kernel and fast.status == "finished"
    assert_same_run(fast, run_with(without_compiled(system), make(), 1.0), tol=1e-9 if kernel else 0.0)


def test_a_joint_pd_is_not_taken_for_the_hoppers_controller():
    twin = slip_hopper.make_system(M, K, L, G).mode_data("flight").mode.compiled
    assert twin.controls(JointPD.__new__(JointPD)) is None


def test_bench_slip_raibert_takes_the_compiled_path_or_refuses(monkeypatch):
    knobs = bench_robots.CONTROLLED_SWEEPS["slip-raibert"]
    assert knobs.compiled
    scene = load_scene("slip_raibert")
    assert bench_robots.takes_compiled_path(scene.model.system, scene.control)
    # Without twins the case would run on the Python path under a compiled label: refused.
    monkeypatch.setattr(slip_hopper, "hopper_twins", lambda *a: {"flight": None, "stance": None})
    with pytest.raises(BenchError, match="Python path"):
        bench_robots.make_robot_case("slip-raibert", quick=True)
