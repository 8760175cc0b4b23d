"""Explicit Runge-Kutta methods as data: Butcher tableaux and their continuous extensions
(``tableau``), the built-in methods by name (``builtin``). The one routine that steps them is the
loop's (``legsim.relaxed.stages``)."""

from .builtin import (
    ALIASES,
    BOGACKI_SHAMPINE,
    DOP853,
    DORMAND_PRINCE,
    EULER,
    HEUN,
    METHODS,
    MIDPOINT,
    RK4,
    dense_output,
    get_method,
)
from .tableau import DenseOutput, Tableau, tableau

__all__ = [
    "ALIASES",
    "BOGACKI_SHAMPINE",
    "DOP853",
    "DORMAND_PRINCE",
    "EULER",
    "HEUN",
    "METHODS",
    "MIDPOINT",
    "RK4",
    "DenseOutput",
    "Tableau",
    "dense_output",
    "get_method",
    "tableau",
]
