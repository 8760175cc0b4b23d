"""How the metric reads the shape of guards and resets: declared shapes are checked against the
mode's dimension; plain functions of coordinate or affine form are recognised exactly, and
others are not."""

from __future__ import annotations

import numpy as np
import pytest

from legsim import HybridSystem, Mode, ModelError, Transition
from legsim.metric import CoordinateGuard, distance
from legsim.metric.detect import detect_affine_reset, detect_coordinate_guard


def test_declared_coordinate_guard_beyond_the_dimension_is_named():
    system = HybridSystem(
        {"m": Mode(1, lambda t, x, u: np.zeros(1))},
        [Transition("m", "m", CoordinateGuard((0, 1.0, 0.0)), lambda x: -x)],
    )
    # A guard declared on a coordinate the mode does not have.
    bad = HybridSystem(
        {"m": Mode(1, lambda t, x, u: np.zeros(1))},
        [Transition("m", "m", CoordinateGuard((3, 1.0, 0.0)), lambda x: -x)],
    )
    assert distance(system, ("m", [1.0]), ("m", [2.0]), 0.1) == pytest.approx(1.0)
    with pytest.raises(
        ModelError, match=r"CoordinateGuard\(\(3, 1\.0, 0\.0\),\) refers to coordinate beyond dimension 1"
    ):
        distance(bad, ("m", [1.0]), ("m", [-2.0]), 0.1)


def test_a_plain_conjunction_of_coordinate_hyperplanes_is_recognised_exactly():
    # The stop max(x_max - x, -v) of the oscillator: constants such as 0.9 come out exact.
    shape = detect_coordinate_guard(lambda x: max(0.9 - x[0], -x[1]), 2, np.zeros(2))
    assert shape is not None
    assert sorted(shape.terms) == [(0, -1.0, 0.9), (1, -1.0, 0.0)]


def test_a_guard_of_another_form_is_not_taken_for_a_coordinate_guard():
    assert detect_coordinate_guard(lambda x: 1.0 - x[0] ** 2 - x[1] ** 2, 2, np.zeros(2)) is None
    assert detect_coordinate_guard(lambda x: x[0] + x[1], 2, np.zeros(2)) is None


def test_a_plain_affine_reset_is_recognised_exactly_and_a_nonlinear_one_is_not():
    A, r = detect_affine_reset(lambda x: np.array([x[1] + 2.0, -0.7 * x[0], x[0] - x[1]]), 2, 3, np.zeros(2))
    np.testing.assert_array_equal(A, [[0.0, 1.0], [-0.7, 0.0], [1.0, -1.0]])
    np.testing.assert_array_equal(r, [2.0, 0.0, 0.0])
    assert detect_affine_reset(lambda x: np.array([x[0] * x[1], x[1]]), 2, 2, np.zeros(2)) is None
    assert detect_affine_reset(lambda x: np.array([x[0]]), 2, 2, np.zeros(2)) is None  # wrong dimension
