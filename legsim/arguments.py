"""Checks of the numeric arguments of the public functions: each returns the value in the type
the algorithm uses, or raises ``SimulationError`` naming the argument and what is allowed."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .errors import ModelError, SimulationError
from .hybrid import HybridSystem


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


def check_start(system: HybridSystem, mode: Any, x0: Any) -> np.ndarray:
    """x0 as a state of ``mode`` of ``system``, shape (n,), or SimulationError naming what is
    wrong."""
    if not isinstance(system, HybridSystem):
        raise SimulationError(f"system must be a legsim.HybridSystem, got {type(system).__name__}")
    if not isinstance(mode, str):
        raise SimulationError(f"mode must be a mode name (str), got {mode!r}")
    try:
        system.mode(mode)
    except ModelError as exc:
        raise SimulationError(f"unknown mode {mode!r}: {exc}") from exc
    return system.check_state(mode, x0, label="x0")


def check_t_final(t_final: Any, t0: float) -> float:
    """t_final (s) as a float, or SimulationError unless it is a finite number after t0."""
    if not (isinstance(t_final, (int, float, np.integer, np.floating)) and math.isfinite(t_final) and t_final > t0):
        raise SimulationError(f"t_final must be a finite number > t0 = {t0}, got {t_final!r}")
    return float(t_final)
