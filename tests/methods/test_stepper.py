"""The one step routine (``legsim.relaxed.stages``, through ``relaxed.single.Stepper``) against
the readable reference rk_step (tests/helpers/reference_rk.py), the error estimate's order, and
the error norms against their formulas."""

from __future__ import annotations

import math

import numpy as np
import pytest

from helpers.reference_rk import rk_step
from legsim.methods import METHODS, get_method
from legsim.relaxed.single import Stepper

ORDERS = {"euler": 1, "rk2": 2, "heun": 2, "rk4": 4, "bs32": 3, "dopri5": 5}


def pendulum(t, x, u):
    return np.array([x[1], -math.sin(x[0]) + (0.0 if u is None else u)])


@pytest.mark.parametrize("name", sorted(ORDERS))
def test_the_step_routine_equals_the_reference_step(name):
    tab = METHODS[name]
    control = lambda t, x: 0.3 * math.cos(2.0 * t) + 0.1 * x[0]  # noqa: E731
    x = np.array([0.7, -0.2])
    K = np.empty((tab.stages, 2))
    K[0] = pendulum(0.4, x, control(0.4, x))
    expected = rk_step(pendulum, 0.4, x, 0.05, tab, K, control)
    got, stages = Stepper(tab).step(pendulum, 0.4, x, 0.05, K[0].copy(), control)
    np.testing.assert_allclose(got, expected, rtol=1e-15, atol=1e-16)
    np.testing.assert_allclose(stages, K, rtol=1e-15, atol=1e-16)
    if tab.fsal:  # the last stage is the field at the new point, ready for the next step
        np.testing.assert_allclose(stages[-1], pendulum(0.45, got, control(0.45, got)), rtol=1e-14)


def fitted_order(hs, errors) -> float:
    return float(np.polyfit(np.log(hs), np.log(errors), 1)[0])


@pytest.mark.parametrize("name", ["bs32", "dopri5"])
def test_error_estimate_is_the_lower_order_local_error(name):
    tab = METHODS[name]
    stepper, rk4 = Stepper(tab), Stepper(METHODS["rk4"])
    x = np.array([0.7, -0.2])
    hs = np.array([0.2, 0.1, 0.05, 0.025])
    estimates, true_errors = [], []
    for h in hs:
        x1, stages = stepper.step(pendulum, 0.0, x, h, pendulum(0.0, x, None), None)
        estimate = stepper.error_estimate(h, stages)
        estimates.append(np.abs(estimate).max())
        # Local error of the embedded (lower-order) solution: against a many-step rk4 reference.
        ref = x.copy()
        sub = 200
        for k in range(sub):
            ref, _ = rk4.step(pendulum, k * h / sub, ref, h / sub, pendulum(k * h / sub, ref, None), None)
        true_errors.append(np.abs(x1 - estimate - ref).max())
    # Both fall like h^(q+1), q the embedded order: the estimate measures the embedded error.
    assert fitted_order(hs, estimates) == pytest.approx(tab.error_order + 1, abs=0.25)
    assert fitted_order(hs, true_errors) == pytest.approx(tab.error_order + 1, abs=0.25)
    np.testing.assert_allclose(estimates[-1], true_errors[-1], rtol=0.1)


def forced_pendulum(t, x, u=None):
    return np.array([x[1], -math.sin(x[0]) + 0.3 * math.cos(1.7 * t)])


def test_the_error_norms_are_their_formulas():
    # DOP853's norm is Hairer's blend of E5 and E3 (scipy's DOP853 norm); the plain norm of the
    # other pairs is the RMS of the scaled estimate.
    tableau = get_method("dop853")
    x0 = np.array([0.7, -0.4])
    h = 0.05
    stepper = Stepper(tableau)
    x1, stages = stepper.step(forced_pendulum, 0.3, x0, h, forced_pendulum(0.3, x0), None)
    K = np.zeros((tableau.stages, 2))
    K[0] = forced_pendulum(0.3, x0)
    ref = rk_step(forced_pendulum, 0.3, x0, h, tableau, K)
    np.testing.assert_allclose(x1, ref, rtol=0, atol=1e-15)
    scale = 1e-6 + 1e-6 * np.maximum(np.abs(x0), np.abs(x1))
    e5 = np.linalg.norm(h * (tableau.b_err @ K) / scale) ** 2
    e3 = np.linalg.norm(h * (tableau.b_err_low @ K) / scale) ** 2
    hairer = e5 / np.sqrt((e5 + 0.01 * e3) * 2)
    assert stepper.error_norm(h, stages, x0, x1, 1e-6, 1e-6) == pytest.approx(hairer, rel=1e-12)

    pair = Stepper(get_method("dopri5"))
    x1, stages = pair.step(forced_pendulum, 0.3, x0, h, forced_pendulum(0.3, x0), None)
    scale = 1e-6 + 1e-6 * np.maximum(np.abs(x0), np.abs(x1))
    expected = float(np.sqrt(np.mean((pair.error_estimate(h, stages) / scale) ** 2)))
    assert pair.error_norm(h, stages, x0, x1, 1e-6, 1e-6) == pytest.approx(expected, rel=1e-14)
