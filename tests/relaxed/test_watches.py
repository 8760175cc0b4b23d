"""Watches (legsim.relaxed.watches): conditions on a run's states (its stored points and the
middle of each step), on a ball falling freely from z0 = 1 m (no floor): z(t) = z0 - g t^2 / 2,
so z reaches b at t = sqrt(2 (z0 - b) / g)."""

import dataclasses
import math

import numpy as np
import pytest

import legsim.compiled  # noqa: F401 -- the kernel, so that runs are compiled
import legsim.relaxed.between as between
from legsim.errors import SimulationError
from legsim.execution import Segment
from legsim.relaxed import Watch, simulate
from legsim.relaxed.between import cubic_least, cubic_misfits
from legsim.relaxed.watches import condition, refined
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


def probe_at(*times):
    """A probe giving ``times`` between the two checked points around them, nan elsewhere."""

    def probe(mode, t, x):
        out = np.full((len(t) - 1, 1, len(times)), np.nan)
        for q, time in enumerate(times):
            out[(t[:-1] < time) & (time < t[1:]), 0, q] = time
        return out

    return probe


@pytest.mark.parametrize("python", [False, True])
@pytest.mark.parametrize(
    ("levels", "probed", "enters"),
    [
        ([(0.0, -10.0), (0.25, 0.8), (0.26, -10.0)], (0.255,), 0.25),  # the probe lies in the jump
        ([(0.0, -10.0), (0.25, -9.0), (0.26, 0.8), (0.27, -10.0)], (0.255,), 0.26),  # on the way back
        ([(0.0, -10.0), (0.25, 0.8), (0.253, -9.0), (0.26, -10.0)], (0.255,), 0.25),  # on the way out
        # two trips: out to the level -9 and back, then out to the level 0.8 and back, each probed
        ([(0.0, -10.0), (0.22, -9.0), (0.23, -10.0), (0.27, 0.8), (0.28, -10.0)], (0.225, 0.275), 0.27),
        # two trips, the hold on the way back from the second, the probes given latest first
        ([(0.0, -10.0), (0.22, -9.0), (0.23, -10.0), (0.27, -8.0), (0.28, 0.8), (0.29, -10.0)], (0.275, 0.225), 0.28),
    ],
    ids=["probed-piece", "way-back", "way-out", "two-trips", "probes-out-of-order"],
)
def test_a_piece_left_and_returned_to_between_two_checked_points_is_seen_at_a_probe(python, levels, probed, enters):
    # The shelves above, each level's piece numbered by its level, -10's always 0: the ball is on
    # piece 0 at both ends of the half step (0.2, 0.3), so no change of piece shows between them.
    # A probe reads another piece inside; the chain of the ends and the probed points is searched
    # across its changes, and the stop is where the level first jumps above the ball.
    value, _ = shelves(levels)

    def piece(mode, t, x):
        return np.array([level for _, level in levels])[np.searchsorted([a for a, _ in levels], t, "right") - 1] + 10

    watch = Watch("shelf", value, "stop", said, rate=lambda mode, t, x: x[:, 1], piece=piece)
    assert run([watch], t_final=0.4, h=0.2, python=python).status == "finished"  # the premise
    probing = dataclasses.replace(watch, probe=probe_at(*probed))
    ex = run([probing], t_final=0.4, h=0.2, python=python)
    assert ex.status == "fell" and ex.t_end == pytest.approx(enters, abs=1e-12)
    (warning,) = run([dataclasses.replace(probing, action="warn")], t_final=0.4, h=0.2, python=python).warnings
    assert warning.time == pytest.approx(enters, abs=1e-12)
    # a probe reading the ends' piece finds nothing; a part ruled clear is not searched
    assert (
        run([dataclasses.replace(watch, probe=probe_at(0.29))], t_final=0.4, h=0.2, python=python).status == "finished"
    )
    ruled_out = dataclasses.replace(probing, clear=lambda mode, ta, xa, tb, xb: np.ones((len(ta), 1), bool))
    assert run([ruled_out], t_final=0.4, h=0.2, python=python).status == "finished"


def test_a_probe_reads_the_piece_on_its_own_step_s_interpolant():
    # Four stored steps of sin(5 t) (not a polynomial: another step's cubic gives other values),
    # refined to checked points; the piece is read from the state (x itself near the crests, where
    # |x| > 0.93, else 0), one probe halfway through each checked interval. Where the piece there differs from the
    # interval's, the detour is the probe's time and that piece, read on the interpolant of the
    # interval's own stored step (``Segment.interpolate``), and nowhere else.
    t = np.array([0.0, 0.4, 0.8, 1.2, 1.6])
    stored = (t, np.sin(5 * t)[:, None], 5 * np.cos(5 * t)[:, None])
    checked_t, checked_x = refined(*stored)
    watch = Watch("w", lambda mode, t, x: x[:, 0], "warn", said, rate=lambda mode, t, x: np.ones(len(t)),
                  piece=lambda mode, t, x: np.where(np.abs(x[:, 0]) > 0.93, x[:, 0], 0.0))  # fmt: skip
    pieces = watch.pieces("m", checked_t, checked_x)
    probes = (checked_t[:-1] + 0.5 * np.diff(checked_t))[:, None, None]
    unsmooth = pieces[:-1] != pieces[1:]
    times, labels = between._detours(watch, "m", checked_t, pieces, probes, unsmooth, stored)
    at_probes = Segment("m", *stored).interpolate(probes[:, 0, 0])[:, 0]
    expected = np.where(np.abs(at_probes) > 0.93, at_probes, 0.0)
    other = ~unsmooth[:, 0] & (expected != pieces[:-1, 0])
    assert other.sum() >= 2
    assert np.array_equal(~np.isnan(times[:, 0, 0]), other)
    assert np.array_equal(labels[other, 0, 0], expected[other]) and np.array_equal(
        times[other, 0, 0], probes[other, 0, 0]
    )


