"""The arguments of the metric functions, checked: hybrid points of M^eps, the strip width eps,
the hop cap, sample times, and the error all of them raise (``MetricError``)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import LegsimError, ModelError
from ..hybrid import HybridSystem

#: Default number of transition crossings searched for a shortest path.
DEFAULT_MAX_HOPS = 2


class MetricError(LegsimError, ValueError):
    """Invalid input to a metric function (point, eps, times, execution)."""


@dataclass(frozen=True)
class HybridPoint:
    """A point of M^eps.

    ``x`` (shape (n_mode,)) is a state of the domain of ``mode``; when ``strip`` names a
    transition leaving ``mode``, the point lies in that transition's strip instead: ``x`` is
    its guard point and ``tau`` in [0, eps] (guard units) the transverse coordinate, tau = eps
    being the reset image.
    """

    mode: str
    x: np.ndarray
    strip: str | None = None
    tau: float = 0.0


def _is_number(value: Any) -> bool:
    # bool is an int to Python, but True as a strip width is a caller's mistake.
    return not isinstance(value, bool) and isinstance(value, (int, float, np.floating, np.integer))


def check_system(system: Any) -> HybridSystem:
    """``system`` itself, when it is a ``HybridSystem``."""
    if not isinstance(system, HybridSystem):
        raise MetricError(f"system must be a legsim.HybridSystem, got {type(system).__name__}")
    return system


def check_eps(eps: Any) -> float:
    """The strip width as a float >= 0 (guard units)."""
    if not _is_number(eps):
        raise MetricError(f"eps must be a number >= 0 (strip width, guard units), got {type(eps).__name__} {eps!r}")
    eps = float(eps)
    if not math.isfinite(eps) or eps < 0.0:
        raise MetricError(f"eps must be finite and >= 0 (strip width, guard units), got {eps}")
    return eps


def check_hops(max_hops: Any) -> int:
    """The cap on transition crossings as an int >= 0."""
    if isinstance(max_hops, bool) or not isinstance(max_hops, (int, np.integer)) or max_hops < 0:
        raise MetricError(f"max_hops must be an integer >= 0, got {max_hops!r}")
    return int(max_hops)


def check_times(times: Any) -> np.ndarray:
    """Sample times (s) as a non-empty finite array of shape (n,)."""
    try:
        arr = np.atleast_1d(np.asarray(times, dtype=float))
    except (TypeError, ValueError) as exc:
        raise MetricError(f"times must be a 1-d sequence of numbers (s): {exc}") from None
    if arr.ndim != 1 or arr.size == 0:
        raise MetricError(f"times must be a non-empty 1-d sequence (s), got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise MetricError("times must be finite")
    return arr


def check_point(system: HybridSystem, point: Any, eps: float, label: str) -> HybridPoint:
    """``(mode, x)`` or ``(mode, x, transition name, tau)`` as a ``HybridPoint`` of ``system``;
    ``label`` names the argument in the error message."""
    if isinstance(point, HybridPoint):
        return point
    if not isinstance(point, (tuple, list)) or len(point) not in (2, 4):
        raise MetricError(f"{label} must be (mode, x) or (mode, x, transition name, tau), got {point!r}")
    mode = point[0]
    x = _check_state(system, mode, point[1], label)
    if len(point) == 2:
        return HybridPoint(mode, x)
    name, tau = point[2], point[3]
    names = [tr.name for tr in system.outgoing(mode)]
    if name not in names:
        raise MetricError(f"{label}: '{name}' is not a transition leaving mode '{mode}' (those are {names})")
    if not _is_number(tau) or not math.isfinite(float(tau)) or not 0.0 <= float(tau) <= eps:
        raise MetricError(f"{label}: strip coordinate tau must be a number in [0, eps={eps:g}], got {tau!r}")
    return HybridPoint(mode, x, str(name), float(tau))


def _check_state(system: HybridSystem, mode: Any, state: Any, label: str) -> np.ndarray:
    if not isinstance(mode, str):
        raise MetricError(f"{label}: mode must be a mode name (str), got {mode!r}")
    try:
        dim = system.mode(mode).dim
    except ModelError:
        raise MetricError(f"{label}: unknown mode '{mode}' of {system.name} (modes: {sorted(system.modes)})") from None
    try:
        x = np.array(state, dtype=float)
    except (TypeError, ValueError) as exc:
        raise MetricError(f"{label}: state in mode '{mode}' is not a numeric vector: {exc}") from None
    if x.shape != (dim,):
        raise MetricError(
            f"{label}: state in mode '{mode}' has shape {x.shape}, expected ({dim},) "
            f"with coordinates {system.state_names(mode)}"
        )
    if not np.all(np.isfinite(x)):
        raise MetricError(f"{label}: state in mode '{mode}' is not finite: {x.tolist()}")
    return x
