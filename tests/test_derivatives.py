"""The finite-difference helper against closed-form derivatives, at the accuracy its steps promise."""

import numpy as np
import pytest

from legsim.derivatives import gradient, jacobian


def field(x):
    return np.array([np.sin(x[0]) * x[1], x[0] ** 3 + np.exp(x[1]), 5.0])


def exact(x):
    return np.array([[np.cos(x[0]) * x[1], np.sin(x[0])], [3 * x[0] ** 2, np.exp(x[1])], [0.0, 0.0]])


@pytest.mark.parametrize("x", [np.array([0.3, -1.2]), np.array([40.0, 2.5]), np.array([1e-9, 0.0])])
def test_central_differences_are_accurate_to_1e_9_relative(x):
    J = jacobian(field, x)
    assert J.shape == (3, 2)
    assert np.allclose(J, exact(x), rtol=1e-9, atol=1e-9 * np.abs(exact(x)).max())


def test_forward_differences_are_accurate_to_1e_7_relative_and_reuse_f0():
    x = np.array([0.7, 0.4])
    calls = []

    def counted(y):
        calls.append(1)
        return field(y)

    J = jacobian(counted, x, scheme="forward", f0=field(x))
    assert len(calls) == 2  # one evaluation per coordinate, fn(x) given
    assert np.allclose(J, exact(x), rtol=1e-7, atol=1e-7)


def test_gradient_of_a_scalar_and_a_given_scale():
    x = np.array([2.0, -3.0, 0.5])
    g = gradient(lambda y: float(y @ y), x, scale=1.0)
    assert np.allclose(g, 2 * x, rtol=1e-10)


def test_unknown_scheme_is_refused():
    with pytest.raises(ValueError, match="central"):
        jacobian(field, np.zeros(2), scheme="backward")
