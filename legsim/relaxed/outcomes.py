"""What the parts of the integrator hand back to its loop: small records, no tagged tuples."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import final

import numpy as np

from ..execution import Status

#: The interpolant of a step on [t, t1]: x, or dx/dt, at fraction s in [0, 1].
Curve = Callable[[float], np.ndarray]


# Final: the step loop tells its outcomes apart by ``type(step) is X`` (faster than isinstance),
# which the type checker can narrow only for classes that have no subclasses.
@final
@dataclass(frozen=True, slots=True)
class Ended:
    """The run ends: its status, a message naming mode, time and state (empty when finished),
    the time reached (s) and whether the state is held in a strip there."""

    status: Status
    message: str
    t: float
    in_strip: bool = False


@dataclass(frozen=True, slots=True)
class Entered:
    """A transition was crossed: the run continues in ``mode`` from state ``x`` at time ``t``.
    ``python_entry``: the compiled kernel hands this entry back for Python's ``enter_mode`` to
    take (a special case of the entry), rather than for the kernel to take once Python has
    checked the mode."""

    mode: str
    x: np.ndarray
    t: float
    python_entry: bool = False


Outcome = Ended | Entered


#: ``Trial.x1`` of a step that broke down before reaching its end.
NOT_REACHED = np.zeros(0)
NOT_REACHED.flags.writeable = False


@final
@dataclass(slots=True)
class Trial:
    """One trial step of length ``hk`` from (t, x) to (t1, x1).

    ``x1`` is ``NOT_REACHED`` (empty) when the model broke down on the way.
    ``gvals`` are the guards at (t1, x1) (None for a mode's single guard, whose value is
    ``gmin``), ``gmin`` the least of them (nan when one is nan). ``failure`` is None for a step
    that was evaluated, else why it left the relaxed domain without a guard value:
    ``"non_finite"`` or ``"model_breakdown"`` (with the model's exception in ``breakdown``).
    """

    hk: float
    t1: float
    x1: np.ndarray
    stages: tuple[np.ndarray, ...] = ()
    gvals: list[float] | None = None
    gmin: float = 0.0
    failure: str | None = None
    breakdown: Exception | None = None

    def guard_values(self) -> list[float]:
        """Every guard at the step's end, in the mode's transition order."""
        return [self.gmin] if self.gvals is None else self.gvals


@final
@dataclass(frozen=True, slots=True)
class Landing:
    """A step that landed in one or more strips, with its own interpolant: ``point(s)`` and
    ``slope(s)`` at fraction s of [t, t1]. ``crossing`` is set when the landing rule has
    already located q (guard index, fraction s of q, converged)."""

    t: float
    x: np.ndarray
    k0: np.ndarray
    t1: float
    x1: np.ndarray
    gvals: list[float]
    point: Curve
    slope: Curve
    crossing: tuple[int, float, bool] | None = None
