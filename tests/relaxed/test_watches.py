"""Watches (legsim.relaxed.watches): conditions on a run's states (its stored points and the
middle of each step), on a ball falling freely from z0 = 1 m (no floor): z(t) = z0 - g t^2 / 2,
so z reaches b at t = sqrt(2 (z0 - b) / g)."""

import dataclasses
import math

import numpy as np
import pytest

import legsim.compiled  # noqa: F401 -- the kernel, so that runs are compiled
from legsim.errors import SimulationError
from legsim.relaxed import Watch, simulate
from legsim.relaxed.watches import condition, cubic_least
from legsim.systems import bouncing_ball

G = 9.81


def reach(b):
    return math.sqrt(2 * (1.0 - b) / G)


def below(b):
    return lambda mode, t, x: x[:, 0] - b


def said(t, mode, x):
    return f"z = {x[0]:.6g} at t={t:.17g}"


def run(watches, t_final=2.0, h=1e-2, python=False):
    system = bouncing_ball.make_system(floor=False)
    return simulate(system, [1.0, 0.0], "flight", t_final, h, 1e-3, watches=watches, python=python)


@pytest.mark.parametrize("python", [False, True])
def test_a_stop_ends_the_run_where_its_condition_first_holds(python):
    ex = run([Watch("low", below(0.5), "stop", said)], python=python)
    assert ex.status == "fell"
    assert ex.t_end == pytest.approx(reach(0.5), abs=1e-12)
    assert ex.final_state[0] == pytest.approx(0.5, abs=1e-12)
    assert ex.final_state[1] == pytest.approx(-G * reach(0.5), abs=1e-12)
    assert ex.message == said(ex.t_end, "flight", ex.final_state)
    assert ex.segments[-1].t[-1] == ex.t_end and np.all(np.diff(ex.segments[-1].t) > 0)
    assert ex.counters["python_steps" if not python else "compiled_steps"] == 0


def test_the_earliest_stop_wins_and_names_its_status():
    ex = run([Watch("late", below(0.2), "stop", said), Watch("early", below(0.6), "stop", said, "model_breakdown")])
    assert ex.status == "model_breakdown" and ex.t_end == pytest.approx(reach(0.6), abs=1e-12)


def test_a_long_run_stops_within_the_driver_s_scan_interval():
    from legsim.relaxed.driver import STOP_CHECK_STEPS

    h = 1e-5
    ex = run([Watch("low", below(0.5), "stop", said)], t_final=2.0, h=h)
    assert ex.t_end == pytest.approx(reach(0.5), abs=1e-12)
    assert reach(0.5) / h <= ex.counters["steps"] <= reach(0.5) / h + STOP_CHECK_STEPS + 1


def test_a_time_watch_measures_the_time_its_condition_holds():
    # z < 0.8 from reach(0.8) on, and z > -2 until reach(-2): the time in between
    ex = run([Watch("band", lambda mode, t, x: np.minimum(0.8 - x[:, 0], x[:, 0] + 2.0), "time", counter="band_s")])
    assert ex.status == "finished"
    inside = [reach(0.8), reach(-2.0)]
    outside = ex.t_end - (inside[1] - inside[0])
    assert ex.counters["band_s"] == pytest.approx(outside, abs=1e-12)


def test_a_warning_watch_says_where_its_condition_first_held_and_most():
    ex = run([Watch("low", below(0.9), "warn", said)], t_final=1.0)
    assert ex.status == "finished"
    (warning,) = ex.warnings
    assert warning.kind == "low" and warning.time == pytest.approx(reach(0.9), abs=1e-12)
    assert warning.details["least_time"] == 1.0
    assert warning.details["least_value"] == pytest.approx((1.0 - G / 2) - 0.9, abs=1e-12)


def in_band(mode, t, x):
    """Holds while 0.65 < z < 0.75."""
    return np.abs(x[:, 0] - 0.7) - 0.05


