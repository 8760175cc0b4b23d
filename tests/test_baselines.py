"""Baselines: event-driven solve_ivp and Paoli-Schatzman, checked against closed forms."""

import numpy as np
import pytest

from helpers.compiled_models import above_floor, pushed_fall
from legsim import HybridSystem, Mode, ModeFunctions, SimulationError, Transition, model_function
from legsim.baselines import paoli_schatzman, simulate_events
from legsim.control import ControlLaw, Controller, LawController

G = 9.81


def ball(c: float) -> HybridSystem:
    return HybridSystem(
        {"flight": Mode(2, lambda t, x, u: np.array([x[1], -G]), names=("z", "zd"))},
        [
            Transition(
                "flight",
                "flight",
                guard=lambda x: max(x[0], x[1]),
                reset=lambda x: np.array([x[0], -c * x[1]]),
                name="bounce",
            )
        ],
    )


def test_event_driven_ball_impact_times_match_closed_form():
    c = 0.8
    ex = simulate_events(ball(c), [1.0, 0.0], "flight", 3.0, method="RK45", rtol=1e-10, atol=1e-12)
    t1 = np.sqrt(2 / G)
    expected = [t1 + 2 * t1 * sum(c**k for k in range(1, n + 1)) for n in range(4)]
    got = [tr.time for tr in ex.transitions[:4]]
    assert np.allclose(got, expected, atol=1e-8)
    # After the reset the ball leaves the floor upwards with c times the impact speed.
    tr = ex.transitions[0]
    assert tr.state_after[1] == pytest.approx(-c * tr.state_before[1])


def test_event_driven_stops_honestly_at_zeno():
    c = 0.5
    t_zeno = np.sqrt(2 / G) * (1 + 2 * c / (1 - c))
    ex = simulate_events(ball(c), [1.0, 0.0], "flight", 2 * t_zeno, rtol=1e-8, atol=1e-10, max_transitions=60)
    # An event-driven simulator cannot pass the accumulation point: the cap ends the run there.
    assert ex.status == "max_transitions"
    assert ex.t_end == pytest.approx(t_zeno, abs=1e-3)
    assert "Zeno" in ex.message


def test_event_driven_fires_simultaneous_guards_at_a_corner():
    # Two independent counters hitting their thresholds at the same instant: both transitions
    # must fire at that instant, in either order (the restart alone would miss the second).
    def field(t, x, u):
        return np.array([-1.0, -1.0])

    modes = {m: Mode(2, field) for m in ("00", "10", "01", "11")}

    def flip(i):
        def reset(x):
            y = x.copy()
            y[i] = 1.0
            return y

        return reset

    trs = [
        Transition("00", "10", guard=lambda x: x[0], reset=flip(0)),
        Transition("00", "01", guard=lambda x: x[1], reset=flip(1)),
        Transition("10", "11", guard=lambda x: x[1], reset=flip(1)),
        Transition("01", "11", guard=lambda x: x[0], reset=flip(0)),
    ]
    system = HybridSystem(modes, trs)
    ex = simulate_events(system, [0.5, 0.5], "00", 0.9, rtol=1e-10, atol=1e-12)
    assert ex.mode_sequence[0] == "00" and ex.mode_sequence[-1] == "11"
    assert [tr.time for tr in ex.transitions] == pytest.approx([0.5, 0.5], abs=1e-9)
    assert np.allclose(ex.final_state, [0.6, 0.6], atol=1e-9)


def test_event_driven_rejects_bad_settings():
    with pytest.raises(SimulationError, match="unknown solve_ivp method 'RK99'"):
        simulate_events(ball(0.5), [1.0, 0.0], "flight", 1.0, method="RK99")
    with pytest.raises(SimulationError, match="rtol must be finite and > 0"):
        simulate_events(ball(0.5), [1.0, 0.0], "flight", 1.0, rtol=0.0)


def free_oscillator_position(t, a, omega, x0, xd0):
    wd = np.sqrt(omega**2 - a**2)
    return np.exp(-a * t) * (x0 * np.cos(wd * t) + (xd0 + a * x0) / wd * np.sin(wd * t))


@pytest.mark.parametrize("compiled", [False, True])
def test_paoli_schatzman_is_second_order_away_from_the_stop(compiled):
    # With the stop out of reach eq. (29) is the central-difference scheme for the damped
    # oscillator: its error at a fixed time falls by 4 when h halves.
    a, omega = 0.1, 2.0
    errors = []
    for h in (2e-2, 1e-2, 5e-3):
        t, z = paoli_schatzman(a, omega, 0.5, 100.0, lambda t: 0.0 * t, 1.0, 0.0, 5.0, h, compiled=compiled)
        errors.append(np.abs(z - free_oscillator_position(t, a, omega, 1.0, 0.0)).max())
    slopes = np.diff(np.log(errors)) / np.diff(np.log([2e-2, 1e-2, 5e-3]))
    assert np.all(np.abs(slopes - 2.0) < 0.15), slopes


