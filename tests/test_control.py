"""Controllers as parts of a run (legsim.control): told the mode, reset at every mode entry, and
evaluated at every stage or held over each step (zero-order hold), against closed forms."""

import math

import numpy as np
import pytest

from legsim import HybridSystem, Mode, Transition, simulate
from legsim.control import Controller


def pushed_mass() -> HybridSystem:
    """x' = v, v' = u: a unit mass pushed by the control; a wall at x = 1 (guard 1 - x, m) sends
    it back to x = 0 at rest in mode 'back'."""
    field = lambda t, s, u: np.array([s[1], u])  # noqa: E731
    modes = {"out": Mode(2, field, ("x", "v")), "back": Mode(2, field, ("x", "v"))}
    return HybridSystem(modes, [Transition("out", "back", lambda s: 1.0 - s[0], lambda s: np.zeros(2), name="wall")])


class Clock(Controller):
    """u = t in 'out', -1 in 'back'; counts the entries it is told of."""

    def __init__(self, hold: bool) -> None:
        self.hold = hold
        self.entries: list[tuple[str, float]] = []

    def reset(self, mode, t, x):
        self.entries.append((mode, t))

    def __call__(self, mode, t, x):
        return t if mode == "out" else -1.0


def test_a_controller_evaluated_at_every_stage_keeps_the_methods_order():
    # u = t: x = t^3 / 6, integrated exactly by RK4 (a cubic) until the wall at t = 6^(1/3).
    clock = Clock(hold=False)
    ex = simulate(pushed_mass(), [0.0, 0.0], "out", 1.0, 1e-2, 1e-6, "rk4", clock)
    assert ex.final_mode == "out"
    np.testing.assert_allclose(ex.final_state, [1 / 6, 1 / 2], rtol=1e-13)
    assert clock.entries == [("out", 0.0)]


def test_a_held_controller_is_a_zero_order_hold_over_each_step():
    # u(t_k) = t_k held over [t_k, t_k + h]: v(T) = h sum_k t_k = h^2 N (N - 1) / 2 exactly.
    h, n = 1e-2, 100
    ex = simulate(pushed_mass(), [0.0, 0.0], "out", n * h, h, 1e-6, "rk4", Clock(hold=True))
    assert ex.final_state[1] == pytest.approx(h * h * n * (n - 1) / 2, rel=1e-12)


def test_the_controller_is_told_the_mode_and_reset_at_every_entry():
    clock = Clock(hold=False)
    ex = simulate(pushed_mass(), [0.0, 0.0], "out", 3.0, 1e-2, 1e-6, "rk4", clock)
    t_wall = 6 ** (1 / 3)
    assert [m for m, _ in clock.entries] == ["out", "back"]
    assert clock.entries[1][1] == pytest.approx(t_wall, abs=2e-6)
    # in 'back' u = -1 from rest at x = 0: x = -(t - t_exit)^2 / 2
    t_exit = ex.transitions[0].exit_time
    assert ex.final_state[0] == pytest.approx(-0.5 * (3.0 - t_exit) ** 2, rel=1e-12)
    assert math.isfinite(t_exit)


def test_a_python_controlled_run_says_it_ran_in_python_even_without_a_step():
    """The run's ``path`` is the loop its tables chose, also for a run that ends where it starts:
    a control of nan stops it at t0 before any step, on the Python loop."""
    ex = simulate(pushed_mass(), [0.0, 0.0], "out", 1.0, 1e-2, 1e-6, "rk4", lambda t, x: math.nan)
    assert ex.status == "non_finite" and ex.t_end == 0.0 and ex.counters["steps"] == 0
    assert ex.settings["path"] == "python" and ex.settings["python_reason"]
