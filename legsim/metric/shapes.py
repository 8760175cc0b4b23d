"""Declarations a model can use so that the metric knows the shape of its guards and resets.

Both are plain callables, usable directly as ``Transition.guard`` and ``Transition.reset``: the
integrator sees no difference, while the metric projects onto a ``CoordinateGuard`` exactly and
minimises over the guard points of an ``AffineReset`` as a convex problem. (Plain functions of
these forms are recognised too, by probing: ``legsim.metric.detect``.)
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..errors import ModelError


class CoordinateGuard:
    """A guard ``g(x) = max_k scale_k * (x[index_k] - value_k)`` (distinct indices).

    Callable, so it can be used directly as ``Transition.guard``; the metric projects onto its
    zero set exactly. ``CoordinateGuard((0, 1.0, 0.0), (1, 1.0, 0.0))`` is the bouncing ball's
    ``max(z, zd)``; ``CoordinateGuard((0, -1.0, x_max), (1, -1.0, 0.0))`` the stop
    ``max(x_max - x, -v)``. Units: those of ``scale * x``.
    """

    __slots__ = ("terms",)

    def __init__(self, *terms: tuple[int, float, float]) -> None:
        if not terms:
            raise ModelError("CoordinateGuard needs at least one term (index, scale, value)")
        clean = [_clean_term(term) for term in terms]
        if len({t[0] for t in clean}) != len(clean):
            raise ModelError(f"CoordinateGuard indices must be distinct, got {[t[0] for t in clean]}")
        self.terms: tuple[tuple[int, float, float], ...] = tuple(clean)

    def __call__(self, x: np.ndarray) -> float:
        best = -math.inf
        for index, scale, value in self.terms:
            v = scale * (float(x[index]) - value)
            if v > best:
                best = v
        return best

    def __repr__(self) -> str:
        return f"CoordinateGuard{self.terms!r}"


def _clean_term(term: Any) -> tuple[int, float, float]:
    try:
        index, scale, value = term
    except (TypeError, ValueError):
        raise ModelError(f"CoordinateGuard terms are (index, scale, value), got {term!r}") from None
    if isinstance(index, bool) or not isinstance(index, (int, np.integer)) or index < 0:
        raise ModelError(f"CoordinateGuard index must be an integer >= 0, got {index!r}")
    scale, value = float(scale), float(value)
    if not (math.isfinite(scale) and scale != 0.0 and math.isfinite(value)):
        raise ModelError(f"CoordinateGuard term {term!r}: scale must be finite and nonzero, value finite")
    return int(index), scale, value


class AffineReset:
    """A reset ``R(x) = matrix @ x + offset`` (matrix shape (n_target, n_source)).

    Callable, so it can be used as ``Transition.reset``; the metric then minimises over guard
    points exactly (a convex problem) and uses ``matrix`` as the Jacobian.
    """

    __slots__ = ("matrix", "offset")

    def __init__(self, matrix: Any, offset: Any = None) -> None:
        A = np.array(matrix, dtype=float)
        if A.ndim != 2 or not np.all(np.isfinite(A)):
            raise ModelError(f"AffineReset matrix must be a finite 2-d array, got shape {A.shape}")
        r = np.zeros(A.shape[0]) if offset is None else np.array(offset, dtype=float).reshape(-1)
        if r.shape != (A.shape[0],) or not np.all(np.isfinite(r)):
            raise ModelError(f"AffineReset offset must be finite of shape ({A.shape[0]},), got {r.shape}")
        self.matrix = A
        self.offset = r

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return self.matrix @ np.asarray(x, dtype=float) + self.offset

    def __repr__(self) -> str:
        return f"AffineReset({self.matrix.tolist()}, {self.offset.tolist()})"