def test_paoli_schatzman_never_passes_the_stop_and_rejects_bad_input():
    _t, z = paoli_schatzman(0.0, 1.0, 0.5, 0.5, lambda t: 0.0 * t, 0.0, 2.0, 10.0, 1e-3)
    # The scheme keeps positions on the admissible side up to O(h) (weighted-average constraint).
    assert z.max() <= 0.5 + 2.0 * 1e-3
    with pytest.raises(SimulationError, match="restitution c must be in"):
        paoli_schatzman(0.0, 1.0, 1.5, 0.5, lambda t: 0.0 * t, 0.0, 2.0, 10.0, 1e-3)
    with pytest.raises(SimulationError, match="forcing must be vectorised"):
        paoli_schatzman(0.0, 1.0, 0.5, 0.5, lambda t: 0.0, 0.0, 2.0, 10.0, 1e-3)


class Recording(LawController):
    """A ``ControlLaw`` run as a Python Controller (``LawController``, as the event-driven
    baseline runs one), its memory recorded after every mode entry as (mode, t, memory)."""

    def __init__(self, law) -> None:
        super().__init__(law)
        self.entries = []

    def reset(self, mode, t, x):
        super().reset(mode, t, x)
        self.entries.append((mode, t, self.memory()))


def test_event_driven_runs_a_controller_as_the_relaxed_integrator_does():
    # Two different integrators on the SLIP hopper under Raibert's foot placement, each a
    # reference for the other: solve_ivp DOP853 with events at 1e-11, and the relaxed DOP853 with
    # strips of 1e-10 m (each transition delays the run by about eps / speed) at 1e-11.
    from legsim.relaxed import simulate
    from legsim.scene import load_scene

    scene = load_scene("slip_raibert")
    system, x0, mode = scene.model.system, scene.initial_state, scene.initial_mode
    events, relaxed = Recording(scene.control), Recording(scene.control)
    ev = simulate_events(system, x0, mode, 5.0, method="DOP853", rtol=1e-11, atol=1e-11, control=events)
    rx = simulate(system, x0, mode, 5.0, 0.05, 1e-10, "dop853", relaxed, rtol=1e-11, atol=1e-11, landing="dense")
    assert ev.status == rx.status == "finished"
    touch_ev = [tr for tr in ev.transitions if tr.name == "touchdown"][:5]
    touch_rx = [tr for tr in rx.transitions if tr.name == "touchdown"][:5]
    assert len(touch_ev) == len(touch_rx) == 5
    # Measured agreement is about 5e-10 s and 5e-10 in the state over five hops; 1e-8 leaves
    # room for rounding across platforms while a wrong mode or a missed reset is off by 1e-2.
    for a, b in zip(touch_ev, touch_rx, strict=True):
        assert a.time == pytest.approx(b.time, abs=1e-8)
        assert np.allclose(a.state_after[:5], b.state_after[:5], atol=1e-8)
    # Each liftoff's entry into flight sets T_s to that stance's duration (the controller's own
    # definition, read off the transitions), identically in both runs.
    for run, rec in ((ev, events), (rx, relaxed)):
        assert [m for m, _, _ in rec.entries][:4] == ["flight", "stance", "flight", "stance"]
        stances = list(zip(run.transitions[0::2], run.transitions[1::2], strict=False))
        after_liftoff = [mem[0] for m, t, mem in rec.entries[1:] if m == "flight"]
        durations = [off.time - on.time for on, off in stances if off.name == "liftoff"]
        assert len(after_liftoff) >= 5 and np.allclose(after_liftoff, durations[: len(after_liftoff)], atol=1e-12)
    ts_ev = [mem[0] for m, _, mem in events.entries if m == "flight"][1:6]
    ts_rx = [mem[0] for m, _, mem in relaxed.entries if m == "flight"][1:6]
    assert np.allclose(ts_ev, ts_rx, atol=1e-8)


def test_event_driven_refuses_a_held_controller():
    class Held(Controller):
        hold = True

        def __call__(self, mode, t, x):
            return 0.0

    with pytest.raises(SimulationError, match=r"hold=True.*solve_ivp cannot run"):
        simulate_events(ball(0.5), [1.0, 0.0], "flight", 1.0, control=Held())


@model_function
def _kicked_bounce(e, t, x, u, p, out):
    """A bounce with restitution p[1] that a paddle under the ball kicks up by u[0] (m/s)."""
    out[0] = x[0]
    out[1] = -p[1] * x[1] + u[0]


@model_function
def _constant_kick(t, x, m, p, u):
    u[0] = p[0]


def test_event_driven_resets_take_the_controllers_input():
    # A reset written as model functions takes the input: the baseline must pass the
    # controller's, as the relaxed integrator does, not zero. The paddle ball's field adds the
    # input to gravity: dropped from 1 m under a constant input k, the ball meets the floor at
    # sqrt(2 (g - k)) and leaves it at c sqrt(2 (g - k)) + k.
    c, kick = 0.8, 0.5
    flight = Mode(2, names=("z", "zd"), functions=ModeFunctions(pushed_fall, above_floor, _kicked_bounce,
                                                                params=[G, c], inputs=1))  # fmt: skip
    system = HybridSystem({"flight": flight}, [Transition("flight", "flight", name="bounce")], name="kicked")
    law = ControlLaw("kick", _constant_kick, 1, lambda mode: np.array([kick]))
    ex = simulate_events(system, [1.0, 0.0], "flight", 0.5, rtol=1e-12, atol=1e-12, control=law)
    (bounce,) = ex.transitions
    assert bounce.time == pytest.approx(np.sqrt(2 / (G - kick)), abs=1e-9)
    assert bounce.state_after[1] == pytest.approx(c * np.sqrt(2 * (G - kick)) + kick, abs=1e-8)
