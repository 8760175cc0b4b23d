"""The core's rule for accumulating transitions (legsim.relaxed.zeno, rules.accumulating): a
transition whose crossings accumulate takes the continuation it names when its image lies in
the target's domain; otherwise the run keeps its relaxed semantics and says so in
``Execution.warnings``, as does a run held in strips for more than 1% of its time. The errors of
the new API. (The ball and the oscillator against their closed forms:
tests/test_systems_bouncing_ball.py, tests/systems/test_oscillator_zeno.py; the double
pendulum: tests/robots/test_double_pendulum.py.)"""

import itertools
import math

import numpy as np
import pytest

from legsim import Continuation, HybridSystem, Mode, ModelError, SimulationError, Transition, simulate
from legsim.relaxed.rules import accumulating
from legsim.stress.models import curved_floor_ball, tangential_speed

G = 9.81


def test_crossings_accumulate_when_the_flight_is_within_the_window_and_shorter_than_the_last():
    window = 1.1e-3
    assert accumulating(2e-3, 1e-3, window)
    assert accumulating(2e-3, window, window)  # the window itself counts
    assert not accumulating(2e-3, 1.2e-3, window)  # resolved by the integrator
    assert not accumulating(1e-3, 1e-3, window)  # not shrinking
    assert not accumulating(0.5e-3, 1e-3, window)  # growing: the motion is leaving the guard
    assert accumulating(math.inf, 0.0, window)  # the first flight of a chain has no predecessor


def ball(rest_release: float | None) -> HybridSystem:
    """The ball (c = 0.5) with a continuation into ``rest``, whose only guard is the constant
    ``rest_release`` (>= 0: the floor would push at rest, < 0: it would pull at once); None: the
    bounce names no continuation."""
    fly = Mode(2, lambda t, x, u: np.array([x[1], -G]), names=("z", "zd"))
    held = Mode(2, lambda t, x, u: np.zeros(2), names=("z", "zd"))
    rest = None if rest_release is None else Continuation("rest", lambda x: np.array([x[0], 0.0]))
    transitions = [
        Transition(
            "fly",
            "fly",
            lambda x: max(x[0], x[1]),
            lambda x: np.array([x[0], -0.5 * x[1]]),
            name="bounce",
            continuation=rest,
        )
    ]
    modes = {"fly": fly}
    if rest_release is not None:
        modes["rest"] = held
        transitions.append(Transition("rest", "fly", lambda x: rest_release, name="release"))
    return HybridSystem(modes, transitions, name="ball")


def test_the_continuation_is_taken_only_where_its_image_lies_in_the_targets_domain():
    h, eps = 1e-3, 1e-4
    pushing = simulate(ball(1.0), [1.0, 0.0], "fly", 2.0, h, eps)
    names = [tr.name for tr in pushing.transitions]
    # named <transition>_continued by default, and the last transition of the run
    assert names[-1] == "bounce_continued" and names.count("bounce_continued") == 1
    assert pushing.final_mode == "rest" and pushing.warnings == []
    # where the target's guard is past at the image (the constraint would pull at once) the
    # bounce is taken instead: the relaxed semantics, and the warning that goes with them
    pulling = simulate(ball(-1.0), [1.0, 0.0], "fly", 2.0, h, eps)
    assert set(tr.name for tr in pulling.transitions) == {"bounce"} and pulling.final_mode == "fly"
    plain = simulate(ball(None), [1.0, 0.0], "fly", 2.0, h, eps)
    assert [tr.time for tr in pulling.transitions] == [tr.time for tr in plain.transitions]
    assert [w.kind for w in pulling.warnings] == [w.kind for w in plain.warnings] == ["accumulation"]
    # continuation=False: the same as no continuation, whatever the model names
    off = simulate(ball(1.0), [1.0, 0.0], "fly", 2.0, h, eps, continuation=False)
    assert [tr.time for tr in off.transitions] == [tr.time for tr in plain.transitions]
    assert off.settings["continuation"] is False and [w.kind for w in off.warnings] == ["accumulation"]


