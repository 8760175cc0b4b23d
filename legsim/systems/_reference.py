"""Pieces shared by the analytic benchmark systems: samples in the Execution's format and the
polylines their pictures are drawn with."""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np

from ..errors import SimulationError
from ..execution import Samples


def as_times(times: Iterable[float] | float, t0: float) -> np.ndarray:
    """``times`` as a finite 1-d float array, each >= t0 (s); SimulationError otherwise."""
    arr = np.atleast_1d(np.asarray(times, dtype=float))
    if arr.ndim != 1:
        raise SimulationError(f"sample times must be a 1-d sequence, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise SimulationError("sample times must be finite")
    if arr.size and arr.min() < t0 - 1e-12 * max(1.0, abs(t0)):
        raise SimulationError(f"sample times must be >= the reference's start time {t0}, got {arr.min()}")
    return arr


def make_samples(times: np.ndarray, modes: Sequence[str], states: np.ndarray | Sequence[np.ndarray]) -> Samples:
    """A ``Samples`` of an exact execution: no strips (the reference has eps = 0)."""
    return Samples(
        np.asarray(times, dtype=float),
        list(modes),
        [np.array(s, dtype=float) for s in states],
        np.zeros(len(times), dtype=bool),
    )


def box(x_left: float, x_right: float, z_bottom: float, z_top: float) -> np.ndarray:
    """Closed rectangle as a polyline, shape (5, 2), points (x, z) in metres."""
    return np.array(
        [[x_left, z_bottom], [x_right, z_bottom], [x_right, z_top], [x_left, z_top], [x_left, z_bottom]], dtype=float
    )


def segment(p: Sequence[float], q: Sequence[float]) -> np.ndarray:
    """Straight line from p to q as a polyline, shape (2, 2)."""
    return np.array([p, q], dtype=float)


def zigzag(x_start: float, x_end: float, z: float, amplitude: float, turns: int = 8) -> np.ndarray:
    """A spring drawn from (x_start, z) to (x_end, z): shape (2 * turns + 3, 2)."""
    xs = np.linspace(x_start, x_end, 2 * turns + 3)
    zs = np.full_like(xs, z)
    zs[1:-1] += amplitude * np.where(np.arange(1, len(xs) - 1) % 2 == 1, 1.0, -1.0)
    zs[1] = zs[-2] = z
    return np.column_stack([xs, zs])
