"""What a landing costs an error-controlled run.

A step shortened to land in a strip is shortened by a guard, not by the error: it must not shrink
the step the error control proposes next, or the mode after a transition restarts at the
landing step's length and creeps back up by 5x per step. And the aimed landing must use the
failed step's interpolant where it is most accurate, next to the step's end, rather than halving.
"""

import math

import numpy as np
import pytest

from legsim import HybridSystem, Mode, SimulationError, Transition, simulate
from legsim.methods.tableau import tableau


def drift_system(gap: float) -> HybridSystem:
    """x' = y' = 1: mode a leaves at x = 1, mode b at y = 1 + gap, mode c runs free. With a
    linear field every embedded pair is exact, so only guards ever shorten a step."""

    def field(t, x, u):
        return np.ones(2)

    def identity(x):
        return x.copy()

    return HybridSystem(
        {
            "a": Mode(2, field, names=("x", "y")),
            "b": Mode(2, field, names=("x", "y")),
            "c": Mode(2, field, names=("x", "y")),
        },
        [
            Transition("a", "b", guard=lambda x: 1.0 - x[0], reset=identity, name="a_to_b"),
            Transition("b", "c", guard=lambda x: 1.0 + gap - x[1], reset=identity, name="b_to_c"),
        ],
    )


@pytest.mark.parametrize("method", ["dopri5", "bs32"])
def test_a_landing_does_not_shrink_the_next_modes_steps(method):
    # Mode b lasts 1e-10 s: its landing step is ~1e-10 s long. Mode c must not start at 5x the
    # landing step (which took 14 steps to grow back to h): it starts at the standard starting
    # step of a new mode, as an event-driven integrator restarts (Hairer, Norsett and Wanner,
    # II.4: with x = f = (1, 1) and f constant, (0.01 / d1)^(1 / (q + 1)), d1 = |f| / (atol +
    # rtol |x|), q the pair's error order), and grows back to h by 5x a step.
    h, t_final, tol = 0.25, 3.0, 1e-8
    ex = simulate(drift_system(1e-10), [0.0, 0.0], "a", t_final, h, 1e-12, method=method, rtol=tol, atol=tol)
    assert ex.status == "finished" and ex.mode_sequence == ["a", "b", "c"]
    c = ex.segments[-1]
    np.testing.assert_allclose(c.x[0], [1.0, 1.0], atol=1e-9)
    steps_in_c = np.diff(c.t)
    q = {"dopri5": 4, "bs32": 2}[method]
    start = (0.01 * (tol + tol * 1.0)) ** (1.0 / (q + 1))
    assert steps_in_c[0] == pytest.approx(start, rel=1e-6)
    grown = int(np.argmax(steps_in_c >= h - 1e-12))
    assert steps_in_c[grown] == pytest.approx(h) and grown == math.ceil(math.log(h / start, 5))
    assert np.all(steps_in_c[grown:-1] == pytest.approx(h))


def test_error_control_refuses_an_embedded_pair_without_its_order():
    # Heun with an embedded Euler, declared without error_order: the controller's step exponent
    # -1 / (min(order, error_order) + 1) cannot be formed, so the run is refused by name.
    heun_euler = tableau("heun_euler", 2, [0.0, 1.0], [[0.0, 0.0], [1.0, 0.0]], [0.5, 0.5], b_hat=[1.0, 0.0])
    with pytest.raises(SimulationError, match="method 'heun_euler' has an embedded error estimate but no error_order"):
        simulate(drift_system(0.5), [0.0, 0.0], "a", 1.0, 0.1, 1e-3, method=heun_euler, rtol=1e-6)