def test_the_continuation_and_the_warning_start_at_the_same_crossing():
    # Free fall is a cubic, integrated exactly: the flights between strips are the exact ones,
    # 2 c^k v1 / g after the k-th impact. The rule fires at the crossing that ends the first
    # flight no longer than the window h + eps, the k-th with c^(k-1) <= g (h + eps) / (2 v1).
    h, eps, c = 1e-3, 1e-4, 0.5
    v1 = math.sqrt(2 * G)
    k = 1 + math.ceil(math.log(2 * v1 / (G * (h + eps))) / math.log(1 / c))
    continued = simulate(ball(1.0), [1.0, 0.0], "fly", 2.0, h, eps)
    plain = simulate(ball(None), [1.0, 0.0], "fly", 2.0, h, eps)
    assert len(continued.transitions) == k
    (warning,) = plain.warnings
    assert warning.time == continued.transitions[-1].time == plain.transitions[k - 1].time


def test_a_chattering_user_system_without_continuation_says_where_its_crossings_accumulate():
    # A ball sliding in a valley, written with the core API: its bounces accumulate while it
    # keeps moving along the floor, and no continuation says how it slides. The run keeps the
    # relaxed semantics (the state held in the strip) and its warning names the transition, the
    # crossing the accumulation began at, the accumulation time, the transitions and strip time
    # since, and the remedy.
    radius, h, eps, t_final = 2.0, 1e-3, 1e-4, 3.0
    system = curved_floor_ball(0.8, radius)
    ex = simulate(system, [1.0, 0.75, 0.0, 0.0], "fly", t_final, h, eps, max_transitions=10**5)
    assert ex.status == "finished"
    (warning,) = ex.warnings
    trs = ex.transitions
    flights = [b.time - a.exit_time for a, b in itertools.pairwise(trs)]
    # it began at the crossing that ends the first flight within the window (all are shrinking)
    start = next(i for i, f in enumerate(flights) if f <= h + eps) + 1
    assert all(f > h + eps for f in flights[: start - 1]) and all(np.diff(flights[:start]) < 0)
    assert warning.kind == "accumulation" and warning.time == trs[start].time
    details = warning.details
    assert details["transition"] == "bounce" and details["mode"] == "fly"
    assert details["transitions_since"] == len(trs) - start
    # (the strips include the one the run ended in, which no transition left)
    assert details["strip_time_since"] == pytest.approx(sum(s.exit_time - s.time for s in ex.strips[start:]), rel=1e-12)
    # The relaxed run resolves the next flights too (it halves into the strips): the
    # accumulation time the warning estimates from the last two flights is the start's strip
    # exit plus the flights still to come (a geometric tail), to the 1% their ratio drifts by.
    to_come = sum(flights[start:])
    assert details["accumulation_time"] - trs[start].exit_time == pytest.approx(to_come, rel=0.01)
    for words in ("transition bounce", f"t={warning.time:.6g}", "Remedy", "Continuation"):
        assert words in warning.message
    # ... while the state it holds still slides along the floor at over 1 m/s
    assert tangential_speed(ex.final_state, radius) > 1.0
    held = ex.sample(np.linspace(details["accumulation_time"] + 0.1, t_final, 50)).states
    assert np.ptp(np.array(held)[:, 0]) < 1e-3


def sawtooth() -> HybridSystem:
    """x' = 1 from 0 to the guard 1 - x, reset to 0: a transition every 1 s (plus its hold)."""
    return HybridSystem(
        {"a": Mode(1, lambda t, x, u: np.array([1.0]), names=("x",))},
        [Transition("a", "a", lambda x: float(1.0 - x[0]), lambda x: np.zeros(1), name="wrap")],
        name="sawtooth",
    )


