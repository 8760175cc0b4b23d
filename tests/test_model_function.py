"""``model_function``'s dispatcher: a helper that compiled code calls with constant arguments
is compiled once for their types (``OneSpecialization``), not once per value, with the same
results; one that compiles only for a constant's value still gets it. Compiled in the process
(``cache=False``), so that each run of the test compiles and counts afresh."""

from __future__ import annotations

import numpy as np
from numba import types

from legsim.compiled.functions import model_function


@model_function(cache=False)
def weighted(x, k, doubled):
    """x[k], twice over when ``doubled``."""
    return 2.0 * x[k] if doubled else x[k]


@model_function(cache=False)
def sum_of_constant_calls(x):
    return weighted(x, 0, False) + weighted(x, 1, True) + weighted(x, 2, False)


@model_function(cache=False)
def pick(pair, k):
    # Types only with k's value: the tuple's items have different types.
    return pair[k]


@model_function(cache=False)
def first_of_pair(x):
    return pick((x[0], x), 0)


def test_constant_arguments_compile_one_specialization_with_the_same_results():
    x = np.array([1.5, -2.0, 4.25])
    assert sum_of_constant_calls(x) == 1.5 + 2.0 * -2.0 + 4.25
    # numba's own dispatcher compiles one per distinct value: (0, False), (1, True), (2, False).
    assert weighted.signatures == [(types.float64[::1], types.int64, types.boolean)]


def test_a_helper_that_types_only_for_a_constants_value_still_gets_the_value():
    assert first_of_pair(np.array([3.0, 1.0])) == 3.0
    assert pick.signatures == [(types.Tuple((types.float64, types.float64[::1])), types.IntegerLiteral(0))]