@pytest.mark.parametrize("python", [False, True])
def test_a_condition_holding_only_inside_one_step_is_seen_at_the_steps_middle(python):
    # One step of 0.5 s: z from 1 to -0.23 m, at the step's middle 0.69 m, in the band, which
    # neither stored point is. The interpolant is exact on z's parabola, so the stop and the
    # warning are at the closed-form time, and the warning's least value is the middle's.
    stop = run([Watch("band", in_band, "stop", said)], t_final=0.5, h=0.5, python=python)
    assert stop.status == "fell" and stop.t_end == pytest.approx(reach(0.75), abs=1e-12)
    assert stop.final_state[0] == pytest.approx(0.75, abs=1e-12)
    (warning,) = run([Watch("band", in_band, "warn", said)], t_final=0.5, h=0.5, python=python).warnings
    assert warning.time == pytest.approx(reach(0.75), abs=1e-12) and warning.details["least_time"] == 0.25
    assert warning.details["least_value"] == pytest.approx(abs(1.0 - G / 2 * 0.25**2 - 0.7) - 0.05, abs=1e-12)


APEX_TIME, NEAR = 0.25, 0.005  # s, m: the thrown ball's apex, and how near it the condition holds


def near_apex(mode, t, x):
    """Holds while the thrown ball is within NEAR of its apex height."""
    return (apex_height() - NEAR) - x[:, 0]


def apex_height():
    return 1.0 + G * APEX_TIME**2 / 2


@pytest.mark.parametrize("python", [False, True])
def test_a_condition_holding_between_every_checked_point_is_seen_by_its_rate(python):
    # Thrown up at g APEX_TIME from z = 1, steps of 0.2 s: the condition holds on
    # APEX_TIME +- sqrt(2 NEAR / g) = (0.218, 0.282) s, between the checked points 0.2 and 0.3 s.
    # The value's rate -z' makes the cubic through those two points the value's parabola itself,
    # so the stop is at the closed-form time; without the rate the run does not see it.
    system = bouncing_ball.make_system(floor=False)
    start, enters = [1.0, G * APEX_TIME], APEX_TIME - math.sqrt(2 * NEAR / G)

    def thrown(watch):
        return simulate(system, start, "flight", 0.4, 0.2, 1e-3, watches=[watch], python=python)

    rising = Watch("apex", near_apex, "stop", said, rate=lambda mode, t, x: -x[:, 1])
    stop = thrown(rising)
    assert stop.status == "fell" and stop.t_end == pytest.approx(enters, abs=1e-12)
    assert stop.final_state[0] == pytest.approx(apex_height() - NEAR, abs=1e-12)
    (warning,) = thrown(dataclasses.replace(rising, action="warn")).warnings
    assert warning.time == pytest.approx(enters, abs=1e-12)
    # the deepest point seen is the one the check found, the cubic's least: the apex itself
    assert warning.details["least_time"] == pytest.approx(APEX_TIME, abs=1e-12)
    assert warning.details["least_value"] == pytest.approx(-NEAR, abs=1e-12)
    assert thrown(dataclasses.replace(rising, rate=None)).status == "finished"


@pytest.mark.parametrize("python", [False, True])
def test_each_part_of_a_condition_is_checked_between_points_by_its_own_rate(python):
    # Two parts: one always 1 mm from holding, below the other at every checked point, and the
    # apex condition above. Had the check followed the least part's rate it would not see the
    # apex; each part's own cubic does.
    system = bouncing_ball.make_system(floor=False)

    def value(mode, t, x):
        return np.column_stack([np.full(len(t), 1e-3), near_apex(mode, t, x)])

    def rate(mode, t, x):
        return np.column_stack([np.zeros(len(t)), -x[:, 1]])

    watch = Watch("apex", value, "stop", said, rate=rate)
    ex = simulate(system, [1.0, G * APEX_TIME], "flight", 0.4, 0.2, 1e-3, watches=[watch], python=python)
    assert ex.status == "fell"
    assert ex.t_end == pytest.approx(APEX_TIME - math.sqrt(2 * NEAR / G), abs=1e-12)


def early(mode, t, x):
    """Holds on (0.202, 0.208) s, inside the half step (0.2, 0.3) of steps of 0.2 s."""
    return (t - 0.205) ** 2 - 0.003**2


