"""Explicit Runge-Kutta methods as data: a Butcher tableau and, where a method has one, its
continuous extension (dense output)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike


@dataclass(frozen=True, eq=False)
class DenseOutput:
    """Continuous extension (dense output) of a Runge-Kutta step of size h from (t, x):

        x(t + theta h) = x + h sum_i w_i(theta) k_i,   w_i(theta) = sum_j P[i, j] theta^(j + 1),

    over the step's s stages followed by m extra stages (theta in [0, 1]). Taken at one theta it
    is itself an explicit Runge-Kutta step of size theta h, of order ``order``.

    Attributes
    ----------
    order: order of the interpolant (local error O(h^(order + 1))).
    P: (s + m, degree) polynomial weights.
    c_extra: (m,) nodes of the extra stages (empty when the interpolant is free).
    A_extra: (m, s + m) their stage weights (row i over the stages before it).
    """

    order: int
    P: np.ndarray
    c_extra: np.ndarray = field(default_factory=lambda: np.zeros(0))
    A_extra: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))


@dataclass(frozen=True)
class Tableau:
    """Butcher tableau of a Runge-Kutta method: explicit, or linearly implicit (a Rosenbrock
    W-method, ``gamma > 0``), whose stages k_i solve

        (I - gamma h J) k_i = f(t + c_i h, x + h sum_{j<i} A_ij k_j) + sum_{j<i} G_ij k_j + g_i h df/dt

    with J an approximation of df/dx (a W-method keeps its order for any J, so J may be reused
    over many steps); x_new = x + h sum b_i k_i either way.

    Attributes
    ----------
    name: short name used by ``simulate(method=...)``.
    order: order of the propagated solution.
    c, A, b: nodes (s,), matrix (s, s) and weights (s,).
    b_err: weights of the local error estimate (s,), or None when the method has no
        embedded pair.
    error_order: order of the embedded (lower-order) solution, when there is one; the step-size
        controller's exponent is -1 / (min(order, error_order) + 1).
    fsal: the last stage is f at the new point (First Same As Last), so the next step
        reuses it and saves one field evaluation.
    dense: the method's continuous extension, when it has one (``landing="dense"``).
    b_err_low: a second, lower-order error estimate that the error norm blends with b_err as
        Hairer's DOP853 does (``err5^2 / sqrt(err5^2 + 0.01 err3^2)``), or None.
    gamma: the diagonal of a linearly implicit method (0: explicit).
    G: the stage coupling G (s, s) of a linearly implicit method, or None.
    time_weights: a linearly implicit method's weights g_i of df/dt in its stages (a
        non-autonomous field: the right-hand side of stage i gains g_i h df/dt), or None.
    """

    name: str
    order: int
    c: np.ndarray
    A: np.ndarray
    b: np.ndarray
    b_err: np.ndarray | None = None
    error_order: int | None = None
    fsal: bool = False
    dense: DenseOutput | None = None
    b_err_low: np.ndarray | None = None
    gamma: float = 0.0
    G: np.ndarray | None = None
    time_weights: np.ndarray | None = None

    @property
    def implicit(self) -> bool:
        """Whether the method is linearly implicit (its stages solve with I - gamma h J)."""
        return self.gamma > 0.0

    @property
    def stages(self) -> int:
        """Number of stages s."""
        return len(self.b)

    @property
    def embedded(self) -> bool:
        """True when the method carries a local error estimate."""
        return self.b_err is not None


def tableau(
    name: str,
    order: int,
    c: ArrayLike,
    A: Sequence[Sequence[float]],
    b: ArrayLike,
    b_hat: ArrayLike | None = None,
    error_order: int | None = None,
    fsal: bool = False,
    dense: DenseOutput | None = None,
    b_err_low: ArrayLike | None = None,
) -> Tableau:
    """A ``Tableau`` from rows of A (each as long as its stage index), with the consistency
    checks that catch a mistyped coefficient (row sums of A equal c, weights sum to 1).
    ``b_hat`` is the embedded solution's weights; the tableau keeps b - b_hat."""
    c_arr = np.array(c, dtype=float)
    s = len(c_arr)
    A_arr = np.zeros((s, s))
    for i, row in enumerate(A):
        A_arr[i, : len(row)] = row
    b_arr = np.array(b, dtype=float)
    b_err = None if b_hat is None else b_arr - np.array(b_hat, dtype=float)
    if not np.allclose(A_arr.sum(axis=1), c_arr, rtol=0.0, atol=1e-13):
        raise ValueError(f"tableau {name}: the rows of A must sum to c")
    if abs(b_arr.sum() - 1.0) > 1e-13:
        raise ValueError(f"tableau {name}: the weights b must sum to 1")
    low = None if b_err_low is None else np.array(b_err_low, dtype=float)
    return Tableau(name, order, c_arr, A_arr, b_arr, b_err, error_order, fsal, dense, low)


