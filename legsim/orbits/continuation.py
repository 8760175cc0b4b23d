"""Families of orbits over a parameter: natural-parameter continuation with a secant predictor,
and where along the family the orbits change stability."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from itertools import pairwise
from typing import Any

import numpy as np

from .errors import OrbitError
from .newton import find_orbit
from .problem import OrbitProblem
from .result import OrbitResult


@dataclass
class FamilyPoint:
    """One orbit of a family: the parameter value and the search's result."""

    value: float
    result: OrbitResult


@dataclass
class StabilityChange:
    """Stability changes between two consecutive orbits of a family.

    ``at`` is the parameter value where the largest non-trivial multiplier modulus crosses 1
    (linear interpolation); ``kind`` says how the multiplier leaves the unit circle:
    ``"period doubling"`` (through -1), ``"fold"`` (through +1), ``"torus"`` (a complex pair).
    """

    between: tuple[float, float]
    at: float
    becomes: str  # "stable" or "unstable"
    kind: str
    multiplier: complex

    def describe(self, parameter: str) -> str:
        """One line naming the change, where it is and the multiplier that makes it."""
        return (
            f"{parameter} ~ {self.at:.6g} (between {self.between[0]:.6g} and {self.between[1]:.6g}): becomes "
            f"{self.becomes}, {self.kind} (multiplier {self.multiplier.real:+.4f}{self.multiplier.imag:+.4f}j)"
        )


@dataclass
class Family:
    """A family of orbits over a parameter (``continue_family``)."""

    parameter: str
    points: list[FamilyPoint]
    stability_changes: list[StabilityChange]
    complete: bool
    message: str

    def to_json(self) -> dict[str, Any]:
        """JSON-ready dict (the keys of ``legsim orbit --continue ... --json``)."""
        return {
            "parameter": self.parameter,
            "complete": self.complete,
            "message": self.message,
            "points": [{"value": p.value, **p.result.to_json()} for p in self.points],
            "stability_changes": [
                {
                    "between": list(c.between),
                    "at": c.at,
                    "becomes": c.becomes,
                    "kind": c.kind,
                    "multiplier": [c.multiplier.real, c.multiplier.imag],
                }
                for c in self.stability_changes
            ],
        }


def continue_family(
    problem: OrbitProblem,
    parameter: str,
    start: float,
    stop: float,
    steps: int,
    guess: Mapping[str, float] | Sequence[float] | np.ndarray,
    *,
    max_refinements: int = 4,
    locate: int = 0,
    progress: Callable[[FamilyPoint], None] | None = None,
    **solver: Any,
) -> Family:
    """Follow a family of orbits as ``parameter`` goes from ``start`` to ``stop`` in ``steps``
    equal steps, with a secant predictor (linear extrapolation of the last two orbits' unknowns
    in the parameter; the previous orbit for the second point) and the Newton corrector
    ``find_orbit(**solver)``. A failed correction halves the parameter step, up to
    ``max_refinements`` times, before the family is declared to end there.

    Stability changes are reported between consecutive orbits where the largest non-trivial
    multiplier modulus crosses 1, at the parameter where it crosses 1 by linear interpolation;
    ``locate`` > 0 first narrows each such interval by that many bisections (one orbit search
    each, warm-started by interpolation), so the change is placed within 2**-locate of a step.
    ``progress(point)``, when given, is called after each orbit found.
    """
    _check_continuation(problem, parameter, start, stop, steps)
    x_guess = problem.state_vector(guess)
    grid = [float(v) for v in np.linspace(start, stop, steps + 1)]
    min_step = abs(grid[1] - grid[0]) / 2**max_refinements
    points: list[FamilyPoint] = []
    history: list[tuple[float, np.ndarray, dict[str, float]]] = []  # (value, fixed point, parameters)
    complete = True
    message = f"{steps + 1} orbit(s) from {parameter} = {start:g} to {stop:g}"
    i, value = 0, grid[0]
    while i < len(grid):
        x_pred, params = _predict(problem, parameter, value, history, x_guess)
        result = find_orbit(replace(problem, parameters=params), x_pred, **solver)
        if result.converged:
            point = FamilyPoint(value, result)
            points.append(point)
            history.append((value, result.fixed_point.copy(), dict(result.parameters)))
            if progress is not None:
                progress(point)
            if value == grid[i]:
                i += 1
            if i < len(grid):
                value = grid[i]
            continue
        if history:
            # Halve the step towards the failed value, down to 2**-max_refinements grid steps.
            last = history[-1][0]
            half = last + 0.5 * (value - last)
            if abs(half - last) >= min_step * (1 - 1e-9):
                value = half
                continue
        complete = False
        message = (
            f"the family ends near {parameter} = {value:g} (last orbit at {history[-1][0]:g}): "
            f"{result.status}: {result.message}"
            if history
            else f"no orbit at the start {parameter} = {value:g}: {result.status}: {result.message}"
        )
        break
    changes = _stability_changes(points)
    if locate > 0 and changes:
        changes = [_locate_change(problem, parameter, points, c, locate, solver) for c in changes]
    return Family(parameter, points, changes, complete, message)