@pytest.mark.parametrize(
    "other",
    [
        (near_apex, lambda mode, t, x: -x[:, 1]),  # holds later in the same half step (0.218 s)
        (lambda mode, t, x: 0.29 - t, lambda mode, t, x: -np.ones(len(t))),  # holds at the checked 0.3 s
    ],
    ids=["later-in-the-half-step", "at-the-next-checked-point"],
)
def test_the_earliest_part_s_dip_is_the_first_hold(other):
    # The other part comes first among the columns; the early part's dip, found by its own
    # cubic, is the first hold wherever the other part holds after it.
    system = bouncing_ball.make_system(floor=False)

    def value(mode, t, x):
        return np.column_stack([other[0](mode, t, x), early(mode, t, x)])

    def rate(mode, t, x):
        return np.column_stack([other[1](mode, t, x), 2 * (t - 0.205)])

    watch = Watch("two", value, "stop", said, rate=rate)
    ex = simulate(system, [1.0, G * APEX_TIME], "flight", 0.4, 0.2, 1e-3, watches=[watch])
    assert ex.status == "fell" and ex.t_end == pytest.approx(0.202, abs=1e-12)


def shelves(levels):
    """A condition on the falling ball with pieces: z below a level that changes at given times,
    ``levels`` [(from t (s), level (m)), ...] in time order; the piece is the level's index."""

    def piece(mode, t, x):
        return np.searchsorted([start for start, _ in levels], t, side="right").astype(float) - 1

    def value(mode, t, x):
        return x[:, 0] - np.array([level for _, level in levels])[piece(mode, t, x).astype(int)]

    return value, piece


@pytest.mark.parametrize("python", [False, True])
@pytest.mark.parametrize(
    ("levels", "enters"),
    [
        ([(0.0, -10.0), (0.25, 0.8), (0.26, -10.0)], 0.25),  # the first change of piece holds
        ([(0.0, -10.0), (0.25, -9.0), (0.26, 0.8), (0.27, -10.0)], 0.26),  # the second does
    ],
    ids=["first-change", "second-change"],
)
def test_a_value_jumping_where_its_piece_changes_inside_a_step_is_seen(python, levels, enters):
    # The ball falls from z = 1 at steps of 0.2 s; the level jumps to 0.8 m, above the ball
    # (z(0.25) = 0.69 m), for 10 ms inside the half step (0.2, 0.3), so no checked point shows it and
    # the cubic through the half step's ends (the level -10 at both) does not dip. The pieces do:
    # the change is found between the checked points, and the stop is where the level jumps.
    value, piece = shelves(levels)
    watch = Watch("shelf", value, "stop", said, rate=lambda mode, t, x: x[:, 1], piece=piece)
    ex = run([watch], t_final=0.4, h=0.2, python=python)
    assert ex.status == "fell" and ex.t_end == pytest.approx(enters, abs=1e-12)
    assert run([dataclasses.replace(watch, piece=None)], t_final=0.4, h=0.2, python=python).status == "finished"
    # a part its watch rules out between two checked points is not searched there
    ruled_out = dataclasses.replace(watch, clear=lambda mode, ta, xa, tb, xb: np.ones((len(ta), 1), bool))
    assert run([ruled_out], t_final=0.4, h=0.2, python=python).status == "finished"
    (warning,) = run([dataclasses.replace(watch, action="warn")], t_final=0.4, h=0.2, python=python).warnings
    assert warning.time == pytest.approx(enters, abs=1e-12)


def probe_at(time):
    """A probe giving ``time`` between the two checked points around it, nan between the others."""

    def probe(mode, t, x):
        inside = (t[:-1] < time) & (time < t[1:])
        return np.where(inside, time, np.nan)[:, None]

    return probe


