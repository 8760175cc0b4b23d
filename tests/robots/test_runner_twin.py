"""Raibert's runner computed by a compiled twin (robots/runner_twin.py): ``runner_control``, fed
``RunnerRaibert.compiled_record`` as the controller's resets leave it, gives the torques
``RunnerRaibert.__call__`` gives, at every state the controller was called at along real runs of
the quadruped's pronk (in place and forward, Python path), in flight and stance, legs falling
and rising; the record's memory (stance time, thrust, bias) reaches those torques; the bound and
subclasses that change the law have no record."""

from __future__ import annotations

import dataclasses

import legsim.compiled.visit as compiled_visit
import legsim.relaxed.integrate as integrate
import numpy as np
import pinocchio as pin
import pytest
from legsim.robots import raibert, runner_laws, runner_twin
from legsim.robots.bridge.control_records import CTRL_RUNNER

from legsim.scene import load_scene

SCENES = ("quadruped_pronk", "quadruped_run")
T_FINAL = 1.2  # s: about four hops, the memory adapted at each
MEMORY = ("stance_time", "thrust", "bias")


@dataclasses.dataclass
class Call:
    """One call of the controller: its mode, time (s), state, record then and torques (N m)."""

    mode: str
    t: float
    x: np.ndarray
    record: list[float]
    u: np.ndarray


@dataclasses.dataclass
class Run:
    controller: raibert.RunnerRaibert
    first_record: list[float]  # the record before the run's first reset
    calls: list[Call]


def python_run(name: str) -> Run:
    """The scene run on the Python path (the runner's torques by ``__call__``), every call of
    the controller recorded with its record at that time (the preview's clones' too: theirs
    is after their own reset)."""
    scene = load_scene(name, [f"integrator.t_final={T_FINAL}"])
    controller = scene.control
    model = controller.bridge.model
    first = controller.compiled_record(model)
    calls: list[Call] = []
    law = raibert.RunnerRaibert.__call__

    def recorded(self, mode, t, x):
        u = law(self, mode, t, x)
        calls.append(Call(mode, t, x.copy(), self.compiled_record(model), u.copy()))
        return u

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(raibert.RunnerRaibert, "__call__", recorded)
        for module in (integrate, compiled_visit):
            patch.setattr(module, "runs_compiled", lambda run, data: False)
        ex = scene.simulate()
    assert ex.status == "finished", ex.message
    return Run(controller, first, calls)


@pytest.fixture(scope="module", params=SCENES)
def run(request) -> Run:
    return python_run(request.param)


def stance_of(controller: raibert.RunnerRaibert, mode: str) -> np.ndarray:
    """1.0 for each leg (in the controller's, the record's order) whose contact is active in mode."""
    active = set(controller.bridge.active_contacts(mode))
    return np.array([1.0 if leg.contact in active else 0.0 for leg in controller.legs])


def twin_torques(controller: raibert.RunnerRaibert, call: Call, record: list[float], at: int = 3) -> np.ndarray:
    """``runner_control`` at the call's state for ``record`` placed at p[at:] (after entries it
    must not read), with gravity from Pinocchio's Python bindings."""
    model, n = controller.bridge.model, controller.n
    p = np.concatenate([np.full(at, np.nan), record])
    gravity = pin.computeGeneralizedGravity(model, model.createData(), call.x[:n])
    u = np.full(controller.count, np.nan)
    runner_control(call.x, n, p, at, stance_of(controller, call.mode), gravity, u)
    return u


runner_control = runner_twin.runner_control


def relative_error(a: np.ndarray, b: np.ndarray) -> float:
    """max |a - b| over max(|b|, 1 N m)."""
    return float(np.max(np.abs(a - b)) / max(float(np.max(np.abs(b))), 1.0))


def test_runner_control_gives_the_controllers_torques_along_the_run(run):
    # The same scalar laws on both paths, compiled by numba from their source; equal to rounding,
    # not to the bit: numba's math.hypot is the C library's and CPython's its own, and numba
    # computes y**2 as y * y where CPython calls pow; each differs from the other in the last bit
    # for some arguments (the pronk in place matches to the bit, the forward run to 3e-14).
    errors = [relative_error(twin_torques(run.controller, c, c.record), c.u) for c in run.calls]
    assert max(errors) <= 1e-12
    # the states cover the law's branches: flight legs falling and rising, one leg and both in stance
    n = run.controller.n
    stances = [stance_of(run.controller, c.mode).sum() for c in run.calls]
    falling = [c.x[n + 1] < 0.0 for c in run.calls]
    assert {0.0, 1.0, 2.0} <= set(stances)
    flight_falling = {f for s, f in zip(stances, falling, strict=True) if s == 0.0}
    assert flight_falling == {True, False}
    assert len(run.calls) > 1000


