"""One Runge-Kutta step of a Python field, for tools that step outside a run (error bounds,
baselines, tests): the loop's own stage routine (``stages.stages``) and error estimate
(``stages.estimate``) on a one-mode table around the field."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from ..methods import Tableau
from .evaluate import Tables, visit_of
from .layout import M_CONTROL, M_DIM, M_ENTER, M_FIELD, MODE_FIELDS, S_HOLD, S_MEMORY
from .stages import (
    INFO_EXTRA,
    INFO_IMPLICIT,
    INFO_STAGES,
    dense_point,
    dense_slope,
    error_norm,
    estimate,
    extend,
    hermite_point,
    hermite_slope,
    jacobian,
    method_arrays,
    stages,
)
from .workspace import allocate

FieldFn = Callable[[float, np.ndarray, Any], Any]
ControlFn = Callable[[float, np.ndarray], Any] | None


class Stepper:
    """Steps of ``tableau``: ``step(field, t, x, h, k0, control) -> (x_new, K)`` with K the
    stages (s, n), K[0] = k0; the control is evaluated at every stage."""

    def __init__(self, tableau: Tableau) -> None:
        self.tableau = tableau
        self.method = method_arrays(tableau)
        self._current: tuple[FieldFn, ControlFn] | None = None

    def _evaluate(self, t: float, x: np.ndarray, u: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
        assert self._current is not None
        field, control = self._current
        value = field(t, x, None if control is None else control(t, x))
        out[:] = np.asarray(value, dtype=float)

    def step(
        self, field: FieldFn, t: float, x: np.ndarray, h: float, k0: np.ndarray, control: ControlFn = None
    ) -> tuple[np.ndarray, np.ndarray]:
        n = len(x)
        rows = self.method.info[INFO_STAGES] + max(self.method.info[INFO_EXTRA], 0)
        tab, ws = self._table(n, rows)
        self._current = (field, control)
        try:
            ws.K[0, :n] = k0
            if self.method.info[INFO_IMPLICIT] == 1:
                jacobian(tab, visit_of(tab, 0, 0), ws, t, np.asarray(x, dtype=float), ws.K[0, :n])
            x_new = np.empty(n)
            stages(tab, visit_of(tab, 0, 0), ws, self.method, t, np.asarray(x, dtype=float), h, ws.K, ws.XS, x_new)
        finally:
            self._current = None
        return x_new, ws.K[: self.method.info[INFO_STAGES], :n].copy()

    def error_estimate(self, h: float, K: np.ndarray) -> np.ndarray:
        """The step's local error estimate h sum_j b_err_j K_j, shape (n,)."""
        return np.array([estimate(self.method, K, h, d)[0] for d in range(K.shape[1])])

    def error_norm(self, h: float, K: np.ndarray, x: np.ndarray, x_new: np.ndarray, rtol: float, atol: float) -> float:
        """The norm error control judges the step by (``stages.error_norm``)."""
        return float(error_norm(self.method, np.ascontiguousarray(K), h, np.asarray(x, float),
                                np.asarray(x_new, float), rtol, atol))  # fmt: skip

    def continuous(
        self, field: FieldFn, t: float, x: np.ndarray, h: float, K: np.ndarray, control: ControlFn = None
    ) -> tuple[Callable[[float], np.ndarray], Callable[[float], np.ndarray]]:
        """The step's continuous extension: (point(theta), slope(theta)) at t + theta h, its
        extra stages evaluated once (``stages.extend``, ``dense_point``, ``dense_slope``)."""
        n = len(x)
        rows = self.method.info[INFO_STAGES] + max(self.method.info[INFO_EXTRA], 0)
        tab, ws = self._table(n, rows)
        ws.K[: K.shape[0], :n] = K
        self._current = (field, control)
        try:
            extend(tab, visit_of(tab, 0, 0), ws, self.method, t, np.asarray(x, float), h, ws.K, ws.XS)
        finally:
            self._current = None
        stages_all, x0 = ws.K[:rows, :n].copy(), np.asarray(x, float).copy()

        def point(theta: float) -> np.ndarray:
            out = np.empty(n)
            dense_point(self.method, x0, h, stages_all, theta, out)
            return out

        def slope(theta: float) -> np.ndarray:
            out = np.empty(n)
            dense_slope(self.method, stages_all, theta, out)
            return out

        return point, slope

    def _table(self, n: int, rows: int) -> tuple[Tables, Any]:
        ws = allocate(n, 1, rows, 0, 0, 1)
        ws.ci[S_MEMORY] = ws.ci[S_HOLD] = 0
        modes = np.zeros((1, MODE_FIELDS), dtype=np.int64)
        modes[0, M_DIM], modes[0, M_FIELD] = n, 0
        modes[0, M_CONTROL] = modes[0, M_ENTER] = -1
        tab = Tables([self._evaluate], modes, np.zeros((0, 2), dtype=np.int64), np.zeros((0, 1), dtype=np.int64),
                     np.zeros(0))  # fmt: skip
        return tab, ws


def hermite(x0: np.ndarray, d0: np.ndarray, x1: np.ndarray, d1: np.ndarray, dt: float, s: Any) -> np.ndarray:
    """The cubic Hermite interpolant of a step of length dt (ends x0, x1, slopes d0, d1) at
    fraction s (a number, shape (n,)), as the loop's curves (``stages.hermite_point``)."""
    out = np.empty(len(x0))
    hermite_point(np.asarray(x0, float), np.asarray(d0, float), np.asarray(x1, float), np.asarray(d1, float),
                  float(dt), float(s), out)  # fmt: skip
    return out


def hermite_derivative(x0: np.ndarray, d0: np.ndarray, x1: np.ndarray, d1: np.ndarray, dt: float, s: Any) -> np.ndarray:
    """d/dt of ``hermite`` at fraction s, shape (n,)."""
    out = np.empty(len(x0))
    hermite_slope(np.asarray(x0, float), np.asarray(d0, float), np.asarray(x1, float), np.asarray(d1, float),
                  float(dt), float(s), out)  # fmt: skip
    return out
