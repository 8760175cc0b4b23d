"""A system's modes are built once: a run keeps its tables (the modes it made ready, their
transitions and functions) on the system for the next run under the same law
(``legsim.relaxed.tables.kept_tables``). A later run prepares no mode again and gives the same
execution to the bit as a run on tables of its own; runs of one system in several threads take
turns, and a run after a failing one builds tables of its own."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from legsim import HybridSystem, Mode, ModelError, SimulationError, Transition, model_function, simulate
from legsim.relaxed import tables as run_tables
from legsim.scene import load_scene


def _same(a, b) -> None:
    assert (a.status, a.final_mode, a.t_end) == (b.status, b.final_mode, b.t_end)
    assert [(tr.name, tr.time) for tr in a.transitions] == [(tr.name, tr.time) for tr in b.transitions]
    assert np.array_equal(a.final_state, b.final_state)
    assert a.counters["field_evals"] == b.counters["field_evals"]


@pytest.fixture
def prepared(monkeypatch):
    """The modes each run makes ready, by name, one list per run (appended as they happen)."""
    runs: list[list[str]] = []
    original = run_tables.RunTables.prepare

    def counting(self, row):
        runs[-1].append(self.names[row])
        return original(self, row)

    monkeypatch.setattr(run_tables.RunTables, "prepare", counting)
    return runs


def test_a_second_run_prepares_no_mode_and_gives_the_same_execution(prepared):
    scene = load_scene("pronk", ["integrator.t_final=1.0"])
    prepared.append([])
    first = scene.simulate()
    prepared.append([])
    second = scene.simulate()
    # the hopper lands on either leg or both: every mode it entered was built by the first run
    assert len(prepared[0]) >= 3 and prepared[1] == []
    assert first.counters["python_steps"] == second.counters["python_steps"] == 0
    _same(first, second)
    # and the same as a run on tables of its own (a fresh system)
    prepared.append([])
    _same(second, load_scene("pronk", ["integrator.t_final=1.0"]).simulate())
    assert len(prepared[2]) == len(prepared[0])


def test_the_python_loop_after_a_compiled_run_says_so_and_the_next_compiled_run_does_not():
    scene = load_scene("pronk", ["integrator.t_final=0.5"])
    system, x0 = scene.model.system, scene.initial_state

    def run(python: bool):
        return simulate(system, x0, scene.initial_mode, 0.5, 1e-3, 1e-4, python=python)

    compiled, plain, again = run(False), run(True), run(False)
    assert compiled.counters["python_steps"] == 0 and "python_reason" not in compiled.settings
    assert plain.counters["compiled_steps"] == 0
    assert plain.settings["python_reason"] == "the run asked for plain Python (simulate(python=True))"
    assert again.counters["python_steps"] == 0 and "python_reason" not in again.settings
    _same(compiled, again)


def test_runs_of_one_robot_in_threads_at_once_each_give_the_execution_of_a_run_alone():
    # The robot's native model keeps one scratch (Pinocchio's data): two runs at once would
    # share it and corrupt the heap, so runs of one system take turns.
    scene = load_scene("pronk", ["integrator.t_final=1.0"])
    alone = scene.simulate()
    results: list = [None] * 4

    def run(k: int) -> None:
        results[k] = scene.simulate()

    threads = [threading.Thread(target=run, args=(k,)) for k in range(len(results))]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert len(alone.transitions) > 3
    for result in results:
        _same(alone, result)


def _ladder(fail_at: str | None = None) -> HybridSystem:
    """A point rising at 1/s through rungs at x = 1, 2, ...: mode k's guard is x - (k + 1)
    crossing into mode k + 1 (expanded on first use); expanding ``fail_at`` raises."""

    def expand(name: str):
        if name == fail_at:
            raise RuntimeError(f"no rung {name}")
        k = int(name)
        mode = Mode(1, lambda t, x, u: np.array([1.0]), names=("x",))
        return mode, [Transition(name, str(k + 1), lambda x, k=k: k + 1 - x[0], name=f"rung{k}")]

    return HybridSystem({}, expand=expand, dims=lambda name: 1, name="ladder")


def test_a_run_that_fails_building_a_mode_keeps_no_tables_and_the_next_run_builds_its_own(prepared):
    system = _ladder(fail_at="3")
    prepared.append([])
    with pytest.raises(ModelError, match=r"no rung 3"):
        simulate(system, [0.5], "0", 5.0, 1e-2, 1e-4)
    assert "tables" not in system.run_scratch
    prepared.append([])
    short = simulate(system, [0.5], "0", 2.2, 1e-2, 1e-4)  # stops before the broken rung
    assert [tr.target for tr in short.transitions] == ["1", "2"]
    assert prepared[1] == ["0", "1", "2"]  # built anew, none taken from the failed run


def _counted_ball(calls: dict[str, int]) -> HybridSystem:
    """A ball falling onto a floor whose bounce counts its reset's calls; a transition from
    'held' whose guard returns a vector, an error ``check_state`` names."""

    def bounce(x):
        calls["reset"] += 1
        return np.array([x[0], -0.8 * x[1]])

    fall = Mode(2, lambda t, x, u: np.array([x[1], -9.81]), names=("z", "zd"))
    modes = {"fall": fall, "held": Mode(2, lambda t, x, u: np.zeros(2), names=("z", "zd"))}
    transitions = [
        Transition("fall", "fall", lambda x: x[0], bounce, name="bounce"),
        Transition("held", "fall", lambda x: np.array([1.0, 1.0]), name="release"),
    ]
    return HybridSystem(modes, transitions, name="counted ball")


def test_a_systems_outputs_are_checked_on_its_first_run_in_a_mode_not_on_every_run():
    # check_state evaluates the field, every guard and every reset once on the initial state; a
    # robot's resets are costly in Python, and the functions do not change between runs.
    calls = {"reset": 0}
    system = _counted_ball(calls)
    first = simulate(system, [1.0, 0.0], "fall", 0.2, 1e-3, 1e-4)
    assert calls["reset"] == 1 and not first.transitions  # the check's call, no bounce yet
    second = simulate(system, [0.5, 0.0], "fall", 0.2, 1e-3, 1e-4)
    assert calls["reset"] == 1
    assert second.final_state[0] == pytest.approx(0.5 - 9.81 * 0.2**2 / 2, rel=1e-9)
    # another mode is checked on its first run, and its error named
    with pytest.raises(ModelError, match=r"guard of transition release"):
        simulate(system, [1.0, 0.0], "held", 0.2, 1e-3, 1e-4)
    # every run still checks the state itself and its domain
    with pytest.raises(SimulationError, match=r"finite"):
        simulate(system, [np.nan, 0.0], "fall", 0.2, 1e-3, 1e-4)
    with pytest.raises(SimulationError, match=r"past the guard of transition bounce"):
        simulate(system, [-1.0, 0.0], "fall", 0.2, 1e-3, 1e-4)


@model_function
def free_fall(t, x, u, p, dx):
    dx[0] = x[1]
    dx[1] = -p[0]


def test_a_run_that_reached_a_python_mode_leaves_later_runs_compiled_until_they_reach_one():
    """A compiled mode whose bounce leads to a mode of Python callables: a short run that never
    bounces is compiled, before and after a long run that went to the Python loop, and names no
    mode it did not reach; the long run takes the same path each time."""
    from helpers.compiled_models import G, above_floor, paddle_bounce
    from legsim import ModeFunctions

    fly = Mode(2, names=("z", "zd"), functions=ModeFunctions(free_fall, above_floor, paddle_bounce, params=[G, 0.8]))
    slow = Mode(2, lambda t, x, u: np.array([x[1], -G]), names=("z", "zd"))
    system = HybridSystem(
        {"fly": fly, "slow": slow},
        [
            Transition("fly", "slow", name="bounce"),
            Transition("slow", "slow", guard=lambda x: max(x[0], x[1]), reset=lambda x: np.array([x[0], -0.8 * x[1]])),
        ],
    )

    def run(t_final):
        return simulate(system, [1.0, 0.0], "fly", t_final, 1e-3, 1e-6, "rk4")

    short_before, long_first, short_after, long_again = run(0.3), run(2.0), run(0.3), run(2.0)
    assert long_first.settings["path"] == "python" and "mode 'slow'" in long_first.settings["python_reason"]
    for short in (short_before, short_after):
        assert short.settings["path"] == "compiled" and "python_reason" not in short.settings
        assert short.counters["python_steps"] == 0
    _same(short_before, short_after)
    _same(long_first, long_again)
    assert long_again.counters["compiled_steps"] == long_first.counters["compiled_steps"] > 0


def test_a_run_on_the_workspace_another_run_left_gives_the_execution_of_a_fresh_one():
    # The tables keep their last run's workspace for the next run of the same sizes, cleared: a
    # longer run that filled its records, visits and Zeno histories first must leave no trace.
    from helpers.compiled_models import G, above_floor, paddle_bounce
    from legsim import ModeFunctions

    def ball() -> HybridSystem:
        functions = ModeFunctions(free_fall, above_floor, paddle_bounce, params=[G, 0.8])
        fall = Mode(2, names=("z", "zd"), functions=functions)
        return HybridSystem({"fall": fall}, [Transition("fall", "fall", name="bounce")])

    def run(system, t_final, h):
        return simulate(system, [1.0, 0.0], "fall", t_final, h, 1e-4, "dopri5", rtol=1e-8)

    fresh = run(ball(), 1.0, 1e-2)
    system = ball()
    long = run(system, 3.0, 2e-2)
    kept = system.run_scratch["tables"].spare_workspace
    assert kept is not None and len(long.transitions) > len(fresh.transitions) > 0
    again = run(system, 1.0, 1e-2)
    assert system.run_scratch["tables"].spare_workspace[1] is kept[1]  # the same arrays, reused
    _same(again, fresh)
    images = [[tr.state_after.tolist() for tr in run.transitions] for run in (again, fresh)]
    assert images[0] == images[1]
    for seg_a, seg_b in zip(again.segments, fresh.segments, strict=True):
        assert np.array_equal(seg_a.x, seg_b.x) and np.array_equal(seg_a.dx, seg_b.dx)


def test_a_cleared_workspace_is_zero_but_its_point_buffers_as_allocate_leaves_one():
    from legsim.relaxed.workspace import POINT_BUFFERS, allocate, cleared

    ws = allocate(5, 3, 7, 2, 1, 4)
    fresh = allocate(5, 3, 7, 2, 1, 4)
    for array in ws:
        array[...] = 7
    cleared(ws)
    for name, array, new in zip(ws._fields, ws, fresh, strict=True):
        if name in POINT_BUFFERS:
            assert np.all(array == 7), name  # left as they are: a run writes a row before reading it
        else:
            assert np.array_equal(array, new), name