def leg_entries(record: list[float], name: str) -> list[float]:
    """The entry ``name`` (``runner_twin.LEG_FIELDS``) of each leg in the record."""
    at = runner_twin.LEG_FIELDS.index(name)
    count = int(record[runner_twin.H_LEGS])
    return [record[runner_twin.RUNNER_HEAD + runner_twin.RUNNER_LEG * i + at] for i in range(count)]


def with_entries(record: list[float], name: str, values: list[float]) -> list[float]:
    out = list(record)
    at = runner_twin.LEG_FIELDS.index(name)
    for i, value in enumerate(values):
        out[runner_twin.RUNNER_HEAD + runner_twin.RUNNER_LEG * i + at] = value
    return out


def test_each_memory_value_of_the_record_reaches_the_torques(run):
    # The comparison above fails when a memory value is not written at the resets: the record
    # with that value as it was before the run's first reset gives other torques along the run
    # (the bias only with the integral term: without it, it stays 0).
    names = MEMORY if run.controller.gains.k_i > 0.0 else ("stance_time", "thrust")
    for name in names:
        stale_values = leg_entries(run.first_record, name)
        changed = [c for c in run.calls if leg_entries(c.record, name) != stale_values]
        assert changed, f"the run's resets never changed {name}"
        stale = [twin_torques(run.controller, c, with_entries(c.record, name, stale_values)) for c in changed]
        assert max(relative_error(u, c.u) for u, c in zip(stale, changed, strict=True)) > 1e-6, name


def test_the_record_lays_out_the_gains_and_legs_where_the_twin_reads_them():
    controller = load_scene("quadruped_run", ["integrator.t_final=0.1"]).control
    model = controller.bridge.model
    record = controller.compiled_record(model)
    legs, g = controller.legs, controller.gains
    assert len(record) == runner_twin.record_size(len(legs)) == runner_twin.RUNNER_HEAD + 2 * runner_twin.RUNNER_LEG
    assert record[runner_twin.H_KIND] == CTRL_RUNNER and record[runner_twin.H_LEGS] == len(legs)
    assert record[runner_twin.H_KP_JOINT] == g.kp_joint and record[runner_twin.H_LEG_LENGTH] == g.leg_length
    frames = {c.name: c.frame for c in controller.bridge.contacts if hasattr(c, "frame")}
    assert leg_entries(record, "frame") == [model.getFrameId(frames[leg.contact]) for leg in legs]
    assert leg_entries(record, "u_knee") == [leg.u_knee for leg in legs]
    assert leg_entries(record, "thrust") == [leg.thrust for leg in legs]
    # the twin tells the legs in stance by their foot frames
    active = {model.getFrameId(frames[legs[1].contact])}
    np.testing.assert_array_equal(runner_twin.stance_flags(record, active), [0.0, 1.0])


def test_the_twin_calls_the_laws_the_controller_calls():
    # one source: runner_twin compiles runner_laws' functions, which the controller calls as Python
    assert runner_twin.stance_torques is runner_laws.stance_torques
    assert runner_twin.pronk_flight_torques is runner_laws.pronk_flight_torques
    assert raibert.touchdown_angle is runner_laws.touchdown_angle


class OwnStance(raibert.RunnerRaibert):
    def _stance(self, leg, s, attitude, unload=False):
        return 0.0, 0.0


class OwnReset(raibert.RunnerRaibert):
    def reset(self, mode, t, x):
        super().reset(mode, t, x)


def test_the_bound_and_a_subclass_changing_the_law_have_no_record():
    bound = load_scene("quadruped_bound", ["integrator.t_final=0.1"]).control
    assert bound.compiled_record(bound.bridge.model) is None
    pronk = load_scene("quadruped_pronk", ["integrator.t_final=0.1"]).control
    model = pronk.bridge.model
    copies = {kind: kind(pronk.bridge, pronk.legs, pronk.gains, True) for kind in (OwnStance, OwnReset)}
    assert copies[OwnStance].compiled_record(model) is None
    # a subclass may change the reset: its values reach the twin through the record
    assert copies[OwnReset].compiled_record(model) == pronk.compiled_record(model)
    # another robot's model
    assert pronk.compiled_record(bound.bridge.model) is None
