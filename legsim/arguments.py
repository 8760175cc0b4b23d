"""Checks of the numeric arguments of the public functions: each returns the value in the type
the algorithm uses, or raises ``SimulationError`` naming the argument and what is allowed."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .errors import SimulationError


def positive(name: str, value: Any) -> float:
    """``value`` as a finite float > 0 (a step size in s, a strip width, a tolerance)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise SimulationError(f"{name} must be a number, got {type(value).__name__} {value!r}")
    value = float(value)
    if not math.isfinite(value) or value <= 0.0:
        raise SimulationError(f"{name} must be finite and > 0, got {value}")
    return value


def count(name: str, value: Any, low: int) -> int:
    """``value`` as an int >= low (a budget or a number of refinements)."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
        raise SimulationError(f"{name} must be an integer >= {low}, got {value!r}")
    return int(value)
