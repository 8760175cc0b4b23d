"""Every option of ``simulate`` runs compiled, and the compiled run is the interpreted run of the
same loop to the bit: landing rules (dense included), fixed and error-controlled steps, held
and stage-wise controllers, joint crossings, first entries in a strip, Zeno continuations and
``t_eval``. The kernel and the Python loop are one source, so any difference is a defect."""

from __future__ import annotations

import numpy as np
import pytest

from helpers.compiled_models import paddle, two_balls, wall
from legsim import simulate
from legsim.relaxed import driver


def both_paths(monkeypatch, *args, **kwargs):
    compiled = simulate(*args, **kwargs)
    with monkeypatch.context() as m:
        m.setattr(driver, "KERNEL", None)
        interpreted = simulate(*args, **kwargs)
    return compiled, interpreted


def assert_same(compiled, interpreted):
    assert compiled.counters["python_steps"] == 0 and compiled.counters["compiled_steps"] == compiled.steps > 0
    assert interpreted.counters["compiled_steps"] == 0 and interpreted.settings["path"] == "python"
    assert compiled.status == interpreted.status and compiled.message == interpreted.message
    assert [tr.name for tr in compiled.transitions] == [tr.name for tr in interpreted.transitions]
    assert [tr.time for tr in compiled.transitions] == [tr.time for tr in interpreted.transitions]
    for a, b in zip(compiled.segments, interpreted.segments, strict=True):
        assert a.mode == b.mode
        assert np.array_equal(a.t, b.t) and np.array_equal(a.x, b.x) and np.array_equal(a.dx, b.dx)
    for name in ("steps", "halvings", "error_rejections", "field_evals", "guard_evals", "reset_evals"):
        assert compiled.counters[name] == interpreted.counters[name], name


RULES = [
    ("rk4", "halve", {}),
    ("rk4", "aim", {}),
    ("bs32", "dense", {"rtol": 1e-6}),
    ("dopri5", "dense", {"rtol": 1e-8}),
    ("dop853", "aim", {"rtol": 1e-9}),
    ("dop853", "dense", {"rtol": 1e-9}),
    ("ros34pw2", "halve", {}),
    ("ros34pw2", "aim", {"rtol": 1e-7}),
]


@pytest.mark.parametrize(("method", "landing", "tolerances"), RULES, ids=lambda v: str(v))
@pytest.mark.parametrize("hold", [False, True], ids=["every stage", "held"])
def test_a_controlled_run_with_memory_is_the_same_on_both_paths(monkeypatch, method, landing, tolerances, hold):
    system, law = paddle(hold)
    compiled, interpreted = both_paths(
        monkeypatch, system, [1.0, 0.0], "flight", 4.0, 1e-2, 1e-5, method, law, landing=landing, **tolerances
    )
    assert_same(compiled, interpreted)
    assert compiled.status == "finished" and len(compiled.transitions) >= 5
    # The memory is part of the state: it changes at mode entries only (the run's start, then
    # every bounce), as the entry law says: 0.1 -> 0.25 at the start -> 0.325 -> 0.3625.
    assert compiled.state_names["flight"] == ("z", "zd", "level", "t_bounce")
    assert compiled.segments[0].x[0, 2] == pytest.approx(0.25)
    levels = [tr.state_after[2] for tr in compiled.transitions]
    assert levels[0] == pytest.approx(0.325) and levels[1] == pytest.approx(0.3625)
    assert [tr.state_after[3] for tr in compiled.transitions] == [tr.exit_time for tr in compiled.transitions]


def test_simultaneous_impacts_are_resolved_jointly_on_both_paths(monkeypatch):
    compiled, interpreted = both_paths(monkeypatch, two_balls(), [1.0, 1.0, 0.0, 0.0], "falling", 3.0, 1e-2, 1e-5)
    assert_same(compiled, interpreted)
    names = [tr.name for tr in compiled.transitions]
    assert names[0] == "joint_bounce" and set(names) <= {"joint_bounce", "bounce_1", "bounce_2", "rest_1", "rest_2"}


