"""The textbook explicit Runge-Kutta step, the readable reference the generated steppers
(``legsim.methods.stepper``) are tested against."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from legsim.methods import Tableau


def rk_step(
    field: Callable[[float, np.ndarray, Any], np.ndarray],
    t: float,
    x: np.ndarray,
    h: float,
    tableau: Tableau,
    K: np.ndarray,
    control: Callable[[float, np.ndarray], Any] | None = None,
) -> np.ndarray:
    """One step of size h from (t, x). ``K`` (s, n) holds f(t, x, u(t, x)) in its first row on
    entry and all stages on exit; the control is sampled at each stage. Returns the new state."""
    A, c = tableau.A, tableau.c
    for i in range(1, tableau.stages):
        xi = x + h * (A[i, :i] @ K[:i])
        ti = t + c[i] * h
        K[i] = field(ti, xi, None if control is None else control(ti, xi))
    return x + h * (tableau.b @ K)