@pytest.mark.parametrize("python", [False, True])
@pytest.mark.parametrize(
    ("levels", "probed", "enters"),
    [
        ([(0.0, -10.0), (0.25, 0.8), (0.26, -10.0)], 0.255, 0.25),  # the probe lies in the jump
        ([(0.0, -10.0), (0.25, -9.0), (0.26, 0.8), (0.27, -10.0)], 0.255, 0.26),  # the way back holds
    ],
    ids=["probed-piece", "after-the-probe"],
)
def test_a_piece_left_and_returned_to_between_two_checked_points_is_seen_at_a_probe(python, levels, probed, enters):
    # The shelves above, each piece numbered by its level, the last one the first's: the ball is on
    # piece 0 at both ends of the half step (0.2, 0.3), so no change of piece shows between them. A
    # probe at 0.255 s reads another piece there; the ways out (to 0.255) and back are searched
    # across their changes, and the stop is where the level jumps above the ball.
    value, piece = shelves(levels)

    def returning(mode, t, x):
        labels = piece(mode, t, x)
        return np.where(labels == len(levels) - 1, 0.0, labels)

    watch = Watch("shelf", value, "stop", said, rate=lambda mode, t, x: x[:, 1], piece=returning)
    assert run([watch], t_final=0.4, h=0.2, python=python).status == "finished"  # the premise
    probing = dataclasses.replace(watch, probe=probe_at(probed))
    ex = run([probing], t_final=0.4, h=0.2, python=python)
    assert ex.status == "fell" and ex.t_end == pytest.approx(enters, abs=1e-12)
    (warning,) = run([dataclasses.replace(probing, action="warn")], t_final=0.4, h=0.2, python=python).warnings
    assert warning.time == pytest.approx(enters, abs=1e-12)
    # a probe reading the ends' piece finds nothing; a part ruled clear is not searched
    assert run([dataclasses.replace(watch, probe=probe_at(0.27 if enters == 0.25 else 0.28))], t_final=0.4,
               h=0.2).status == "finished"  # fmt: skip
    ruled_out = dataclasses.replace(probing, clear=lambda mode, ta, xa, tb, xb: np.ones((len(ta), 1), bool))
    assert run([ruled_out], t_final=0.4, h=0.2).status == "finished"


def dip(centre):
    """A parabola on the ball's time: 1000 (t - centre)^2 - 0.01, below zero for sqrt(1e-5) s
    either side of ``centre``, and its rate."""
    return (lambda t: 1000.0 * (t - centre) ** 2 - 0.01), (lambda t: 2000.0 * (t - centre))


@pytest.mark.parametrize(
    ("centre", "during"),
    [(0.23, lambda t: t < 0.25), (0.28, lambda t: t >= 0.25)],
    ids=["before-the-change", "after-the-change"],
)
def test_a_dip_on_either_side_of_a_change_of_piece_is_found_by_that_side_s_cubic(centre, during):
    # Steps of 0.2 s, the piece changing at 0.25 s inside the half step (0.2, 0.3); on one side
    # of the change the value is a parabola dipping below zero around ``centre`` (not at the
    # change itself), on the other it is 10. The cubic through the half step's ends does not
    # dip; the cubic of the dipping side, through its end and the change (a parabola's own),
    # does, and the stop is where the parabola first reaches zero: centre - sqrt(1e-5).
    value_at, rate_at = dip(centre)

    def value(mode, t, x):
        return np.where(during(t), value_at(t), 10.0)

    def rate(mode, t, x):
        return np.where(during(t), rate_at(t), 0.0)

    def piece(mode, t, x):
        return (t >= 0.25).astype(float)

    watch = Watch("dip", value, "stop", said, rate=rate, piece=piece)
    ex = run([watch], t_final=0.4, h=0.2)
    assert ex.status == "fell" and ex.t_end == pytest.approx(centre - math.sqrt(1e-5), abs=1e-12)
    assert run([dataclasses.replace(watch, piece=None)], t_final=0.4, h=0.2).status == "finished"


def test_a_cubic_leaving_its_start_level_has_its_least_found():
    # p(s) = 0.1 - s^2 + s^3 (slope 0 at the start): least at s = 2/3, 0.1 - 4/27
    s, least = cubic_least(*(np.array([w]) for w in (0.1, 0.1, 0.0, 1.0, 1.0)))
    assert s[0] == pytest.approx(2 / 3, abs=1e-15) and least[0] == pytest.approx(0.1 - 4 / 27, abs=1e-15)


def test_a_nan_part_hides_no_other():
    assert np.array_equal(condition(np.array([[np.nan, -1.0], [np.nan, np.nan], [2.0, 1.0]])), [-1.0, np.nan, 1.0],
                          equal_nan=True)  # fmt: skip


def test_the_least_of_a_cubic_is_its_interior_minimum():
    # against the local minima of a fine grid over random cubics given by their ends' values and
    # slopes (a cubic has one at most; where the ends hold nothing and it is below zero, it is
    # the least of the cubic, which is what the check between points needs)
    rng = np.random.default_rng(7)
    v0, v1, r0, r1 = rng.normal(size=(4, 500))
    dt = rng.uniform(0.1, 2.0, size=500)
    s, least = cubic_least(v0, v1, r0, r1, dt)
    grid = np.linspace(0.0, 1.0, 200_001)[:, None]
    h00, h10 = 2 * grid**3 - 3 * grid**2 + 1, grid**3 - 2 * grid**2 + grid
    h01, h11 = -2 * grid**3 + 3 * grid**2, grid**3 - grid**2
    p = h00 * v0 + h10 * dt * r0 + h01 * v1 + h11 * dt * r1
    local = (p[1:-1] < p[:-2]) & (p[1:-1] <= p[2:])
    assert np.array_equal(local.any(axis=0), ~np.isnan(s))
    found = local.any(axis=0)
    where = np.argmax(local, axis=0)[found] + 1
    assert np.allclose(least[found], p[where, np.flatnonzero(found)], atol=1e-12)
    assert np.allclose(s[found], grid[where, 0], atol=1e-5)