@pytest.mark.parametrize("continuation", [True, False])
def test_accumulating_bounces_take_their_continuation_or_warn_on_both_paths(monkeypatch, continuation):
    compiled, interpreted = both_paths(
        monkeypatch,
        two_balls(),
        [1.0, 0.7, 0.0, 0.0],
        "falling",
        4.0,
        1e-2,
        1e-5,
        continuation=continuation,
        max_transitions=2000,
    )
    assert_same(compiled, interpreted)
    names = {tr.name for tr in compiled.transitions}
    assert ("rest_1" in names or "rest_2" in names) == continuation
    assert [w.kind for w in compiled.warnings] == [w.kind for w in interpreted.warnings]


def test_a_start_inside_a_strip_crosses_it_at_once_on_both_paths(monkeypatch):
    # z = -5e-6 is inside the floor's strip (eps 1e-5) while falling: the first entry crosses.
    system, law = paddle()
    compiled, interpreted = both_paths(monkeypatch, system, [-5e-6, -1.0], "flight", 1.0, 1e-2, 1e-5, control=law)
    assert_same(compiled, interpreted)
    assert compiled.transitions[0].time == 0.0 and compiled.segments[0].t.shape == (1,)


def test_t_eval_samples_the_compiled_execution(monkeypatch):
    times = np.linspace(0.0, 2.0, 41)
    compiled, interpreted = both_paths(
        monkeypatch, two_balls(), [1.0, 0.4, 0.0, 0.0], "falling", 2.0, 1e-2, 1e-5, t_eval=times
    )
    assert_same(compiled, interpreted)
    assert np.array_equal(compiled.evaluated.times, times)
    assert np.array_equal(compiled.evaluated.stack(), interpreted.evaluated.stack())


def test_a_run_that_stops_advancing_ends_stalled_on_both_paths(monkeypatch):
    # The stall rule is part of the loop, so the kernel ends the run where the Python loop does.
    compiled, interpreted = both_paths(monkeypatch, wall(1e-6), [0.0], "a", 10.0, 0.1, 1e-6)
    assert_same(compiled, interpreted)
    assert compiled.status == "stalled"
    assert "mode 'a'" in compiled.message and "transition wall" in compiled.message
    assert len(compiled.transitions) < 2000  # the stall window (1000), not the transition budget (100000)


@pytest.mark.parametrize("python", [False, True], ids=["compiled", "interpreted"])
def test_an_execution_does_not_depend_on_the_output_buffers_it_was_drained_from(monkeypatch, python):
    # Short buffers (16 points) grow as they fill; 2000 points and 100 transitions drain them many
    # times, with visits and crossing records split across drains. The execution must be the one
    # assembled from buffers that hold the whole run.
    from legsim.relaxed import workspace

    args = (two_balls(0.9), [1.0, 0.7, 0.0, 0.0], "falling", 8.0, 4e-3, 1e-5)
    with monkeypatch.context() as m:
        m.setattr(workspace, "FIRST_SHARE", 1)
        whole = simulate(*args, python=python)
    with monkeypatch.context() as m:
        m.setattr(workspace, "FIRST_SHARE", 512)
        assert workspace.shapes(4, 2, 4, 0, 0, 1)["T"][0] == (16,)
        drained = simulate(*args, python=python)
    assert whole.steps > 1000 and len(whole.transitions) > 50
    assert drained.status == whole.status == "finished"
    for name in ("steps", "halvings", "field_evals", "guard_evals", "reset_evals", "transitions"):
        assert drained.counters[name] == whole.counters[name], name
    assert [tr.name for tr in drained.transitions] == [tr.name for tr in whole.transitions]
    assert [tr.time for tr in drained.transitions] == [tr.time for tr in whole.transitions]
    assert [s.exit_time for s in drained.strips] == [s.exit_time for s in whole.strips]
    assert len(drained.segments) == len(whole.segments)
    for a, b in zip(drained.segments, whole.segments, strict=True):
        assert a.mode == b.mode and np.array_equal(a.t, b.t) and np.array_equal(a.x, b.x)
