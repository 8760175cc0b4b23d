"""The continuous extension of one step, evaluated anywhere inside it."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from ..errors import SimulationError
from .tableau import Tableau


class ContinuousStep:
    """The dense output of one step of ``tableau`` (which must carry ``dense``): evaluates its
    extra stages, if any, once; then ``point(theta)`` and ``slope(theta)`` give x and dx/dt at
    t + theta h for theta in [0, 1].

    ``extra_evals`` is the number of field evaluations the extra stages cost.
    """

    def __init__(
        self,
        tableau: Tableau,
        field: Callable[..., np.ndarray],
        t: float,
        x: np.ndarray,
        h: float,
        stages: tuple[np.ndarray, ...],
        control: Callable[[float, np.ndarray], Any] | None = None,
    ) -> None:
        dense = tableau.dense
        if dense is None:
            raise SimulationError(f"method '{tableau.name}' has no dense output")
        K = np.empty((len(dense.P), len(x)))
        K[: len(stages)] = stages
        for i, (ci, row) in enumerate(zip(dense.c_extra, dense.A_extra, strict=True)):
            s = len(stages) + i
            xi = x + h * (row[:s] @ K[:s])
            ti = t + float(ci) * h
            K[s] = field(ti, xi, None if control is None else control(ti, xi))
        self.extra_evals = len(dense.c_extra)
        self._x, self._h, self._K, self._P = x, h, K, dense.P
        self._powers = np.arange(1, dense.P.shape[1] + 1)

    def point(self, theta: float) -> np.ndarray:
        """x at t + theta h, shape (n,)."""
        w = self._P @ (theta**self._powers)
        return self._x + self._h * (w @ self._K)

    def slope(self, theta: float) -> np.ndarray:
        """dx/dt at t + theta h, shape (n,)."""
        w = self._P @ (self._powers * theta ** (self._powers - 1))
        return w @ self._K
