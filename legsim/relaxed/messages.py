"""The messages of a run's ends, built in one place for the Python loop and the compiled kernel
alike: each names the mode, the time and the state."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from .resolution import state_scale, thinnest_strip


def _resolution_hint(eps: float, x: np.ndarray) -> str:
    """A second explanation when eps is thinner than float64 resolves at x's scale (the state
    grew since the run began): no step can land inside the strip."""
    if eps < thinnest_strip(x):
        spacing = float(np.spacing(state_scale(x)))
        return (
            f"; or eps = {eps:g} is thinner than float64 can resolve near this state (spacing {spacing:.3g}): raise eps"
        )
    return ""


def halving_exhausted(mode: str, t: float, x: np.ndarray, shortened: int, h: float, transition: str, eps: float,
                      guards: tuple[float, float] = (math.nan, math.nan)) -> str:  # fmt: skip
    """No shortened step landed in the relaxed domain: the flow crosses the guard of
    ``transition`` without entering its strip (or eps is below float64's resolution).
    ``shortened`` trial steps were shortened, the last to h (s); ``guards``: the guard at the
    step's start and at the last trial's end, which show a guard that jumps."""
    head = (
        f"no step from t={t:.17g} in mode '{mode}' lands in the relaxed domain (shortened "
        f"{'once' if shortened == 1 else f'{shortened} times'}, down to a trial step of {h:.3g} s): "
    )
    start, end = guards
    rounding = h <= 16.0 * float(np.spacing(max(abs(t), 1.0)))
    if start >= -eps and end < -eps and rounding:  # past the strip within a rounding of t: a jump
        return head + (
            f"the guard of transition {transition} goes from {start:.3g} to {end:.3g} within a rounding of t. "
            f"It jumps there, as a guard discontinuous in the state does (a spring leg's touchdown guard "
            f"where its foot is below the ground while the body rises, the foot placed there by its controller, "
            f"say): the state is past the model's range (x={x.tolist()})"
        )
    return head + (
        f"the flow leaves through the guard of transition {transition} without entering its strip "
        f"(x={x.tolist()})" + _resolution_hint(eps, x)
    )


def non_finite_step(mode: str, t: float, x: np.ndarray, hk: float) -> str:
    """Even the shortest trial step from (t, x) gives a non-finite state."""
    return f"the step from t={t:.17g} in mode '{mode}' gives a non-finite state even at h={hk:.3g}: x={x.tolist()}"


def nan_guard(mode: str, t: float, x: np.ndarray, transition: str) -> str:
    """A guard evaluated to nan at a trial step's end (t, x)."""
    return f"guard of transition {transition} is nan at t={t:.17g} in mode '{mode}', x={x.tolist()}"


def non_finite_guard(mode: str, t: float, x: np.ndarray, transition: str, value: float) -> str:
    """A guard is not finite on the state entering a mode."""
    return f"guard of transition {transition} is {value} at t={t:.17g} in mode '{mode}', x={x.tolist()}"


def non_finite_field(mode: str, t: float, x: np.ndarray, f: np.ndarray) -> str:
    """The field is not finite on the state entering a mode."""
    return f"field of mode '{mode}' is not finite at t={t:.17g}, x={x.tolist()}: f={f.tolist()}"


def model_breakdown(reason: object, mode: str, t: float, within: float | None = None) -> str:
    """The model left its range of validity (``reason``: its ModelBreakdown) after time t; with
    ``within``, the flow itself leaves the range within that many seconds."""
    if within is None:
        return f"{reason} (mode '{mode}', after t={t:.17g})"
    return f"{reason} (mode '{mode}', after t={t:.17g}: the flow leaves the model's range within {within:.3g} s)"


def first_nonfinite(values: Sequence[float]) -> int | None:
    """Index of the first value that is not finite, or None."""
    for i, v in enumerate(values):
        if v - v != 0.0:
            return i
    return None
