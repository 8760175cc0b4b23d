"""The linearly implicit (Rosenbrock W) method ros2: second order, stable where explicit methods
diverge on a stiff field, under the relaxed semantics (landing, strips, resets) and compiled."""

from __future__ import annotations

import math

import numpy as np
import pytest

from legsim import HybridSystem, Mode, Transition, simulate
from legsim.methods import get_method
from legsim.relaxed.single import Stepper


def stiff_decay(lam: float):
    """x' = lam (x - cos t) - sin t: x = cos t is the solution from x(0) = 1, however stiff."""
    return HybridSystem({"m": Mode(1, lambda t, x, u: np.array([lam * (float(x[0]) - math.cos(t)) - math.sin(t)]))})


def test_ros34pw2_is_third_order_on_a_non_autonomous_field():
    system = stiff_decay(-2.0)
    hs = (0.1, 0.05, 0.025)
    errors = [abs(simulate(system, [1.0], "m", 1.0, h, 1e-3, "ros34pw2").final_state[0] - math.cos(1.0)) for h in hs]
    rates = np.log2(np.array(errors[:-1]) / errors[1:])
    assert np.all(np.abs(rates - 3.0) < 0.2), rates


def test_ros34pw2_stays_on_a_stiff_solution_where_rk4_diverges():
    # lam h = -50: far outside rk4's stability region (|lam h| < 2.8), inside ros2's (L-stable).
    system = stiff_decay(-5000.0)
    rk4 = simulate(system, [1.0], "m", 1.0, 0.01, 1e-3, "rk4")
    assert rk4.status == "non_finite" or abs(rk4.final_state[0]) > 1e6
    ros2 = simulate(system, [1.0], "m", 1.0, 0.01, 1e-3, "ros34pw2")
    assert ros2.status == "finished" and abs(ros2.final_state[0] - math.cos(1.0)) < 1e-4


def test_a_stiff_bouncing_contact_lands_in_its_strips_with_error_control():
    # A stiff spring-damper leg (k = 1e6 N/m, b = 2e3 N s/m on 1 kg) bouncing off a wall under
    # gravity: error-controlled ros2 takes steps far beyond rk4's stability limit (2.8 / 2e3 s
    # at the damping rate) while every crossing lands in its strip.
    def field(t, x, u):
        return np.array([x[1], -9.81 - 2e3 * x[1] - 1e6 * (x[0] - 0.5)])

    system = HybridSystem(
        {"m": Mode(2, field)},
        [Transition("m", "m", lambda x: max(x[0], x[1]), lambda x: np.array([x[0], -0.5 * x[1]]), name="wall")],
    )
    ex = simulate(system, [0.6, 0.0], "m", 2.0, 0.05, 1e-6, "ros34pw2", rtol=1e-6, atol=1e-9, landing="aim")
    assert ex.status == "finished" and ex.counters["python_steps"] == ex.steps
    assert ex.steps < 2.0 / (2.8 / 2e3)  # fewer steps than rk4 would need to stay stable
    assert ex.final_state[0] == pytest.approx(0.5 - 9.81 / 1e6, abs=1e-6)  # at rest on the spring


def test_the_step_is_the_methods_stability_function_on_a_linear_field():
    # x' = A x with A symmetric: each eigen-direction is multiplied by R(h lambda), R the method's
    # stability function computed from the published coefficients (Hairer and Wanner IV.7:
    # R(z) = 1 + z b^T (I - z (alpha + Gamma))^{-1} 1); R(-inf) = 0: L-stable.
    from legsim.methods import builtin

    A = np.array([[-3.0, 1.0], [1.0, -400.0]])
    lams, V = np.linalg.eigh(A)
    x0 = np.array([1.0, -2.0])
    h = 0.05
    x1, _ = Stepper(get_method("ros34pw2")).step(lambda t, x, u: A @ x, 0.0, x0, h, A @ x0)
    alpha = np.array(ROS34PW2_ALPHA)
    Gamma = np.array(ROS34PW2_GAMMA) + 0.43586652150845900 * np.eye(4)
    b = np.array(ROS34PW2_B)

    def R(z):
        return 1.0 + z * b @ np.linalg.solve(np.eye(4) - z * (alpha + Gamma), np.ones(4))

    expected = V @ np.diag([R(h * lam) for lam in lams]) @ V.T @ x0
    np.testing.assert_allclose(x1, expected, rtol=1e-12, atol=1e-14)
    assert abs(R(-1e12)) < 1e-9
    assert builtin.ROS34PW2.implicit


ROS34PW2_ALPHA = [
    [0.0, 0.0, 0.0, 0.0],
    [8.7173304301691801e-01, 0.0, 0.0, 0.0],
    [8.4457060015369423e-01, -1.1299064236484185e-01, 0.0, 0.0],
    [0.0, 0.0, 1.0, 0.0],
]
ROS34PW2_GAMMA = [
    [0.0, 0.0, 0.0, 0.0],
    [-8.7173304301691801e-01, 0.0, 0.0, 0.0],
    [-9.0338057013044082e-01, 5.4180672388095326e-02, 0.0, 0.0],
    [2.4212380706095346e-01, -1.2232505839045147e00, 5.4526025533510214e-01, 0.0],
]
ROS34PW2_B = [2.4212380706095346e-01, -1.2232505839045147e00, 1.5452602553351020e00, 4.3586652150845900e-01]
