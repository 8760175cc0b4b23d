"""``simulate``'s ``until``: a run ends at the hand-back where the caller's condition on the run
so far first holds, its execution the beginning of the run to t_final."""

import numpy as np
import pytest

import legsim.compiled  # noqa: F401 -- the kernel, so that runs are compiled
from legsim.errors import SimulationError
from legsim.relaxed import simulate
from legsim.relaxed.driver import STOP_CHECK_STEPS
from legsim.systems import bouncing_ball


def bounces(count):
    return lambda so_far: len(so_far.transitions) >= count


def run(until=None, t_final=3.0, h=1e-3, python=False):
    system = bouncing_ball.make_system(restitution=0.8)
    return simulate(system, [1.0, 0.0], "flight", t_final, h, 1e-5, until=until, python=python)


@pytest.mark.parametrize("python", [False, True])
def test_a_run_ends_soon_after_until_holds_and_is_the_full_runs_beginning(python):
    full, ended = run(python=python), run(bounces(2), python=python)
    assert ended.status == "finished" and "until held" in ended.message
    assert ended.counters["compiled_steps" if python else "python_steps"] == 0
    second = full.transitions[1].exit_time
    assert second <= ended.t_end < full.t_end
    # The loop hands back every STOP_CHECK_STEPS steps at most: no more are taken past the bounce.
    steps_to_second = np.searchsorted(np.concatenate([s.t for s in full.segments]), second)
    assert ended.counters["steps"] <= steps_to_second + STOP_CHECK_STEPS + 1
    taken = len(ended.transitions)
    assert [tr.exit_time for tr in ended.transitions] == [tr.exit_time for tr in full.transitions[:taken]]
    for mine, theirs in zip(ended.segments, full.segments, strict=False):
        n = len(mine.t) - 1  # the last point may yet move onto a guard point in the longer run
        assert mine.mode == theirs.mode
        np.testing.assert_array_equal(mine.t[:n], theirs.t[:n])
        np.testing.assert_array_equal(mine.x[:n], theirs.x[:n])


def test_a_condition_never_holding_leaves_the_run_as_it_was():
    full, same = run(), run(lambda so_far: False)
    assert same.status == full.status == "finished" and same.t_end == full.t_end
    np.testing.assert_array_equal(same.final_state, full.final_state)
    assert same.counters["steps"] == full.counters["steps"]


def test_a_bad_until_is_refused_by_name():
    with pytest.raises(SimulationError, match="until must be callable"):
        run(until=3)

    def broken(so_far):
        raise KeyError("apex")

    with pytest.raises(SimulationError, match=r"until failed at t=.*KeyError"):
        run(until=broken, h=1e-4)


def test_an_open_visit_grows_in_place_and_hands_back_views_of_it():
    # A hand-back's checks read the open visit as views of one growing array (so a long visit
    # costs its points once, not once per hand-back), the same points as its pieces end to end.
    from legsim.relaxed.assemble import OpenVisit

    rng = np.random.default_rng(0)
    visit, pieces = OpenVisit(mode=0, width=2, capacity=4), []
    for _ in range(40):
        rows = int(rng.integers(1, 50))
        t, x, dx = rng.normal(size=rows), rng.normal(size=(rows, 3)), rng.normal(size=(rows, 3))
        visit.append(t, x, dx)  # wider rows than the mode's state: its first two columns
        visit.append(t[:0], x[:0], dx[:0])  # an empty hand-back adds nothing
        pieces.append((t, x[:, :2], dx[:, :2]))
        views = visit.points()
        for got, column in zip(views, zip(*pieces, strict=True), strict=True):
            np.testing.assert_array_equal(got, np.concatenate(column))
        assert np.shares_memory(views[0], visit.t) and views[0].shape[0] == visit.size
    copies = visit.points(copy=True)
    assert not any(np.shares_memory(c, a) for c, a in zip(copies, (visit.t, visit.x, visit.dx), strict=True))


@pytest.mark.parametrize("python", [False, True])
def test_until_sees_a_long_visit_whole_at_every_hand_back(python):
    # One visit of 20,000 steps (no bounce before 2 s from 30 m), checked at every hand-back:
    # each call of until sees the visit's points so far, contiguous in time, the last the newest.
    seen = []

    def record(so_far):
        (segment,) = so_far.segments
        assert segment.t[0] == 0.0 and np.all(np.diff(segment.t) > 0)
        seen.append(segment.t[-1])
        return False

    system = bouncing_ball.make_system(restitution=0.8)
    ex = simulate(system, [30.0, 0.0], "flight", 2.0, 1e-4, 1e-5, until=record, python=python)
    assert ex.status == "finished" and len(ex.segments) == 1 and not ex.transitions
    assert len(seen) >= 20_000 // STOP_CHECK_STEPS and np.all(np.diff(seen) > 0)


def test_where_an_until_run_ends_does_not_depend_on_a_progress_callback_or_the_clock():
    """The hand-backs at which until is asked come every STOP_CHECK_STEPS steps exactly: with a
    progress callback (whose pace the clock sets, here slowed by a sleep) the run ended at other
    hand-backs, so its end time and counters changed with the machine's load."""
    import time

    def slow_progress(t, t0, t_final):
        time.sleep(0.002)

    plain = run(bounces(2))
    system = bouncing_ball.make_system(restitution=0.8)
    watched = simulate(system, [1.0, 0.0], "flight", 3.0, 1e-3, 1e-5, until=bounces(2), progress=slow_progress)
    assert watched.t_end == plain.t_end
    assert watched.counters["steps"] == plain.counters["steps"]
    np.testing.assert_array_equal(watched.final_state, plain.final_state)