def test_a_run_held_in_strips_over_one_percent_of_its_time_says_so():
    # At unit rate across a linear guard each crossing holds the state exactly eps: 4 crossings
    # in 5 s (at 1, 2 + eps, 3 + 2 eps, 4 + 3 eps) hold it 4 eps.
    ex = simulate(sawtooth(), [0.0], "a", 5.0, 1e-2, 0.05)
    (warning,) = ex.warnings
    assert len(ex.transitions) == 4 and warning.kind == "strip_hold"
    assert warning.details["strip_time"] == pytest.approx(4 * 0.05, rel=1e-9)
    assert warning.details["share"] == pytest.approx(4 * 0.05 / 5.0, rel=1e-9)
    assert "0.2 s of the run's 5 s (4.0%)" in warning.message and "smaller eps" in warning.message
    # 4 eps / 5 s = 0.8% at eps = 0.01: under the 1% the run vouches for
    assert simulate(sawtooth(), [0.0], "a", 5.0, 1e-2, 0.01).warnings == []


def test_an_accumulation_warning_is_not_doubled_by_a_strip_hold_warning():
    # The plain ball past its Zeno time is held in strips most of the time: one warning says why.
    ex = simulate(ball(None), [1.0, 0.0], "fly", 2.7, 1e-3, 1e-4)
    assert sum(strip.exit_time - strip.time for strip in ex.strips) > 0.4 * 2.7
    assert [w.kind for w in ex.warnings] == ["accumulation"]


@pytest.mark.parametrize(
    "window, error",
    [
        (-1.0, "must be finite and > 0, got -1"),
        (0.0, "must be finite and > 0"),
        (math.nan, "must be finite and > 0"),
        (math.inf, "must be finite and > 0"),
        ("0.1", "must be a number, got str"),
    ],
)
def test_a_zeno_window_that_is_not_a_positive_time_is_refused_by_name(window, error):
    with pytest.raises(SimulationError, match=rf"^zeno_window {error}"):
        simulate(ball(1.0), [1.0, 0.0], "fly", 1.0, 1e-3, 1e-4, zeno_window=window)


def test_the_window_defaults_to_h_plus_eps_and_is_recorded():
    ex = simulate(ball(1.0), [1.0, 0.0], "fly", 0.1, 1e-3, 1e-4)
    assert ex.settings["zeno_window"] == pytest.approx(1.1e-3) and ex.settings["continuation"] is True
    assert simulate(ball(1.0), [1.0, 0.0], "fly", 0.1, 1e-3, 1e-4, zeno_window=0.05).settings["zeno_window"] == 0.05


@pytest.mark.parametrize("value", ["no", 1.5])
def test_continuation_must_be_a_bool(value):
    with pytest.raises(SimulationError, match="continuation"):
        simulate(ball(1.0), [1.0, 0.0], "fly", 0.1, 1e-3, 1e-4, continuation=value)


def test_a_continuation_is_checked_by_name():
    with pytest.raises(ModelError, match=r"continuation None: target must be a mode name \(str\), got 3"):
        Continuation(3)
    with pytest.raises(ModelError, match=r"continuation stick: reset must be callable"):
        Continuation("rest", reset="x", name="stick")
    with pytest.raises(ModelError, match=r"transition bounce: continuation must be a legsim.Continuation or None"):
        Transition("fly", "fly", lambda x: x[0], name="bounce", continuation="rest")
    # into a mode the system does not have: refused naming the mode and listing those it has
    fly = Mode(2, lambda t, x, u: np.array([x[1], -G]), names=("z", "zd"))
    with pytest.raises(
        ModelError,
        match=r"^ball: continuation .* of transition .* targets unknown mode 'rest' "
        r"\(modes: \['fly'\]\)",
    ):
        HybridSystem(
            {"fly": fly},
            [Transition("fly", "fly", lambda x: max(x[0], x[1]), continuation=Continuation("rest"))],
            name="ball",
        )
    # a continuation without reset keeps the state: the target must have the source's dimension
    point = Mode(1, lambda t, x, u: np.zeros(1), names=("z",))
    shrink = HybridSystem(
        {"fly": fly, "rest": point},
        [
            Transition(
                "fly",
                "fly",
                lambda x: max(x[0], x[1]),
                lambda x: np.array([x[0], -x[1]]),
                name="bounce",
                continuation=Continuation("rest"),
            )
        ],
        name="ball",
    )
    with pytest.raises(ModelError, match=r"transition bounce_continued has no reset but changes dimension 2 -> 1"):
        simulate(shrink, [1.0, 0.0], "fly", 1.0, 1e-3, 1e-4)


