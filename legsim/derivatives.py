"""Finite-difference derivatives: the one helper every tool uses where a model gives no
Jacobian of its own (field Jacobians, guard gradients, reset Jacobians, metric constraints).

Steps follow the usual rule for a smooth function evaluated to rounding: the relative step that
balances truncation against rounding is sqrt(machine eps) for forward differences (error
~1e-8) and cbrt(machine eps) for central ones (error ~1e-11). Each coordinate's step is scaled
by ``max(1, |x_j|)`` unless the caller gives a scale, and the step actually taken (after
rounding x_j + d) is the one divided by.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

#: Relative step of forward differences: sqrt(machine eps).
FORWARD_STEP = math.sqrt(float(np.finfo(float).eps))
#: Relative step of central differences: cbrt(machine eps).
CENTRAL_STEP = float(np.finfo(float).eps) ** (1.0 / 3.0)

Scheme = Literal["central", "forward"]


def jacobian(
    fn: Callable[[np.ndarray], ArrayLike],
    x: np.ndarray,
    *,
    scheme: Scheme = "central",
    step: float | None = None,
    scale: float | np.ndarray | None = None,
    f0: np.ndarray | None = None,
) -> np.ndarray:
    """d fn / dx at ``x`` by finite differences, shape (m, n) for fn: R^n -> R^m.

    Parameters
    ----------
    fn: the function, taking an array of shape (n,) and returning shape (m,) (or a scalar: m = 1).
    x: where, shape (n,).
    scheme: ``"central"`` (2n evaluations) or ``"forward"`` (n evaluations, plus one for
        ``fn(x)`` unless ``f0`` gives it).
    step: relative step; default ``CENTRAL_STEP`` or ``FORWARD_STEP`` by scheme.
    scale: the size each coordinate's step is relative to, a number or shape (n,); default
        ``max(1, |x_j|)``.
    f0: ``fn(x)`` when the caller has it (forward differences only).
    """
    x = np.asarray(x, dtype=float)
    n = x.shape[0]
    rel = step if step is not None else (CENTRAL_STEP if scheme == "central" else FORWARD_STEP)
    sizes = np.maximum(1.0, np.abs(x)) if scale is None else np.broadcast_to(np.asarray(scale, dtype=float), (n,))
    if scheme == "forward":
        base = np.atleast_1d(np.asarray(fn(x) if f0 is None else f0, dtype=float))
    columns = []
    for j in range(n):
        d = rel * float(sizes[j])
        plus = x.copy()
        plus[j] += d
        if scheme == "central":
            minus = x.copy()
            minus[j] -= d
            width = plus[j] - minus[j]  # the steps actually taken, after rounding
            columns.append(
                (np.atleast_1d(np.asarray(fn(plus), dtype=float)) - np.atleast_1d(np.asarray(fn(minus), dtype=float)))
                / width
            )
        elif scheme == "forward":
            columns.append((np.atleast_1d(np.asarray(fn(plus), dtype=float)) - base) / (plus[j] - x[j]))
        else:
            raise ValueError(f"scheme must be 'central' or 'forward', got {scheme!r}")
    return np.column_stack(columns) if columns else np.zeros((0, 0))


def gradient(fn: Callable[[np.ndarray], float], x: np.ndarray, **options) -> np.ndarray:
    """The gradient of a scalar ``fn`` at ``x``, shape (n,); options as for ``jacobian``."""
    return jacobian(fn, x, **options)[0]