def narrow_dip(centre, width=0.02):
    """0.05 - 0.1 exp(-((t - centre) / width)^2) on the ball's time, below zero where
    |t - centre| < width sqrt(ln 2), and its rate."""

    def value(mode, t, x):
        return 0.05 - 0.1 * np.exp(-(((t - centre) / width) ** 2))

    def rate(mode, t, x):
        return 0.2 * (t - centre) / width**2 * np.exp(-(((t - centre) / width) ** 2))

    return value, rate


@pytest.mark.parametrize("python", [False, True])
def test_a_dip_the_cubic_between_two_checked_points_misses_is_found_by_the_step_s_misfit(python, monkeypatch):
    # Steps of 0.2 s; the value dips below zero around t = 0.23 s for 33 ms, inside the half step
    # (0.2, 0.3). At the checked points it is above zero (0.0395 at 0.2 s, 0.05 at 0.3 and 0.4 s),
    # and the cubic through the half step's ends and rates stays above zero (its least, 0.019, at
    # 0.229 s). The step's middle lies 0.045 from the cubic through the step's ends: the value is
    # that far from a cubic there, so the half step is searched where its cubic comes within that
    # of zero, and the stop is where the value first reaches zero: 0.23 - 0.02 sqrt(ln 2).
    value, rate = narrow_dip(0.23)
    watch = Watch("narrow", value, "stop", said, rate=rate)
    ex = run([watch], t_final=0.4, h=0.2, python=python)
    assert ex.status == "fell" and ex.t_end == pytest.approx(0.23 - 0.02 * math.sqrt(math.log(2.0)), abs=1e-12)
    # the premise: without the misfit's margin the cubic alone does not show it
    monkeypatch.setattr(between, "cubic_misfits", lambda t, v, r, unsmooth: np.zeros((len(t) - 1, v.shape[1])))
    assert run([watch], t_final=0.4, h=0.2, python=python).status == "finished"


@pytest.mark.parametrize("python", [False, True])
def test_a_later_hold_at_a_step_s_middle_does_not_hide_an_earlier_dip(python):
    # The narrow dip above, and from t = 0.28 s the value falling away (by 200 (t - 0.28)^2, -0.03
    # at the step's middle, 0.3 s, the first checked point that holds): the check before that
    # point still has the step's end, and with it the step's misfit, and stops at the dip.
    dip_value, dip_rate = narrow_dip(0.23)

    def value(mode, t, x):
        return dip_value(mode, t, x) - 200.0 * np.maximum(t - 0.28, 0.0) ** 2

    def rate(mode, t, x):
        return dip_rate(mode, t, x) - 400.0 * np.maximum(t - 0.28, 0.0)

    ex = run([Watch("narrow", value, "stop", said, rate=rate)], t_final=0.4, h=0.2, python=python)
    assert ex.status == "fell" and ex.t_end == pytest.approx(0.23 - 0.02 * math.sqrt(math.log(2.0)), abs=1e-12)


def test_the_misfit_of_a_cubic_value_is_zero_and_of_a_quartic_its_own():
    # checked points of two steps of 0.2 s (stored at 0, 0.2, 0.4, middles at 0.1, 0.3): a cubic
    # value has no misfit; t^4 less its cubic Hermite through a step's ends [a, b] is
    # (t - a)^2 (t - b)^2 (the Hermite remainder f''''/4! (t - a)^2 (t - b)^2), dt^4 / 16 at the middle
    t = np.array([0.0, 0.1, 0.2, 0.3, 0.4])
    cubic = np.stack([2 * t**3 - t + 1, 6 * t**2 - 1], axis=1)
    quartic = np.stack([t**4, 4 * t**3], axis=1)
    none = np.zeros((4, 1), dtype=bool)
    assert np.allclose(cubic_misfits(t, cubic[:, :1], cubic[:, 1:], none), 0.0, atol=1e-15)
    assert np.allclose(cubic_misfits(t, quartic[:, :1], quartic[:, 1:], none), 0.2**4 / 16, atol=1e-15)
    # none where a piece changes in the step, or where the points end at a middle
    changed = np.array([[False], [True], [False], [False]])
    assert np.array_equal(cubic_misfits(t, quartic[:, :1], quartic[:, 1:], changed)[:, 0] > 0,
                          [False, False, True, True])  # fmt: skip
    assert np.allclose(cubic_misfits(t[:4], quartic[:4, :1], quartic[:4, 1:], none[:3]), [[1e-4], [1e-4], [0]])


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
    with pytest.raises(
        SimulationError,
        match=r"watch 'w': its probe gave shape \(\d+, 2, 1\) \(rows, parts, probes\) for \d+ points of 1 parts",
    ):
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
    # Its message ends up in the run's message or warnings: a failure is named, a number refused.
    for action in ("stop", "warn"):
        with pytest.raises(SimulationError, match=r"watch 'w': its message failed at t=0\.3.* ZeroDivisionError"):
            run([Watch("w", below(0.5), action, lambda t, mode, x: f"{1 / 0}")])
        with pytest.raises(SimulationError, match="watch 'w': its message must return a str, got int"):
            run([Watch("w", below(0.5), action, lambda t, mode, x: 42)])
    with pytest.raises(SimulationError, match=r"watch 'w': its rates' shape \(\d+, 2\) is not its values' \(\d+, 1\)"):
        run([Watch("w", below(0.5), "stop", said, rate=lambda mode, t, x: np.zeros((len(t), 2)))])
