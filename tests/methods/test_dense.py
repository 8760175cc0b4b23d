"""The methods' continuous extensions (bs32, dopri5, DOP853): each is a Runge-Kutta step of its
stated order at any fraction of the step, and meets the step's ends."""

import math

import numpy as np
import pytest

from legsim.methods import dense_output, get_method
from legsim.relaxed.single import Stepper

PAIRS = [get_method("bs32"), get_method("dopri5"), get_method("dop853")]


def forced_pendulum(t, x, u=None):
    return np.array([x[1], -math.sin(x[0]) + 0.3 * math.cos(1.7 * t)])


def reference(t_end, x0):
    from scipy.integrate import solve_ivp

    return solve_ivp(forced_pendulum, (0.0, t_end), x0, method="DOP853", rtol=1e-13, atol=1e-15).y[:, -1]


@pytest.mark.parametrize("tableau", PAIRS, ids=lambda t: t.name)
def test_dense_output_has_its_order_and_meets_the_step_ends(tableau):
    dense = dense_output(tableau)
    stepper = Stepper(tableau)
    x0 = np.array([1.0, 0.2])
    errors, slope_errors = [], []
    hs = (0.4, 0.2, 0.1)
    for h in hs:
        x1, stages = stepper.step(forced_pendulum, 0.0, x0, h, forced_pendulum(0.0, x0), None)
        point, slope = stepper.continuous(forced_pendulum, 0.0, x0, h, stages)
        np.testing.assert_allclose(point(0.0), x0, rtol=0, atol=1e-15)
        np.testing.assert_allclose(point(1.0), x1, rtol=0, atol=1e-14)
        theta = 0.37
        exact = reference(theta * h, x0)
        errors.append(np.abs(point(theta) - exact).max())
        slope_errors.append(np.abs(slope(theta) - forced_pendulum(theta * h, exact)).max())
    # Local error O(h^(order+1)) of the value, O(h^order) of the slope.
    rates = np.log2(np.array(errors[:-1]) / errors[1:])
    slope_rates = np.log2(np.array(slope_errors[:-1]) / slope_errors[1:])
    assert np.all(np.abs(rates - (dense.order + 1)) < 0.3), rates
    assert np.all(np.abs(slope_rates - dense.order) < 0.3), slope_rates
