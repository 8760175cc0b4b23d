"""Explicit Runge-Kutta methods as data (``tableau``, ``builtin``), the one step routine and
error norm they share (``stepper``), and their continuous extensions (``dense``)."""

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
from .dense import ContinuousStep
from .stepper import error_estimate, error_estimator, error_norm, make_error_norm, make_stepper, stage_groups
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
    "ContinuousStep",
    "DenseOutput",
    "Tableau",
    "dense_output",
    "error_estimate",
    "error_estimator",
    "error_norm",
    "get_method",
    "make_error_norm",
    "make_stepper",
    "stage_groups",
    "tableau",
]
