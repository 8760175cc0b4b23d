"""Baselines: event-driven solve_ivp and Paoli-Schatzman, checked against closed forms."""

import numpy as np
import pytest

from legsim import HybridSystem, Mode, SimulationError, Transition
from legsim.baselines import paoli_schatzman, simulate_events

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
