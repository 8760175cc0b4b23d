"""The bouncing ball through its Zeno time: closed-form impact times, no fall-through."""

import numpy as np

from legsim import HybridSystem, Mode, Transition, simulate

G, C, Z0 = 9.81, 0.5, 1.0


def ball() -> HybridSystem:
    return HybridSystem(
        {"fall": Mode(2, lambda t, x, u: np.array([x[1], -G]), names=("z", "zd"))},
        [Transition("fall", "fall", guard=lambda x: max(x[0], x[1]),
                    reset=lambda x: np.array([x[0], -C * x[1]]), name="bounce")],
    )


def test_first_impact_time_is_exact_and_ball_never_sinks_past_eps():
    eps = 1e-3
    t_zeno = np.sqrt(2 * Z0 / G) * (1 + 2 * C / (1 - C))
    ex = simulate(ball(), [Z0, 0.0], "fall", 2 * t_zeno, 1e-3, eps)
    assert ex.status == "finished"
    # Free fall is a cubic polynomial: RK4 and the Hermite crossing are exact to rounding.
    assert abs(ex.transitions[0].time - np.sqrt(2 * Z0 / G)) < 1e-12
    # Runs through the Zeno time to twice it with a bounded number of transitions.
    assert len(ex.transitions) < 20_000
    for seg in ex.segments:
        assert seg.x[:, 0].min() >= -eps