def test_an_accumulation_the_run_leaves_ends_at_its_last_crossing_not_at_the_runs_end():
    # A graze crossed three times within 0.1 ms (flights 4e-5 and 2e-5 s, inside the window
    # 1.1e-3 s and shrinking) and never again, then ten touchdowns a second apart: the
    # episode counts the grazes from the one that opened it, and ends where the grazes did.
    from legsim.relaxed.assemble import _Replay
    from legsim.relaxed.zeno import ZenoWatch

    window, hold = 1.1e-3, 1e-5
    watch, replay = ZenoWatch(window, continues=False), _Replay()
    graze_times = [1.0, 1.0 + hold + 4e-5, 1.0 + 2 * hold + 6e-5]
    crossings = [("flight", "graze", t) for t in graze_times] + [("flight", "touchdown", 2.0 + k) for k in range(10)]
    for mode, name, tc in crossings:
        replay.transitions.append(None)
        replay.strip_time += hold
        watch.crossed(replay, mode, name, tc, tc + hold, watch.crossing(mode, name, tc), continued=False)
    (warning,) = watch.warnings(replay, t_end=12.0)
    # The second graze's flight (4e-5 s) is the first within the window after an infinite one.
    assert warning.time == graze_times[1]
    assert warning.details["transitions_since"] == 2  # the second and third grazes
    assert warning.details["strip_time_since"] == pytest.approx(2 * hold, rel=1e-12)
    assert f"until t={graze_times[2] + hold:.6g} s" in warning.message
    # Without a later crossing the run's end closes it at the last graze too.
    watch, replay = ZenoWatch(window, continues=False), _Replay()
    for mode, name, tc in crossings[:3]:
        replay.transitions.append(None)
        replay.strip_time += hold
        watch.crossed(replay, mode, name, tc, tc + hold, watch.crossing(mode, name, tc), continued=False)
    (warning,) = watch.warnings(replay, t_end=12.0)
    assert warning.details["transitions_since"] == 2 and f"until t={graze_times[2] + hold:.6g} s" in warning.message


@pytest.mark.parametrize("h", [0.1, 0.25])
def test_a_periodic_event_as_frequent_as_the_steps_taking_a_continuation_says_so(h):
    """A timer ticking every 0.1 s (no Zeno point) run at h >= 0.1: each tick falls within the
    window h + eps of the last, so one flight makes it look accumulating and the continuation
    stops the timer. One flight cannot tell that from a Zeno point, so the run must say so, also
    where the flight is well under the window (h = 0.25 s); at h = 0.05 s it ticks 10 times."""
    from legsim import ModeFunctions, model_function

    @model_function
    def clock(t, x, u, p, dx):
        dx[0] = 1.0
        dx[1] = 0.0

    @model_function
    def due(t, x, u, p, g):
        g[0] = p[0] - x[0]

    @model_function
    def tick(e, t, x, u, p, out):
        out[0] = 0.0 if e == 0 else x[0]
        out[1] = x[1] + 1.0 if e == 0 else x[1]

    @model_function
    def still(t, x, u, p, dx):
        dx[0] = 0.0
        dx[1] = 0.0

    timer = HybridSystem(
        {
            "T": Mode(2, names=("tau", "n"), functions=ModeFunctions(clock, due, tick, params=[0.1])),
            "S": Mode(2, names=("tau", "n"), functions=ModeFunctions(still)),
        },
        [Transition("T", "T", name="tick", continuation=Continuation("S", name="stop"))],
    )
    fine = simulate(timer, [0.0, 0.0], "T", 1.05, 0.05, 1e-6, "rk4", python=True)
    assert fine.final_state[1] == 10.0 and fine.warnings == []
    coarse = simulate(timer, [0.0, 0.0], "T", 1.05, h, 1e-6, "rk4", python=True)
    assert coarse.final_mode == "S"
    assert [w.kind for w in coarse.warnings] == ["unconfirmed_continuation"]
    assert coarse.warnings[0].details["flight"] == pytest.approx(0.1, abs=1e-5)