def check_tableau(method: Tableau) -> Tableau:
    """``method`` itself, once its arrays are consistent: shapes of s stages, finite entries,
    stages that use only earlier ones, an explicit method's rows of A summing to c and weights b
    summing to 1 (to 1e-12), an FSAL method's last stage its new point. ValueError naming the
    method and what is wrong: a ``Tableau`` built by hand is used as given, and a mistyped one
    would run quietly wrong (or read past its arrays in the compiled loop). Checked once per
    object (about 0.1 ms, a short run's worth): a tableau is frozen, its arrays constants."""
    if getattr(method, "_checked", False):
        return method
    name = method.name
    s = len(np.atleast_1d(method.b))
    shapes = {"c": (s,), "A": (s, s), "b": (s,), "b_err": (s,), "b_err_low": (s,), "G": (s, s), "time_weights": (s,)}
    for key, shape in shapes.items():
        value = getattr(method, key)
        if value is None:
            continue
        array = np.asarray(value)
        if array.shape != shape or not np.issubdtype(array.dtype, np.number) or not np.all(np.isfinite(array)):
            raise ValueError(f"Tableau {name!r}: {key} must be finite numbers of shape {shape} for {s} stages (b's)")
    if np.any(np.triu(np.asarray(method.A, dtype=float)) != 0.0) or (
        method.G is not None and np.any(np.triu(np.asarray(method.G, dtype=float)) != 0.0)
    ):
        raise ValueError(f"Tableau {name!r}: stage i may use only stages before it (A and G strictly lower triangular)")
    if not method.implicit:  # a linearly implicit method's A and b act with G on its stages
        _check_sums(method)
    if method.fsal and not (np.allclose(method.A[-1], method.b, rtol=0.0, atol=1e-15) and method.c[-1] == 1.0):
        raise ValueError(f"Tableau {name!r}: fsal needs the last stage at the new point (A's last row b, c = 1)")
    if method.error_order is not None and method.b_err is None:
        raise ValueError(f"Tableau {name!r}: error_order without b_err")
    _check_orders(method)
    if method.implicit and method.G is None:
        raise ValueError(f"Tableau {name!r}: a linearly implicit method (gamma > 0) needs its stage coupling G")
    if method.implicit and method.dense is not None:  # the implicit stages have no continuous extension here
        raise ValueError(f"Tableau {name!r}: a linearly implicit method takes no dense output (its stages are not k_i)")
    _check_dense(name, method.dense, s)
    object.__setattr__(method, "_checked", True)  # not a field: equality and copies ignore it
    return method


def _check_orders(method: Tableau) -> None:
    """Orders are positive integers: the step-size controller's exponent is -1 / (order + 1)."""
    for key in ("order", "error_order"):
        value = getattr(method, key)
        if value is None and key == "error_order":
            continue
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
            raise ValueError(f"Tableau {method.name!r}: {key} must be an integer >= 1, got {value!r}")


def _check_sums(method: Tableau) -> None:
    """An explicit method's consistency: rows of A summing to c, weights b summing to 1."""
    if not np.allclose(np.sum(method.A, axis=1), method.c, rtol=0.0, atol=1e-12):
        raise ValueError(f"Tableau {method.name!r}: the rows of A must sum to c")
    total = float(np.sum(method.b))
    if abs(total - 1.0) > 1e-12:
        raise ValueError(f"Tableau {method.name!r}: the weights b must sum to 1 (they sum to {total:.17g})")


def _check_dense(name: str, dense: DenseOutput | None, s: int) -> None:
    """The continuous extension's arrays fit s stages and its own m extra ones."""
    if dense is None:
        return
    m = len(np.atleast_1d(dense.c_extra))
    P, A_extra = np.asarray(dense.P), np.asarray(dense.A_extra)
    if P.ndim != 2 or P.shape[0] != s + m or (m and A_extra.shape != (m, s + m)) or not np.all(np.isfinite(P)):
        raise ValueError(
            f"Tableau {name!r}: dense output needs P of shape ({s + m}, degree) and A_extra ({m}, {s + m}) "
            f"for {s} stages and {m} extra ones"
        )