def test_bad_watches_are_refused_by_name():
    with pytest.raises(SimulationError, match="action must be one of"):
        Watch("w", below(0), "explode", said)
    with pytest.raises(SimulationError, match="needs message"):
        Watch("w", below(0), "stop")
    with pytest.raises(SimulationError, match="needs a counter"):
        Watch("w", below(0), "time")
    with pytest.raises(SimulationError, match="'nope' is not a run status"):
        Watch("w", below(0), "stop", said, "nope")
    with pytest.raises(SimulationError, match=r"must be legsim\.relaxed\.Watch"):
        run([lambda mode, t, x: x])
    with pytest.raises(SimulationError, match="rate must be None or a function"):
        Watch("w", below(0), "stop", said, rate=1.0)
    with pytest.raises(SimulationError, match="piece must be None or a function piece"):
        Watch("w", below(0), "stop", said, piece=lambda mode, t, x: np.zeros(len(t)))
    with pytest.raises(SimulationError, match="clear must be None or a function clear"):
        Watch("w", below(0), "stop", said, rate=lambda mode, t, x: x[:, 1], clear=lambda *args: None)
    value, piece = shelves([(0.0, -10.0), (0.25, 0.8)])
    with pytest.raises(SimulationError, match=r"watch 'w': its clear gave shape \(1, 2\) for 1 stretches of 1 parts"):
        run([Watch("w", value, "stop", said, rate=lambda mode, t, x: x[:, 1], piece=piece,
                   clear=lambda mode, ta, xa, tb, xb: np.zeros((len(ta), 2), bool))], t_final=0.4, h=0.2)  # fmt: skip
    with pytest.raises(SimulationError, match="probe must be None or a function probe"):
        Watch("w", below(0), "stop", said, rate=lambda mode, t, x: x[:, 1], probe=probe_at(0.25))
    with pytest.raises(SimulationError, match=r"watch 'w': its probe gave shape \(\d+, 2\) for \d+ points of 1 parts"):
        run([Watch("w", value, "stop", said, rate=lambda mode, t, x: x[:, 1], piece=piece,
                   probe=lambda mode, t, x: np.zeros((len(t) - 1, 2)))], t_final=0.4, h=0.2)  # fmt: skip
    with pytest.raises(SimulationError, match="watch 'w': its probe failed in mode 'flight': ZeroDivisionError"):
        run([Watch("w", value, "stop", said, rate=lambda mode, t, x: x[:, 1], piece=piece,
                   probe=lambda mode, t, x: 1 / 0)], t_final=0.4, h=0.2)  # fmt: skip
    value, _ = shelves([(0.0, -10.0)])
    with pytest.raises(SimulationError, match=r"watch 'w': its pieces' shape \(\d+, 2\) is not its values' \(\d+, 1\)"):
        run([Watch("w", value, "stop", said, rate=lambda mode, t, x: x[:, 1],
                   piece=lambda mode, t, x: np.zeros((len(t), 2)))])  # fmt: skip
    with pytest.raises(SimulationError, match="watch 'w': its rate failed in mode 'flight': ZeroDivisionError"):
        run([Watch("w", below(0.5), "stop", said, rate=lambda mode, t, x: 1 / 0)])
    with pytest.raises(SimulationError, match=r"watch 'w' gave values of shape \(1,\) for \d+ points"):
        run([Watch("w", lambda mode, t, x: np.zeros(1), "stop", said)])
    with pytest.raises(SimulationError, match=r"watch 'w': its rates' shape \(\d+, 2\) is not its values' \(\d+, 1\)"):
        run([Watch("w", below(0.5), "stop", said, rate=lambda mode, t, x: np.zeros((len(t), 2)))])
