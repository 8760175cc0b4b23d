"""A model function of the state shape ``fn(t, a, b, c, out)`` evaluated at many stored points
in one compiled call, for checks that scan a whole run (a controller's input at every stored
point); a function numba does not compile is called point by point from Python.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .functions import model_function
from .native import address, call_state_at, compiles


@model_function
def _at_rows(address: int, t: np.ndarray, states: np.ndarray, split: int, c: np.ndarray, out: np.ndarray) -> None:
    for k in range(states.shape[0]):
        # An intrinsic's typing context is numba's to pass: compiled code calls it without one.
        call_state_at(address, t[k], states[k, :split], states[k, split:], c, out[k])  # type: ignore[call-arg]


def at_rows(function: Any, t: np.ndarray, states: np.ndarray, split: int, c: np.ndarray, out: np.ndarray) -> None:
    """``function(t[k], states[k, :split], states[k, split:], c, out[k])`` for every row k.

    t (rows,) in s; states (rows, width) and out (rows, outputs), float64, C-contiguous; c the
    function's parameter array."""
    if compiles(function):
        _at_rows(address(function, "state"), t, states, split, c, out)
        return
    for k in range(states.shape[0]):
        function(float(t[k]), states[k, :split], states[k, split:], c, out[k])