def _check_continuation(problem: OrbitProblem, parameter: str, start: float, stop: float, steps: int) -> None:
    if not problem.is_factory:
        raise OrbitError("continuation needs a system factory system(parameters) -> HybridSystem")
    if parameter in problem.free:
        raise OrbitError(f"the continuation parameter '{parameter}' cannot also be a free parameter")
    if isinstance(steps, bool) or not isinstance(steps, int) or steps < 1:
        raise OrbitError(f"steps must be an integer >= 1, got {steps!r}")
    for label, v in (("start", start), ("stop", stop)):
        if not isinstance(v, (int, float)) or not math.isfinite(v):
            raise OrbitError(f"continuation {label} must be a finite number, got {v!r}")
    if start == stop:
        raise OrbitError("continuation needs start != stop")


def _predict(
    problem: OrbitProblem,
    parameter: str,
    value: float,
    history: list[tuple[float, np.ndarray, dict[str, float]]],
    x_guess: np.ndarray,
) -> tuple[np.ndarray, dict[str, float]]:
    """The predicted fixed point and parameters at ``value``: linear extrapolation of the last
    two orbits, the last orbit itself after the first, the user's guess at the start."""
    params = dict(problem.parameters)
    params[parameter] = value
    if len(history) >= 2:
        (v1, x1, p1), (v2, x2, p2) = history[-2], history[-1]
        w = (value - v2) / (v2 - v1)
        for name in problem.free:
            params[name] = p2[name] + w * (p2[name] - p1[name])
        return x2 + w * (x2 - x1), params
    if history:
        for name in problem.free:
            params[name] = history[-1][2][name]
        return history[-1][1].copy(), params
    return x_guess, params


def _locate_change(
    problem: OrbitProblem,
    parameter: str,
    points: list[FamilyPoint],
    change: StabilityChange,
    bisections: int,
    solver: Mapping[str, Any],
) -> StabilityChange:
    """Narrow a stability change's interval by bisection on the parameter, each midpoint's orbit
    warm-started halfway between the bracketing orbits."""
    by_value = {p.value: p for p in points}
    lo, hi = by_value[change.between[0]], by_value[change.between[1]]
    for _ in range(bisections):
        mid_value = 0.5 * (lo.value + hi.value)
        params = dict(problem.parameters)
        params[parameter] = mid_value
        for name in problem.free:
            params[name] = 0.5 * (lo.result.parameters[name] + hi.result.parameters[name])
        x_mid = 0.5 * (lo.result.fixed_point + hi.result.fixed_point)
        result = find_orbit(replace(problem, parameters=params), x_mid, **solver)
        if not result.converged or result.stable is None:
            break
        mid = FamilyPoint(mid_value, result)
        if mid.result.stable == lo.result.stable:
            lo = mid
        else:
            hi = mid
    located = _stability_changes([lo, hi])
    return located[0] if located else change


def _stability_changes(points: list[FamilyPoint]) -> list[StabilityChange]:
    """The changes between consecutive points whose spectral radii lie on either side of 1 (both
    resolved: an orbit whose return map is not differentiable has no verdict to change)."""
    changes = []
    for a, b in pairwise(points):
        ra, rb = a.result.spectral_radius, b.result.spectral_radius
        verdicts = (a.result.stable, b.result.stable)  # None: no multipliers, or a kinked return map
        if ra is None or rb is None or None in verdicts or verdicts[0] == verdicts[1]:
            continue
        at = a.value + (1.0 - ra) * (b.value - a.value) / (rb - ra)
        unstable = a.result if ra >= 1.0 else b.result
        mu = unstable.nontrivial_multipliers
        assert mu is not None  # its spectral radius is not None
        m = complex(mu[np.argmax(np.abs(mu))])
        changes.append(
            StabilityChange((a.value, b.value), at, "unstable" if rb >= 1.0 else "stable", _change_kind(m), m)
        )
    return changes


def _change_kind(m: complex) -> str:
    """How the multiplier m (outside the unit circle) left it."""
    if abs(m.imag) > 1e-9 * max(1.0, abs(m)):
        return "torus (complex pair leaves the unit circle)"
    if m.real < 0:
        return "period doubling (multiplier through -1)"
    return "fold or branch point (multiplier through +1)"
