"""Is the return map differentiable at the orbit? A check on finite-difference Jacobian columns.

A return map whose transitions can happen in either order near the orbit (two feet whose slip
events are simultaneous on a symmetric gait) is only piecewise smooth: across the surface where
the order switches its slope jumps. A central difference whose stencil straddles that surface
averages the two slopes, and the multipliers of the averaged Jacobian belong to neither side.

For each column j with step d the check compares the one-sided secant slopes of the return map
P along e_j, ``S(h) = (P(x + h e_j) - P(x)) / h``, at h = -d and +d (the central difference's own
evaluations, plus P(x)) and at h = +d/2 (one more evaluation). For a smooth map
``S(h) = P' + h P''/2 + O(h^2)`` is linear in h to O(d^2), so the forward-backward gap
``S(d) - S(-d) ~ d P''`` is predicted by the forward side alone, ``4 (S(d) - S(d/2)) ~ d P''``;
their difference (the defect) is ``d^2 P'''/2`` plus the map's noise over d. At a kink with
slopes a and b either side the gap is O(|a - b|) whatever the step, and the defect with it:
a kink at x - s d (0 <= s < 1) gives the defect (1 - s) (b - a), one at x + s d (0 < s < 1) the
defect (1 - 5 s) (b - a) for s < 1/2 and 3 (1 - s) (a - b) beyond: it vanishes only for a kink
0.2 d from x (the one blind spot of four points: a piecewise-linear map with its kink there
fits them), and with ``KINK_RATIO`` = 0.5 the kinks between d/9 and d/3 right of x go unflagged.

A column is *kinked* when its defect (max-norm over the rows) exceeds ``KINK_RATIO`` times the
larger of the gap and its prediction (so curvature cannot explain it) and ``KINK_FLOOR`` times
the largest entry of the Jacobian (so it matters for the multipliers: below, it is rounding and
the integrator's noise). A kinked column is reported with the forward and backward Jacobians
(each side's one-sided differences) so that the spread of their multipliers shows what the
central one cannot vouch for.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

#: Defect over the larger of the gap and its smooth prediction beyond which a column's one-sided
#: slopes disagree by more than curvature explains (smooth maps: about d P''' / P'' << 1).
KINK_RATIO = 0.5
#: Defect, relative to the Jacobian's largest entry, below which a disagreement is left to
#: rounding and the integrator's noise (it would move the multipliers by less than this).
KINK_FLOOR = 1e-3


@dataclass
class ColumnStencil:
    """The return map's values around x along one coordinate, each shape (size,):
    ``base`` P(x), ``plus`` P(x + d e_j), ``minus`` P(x - d e_j), ``half`` P(x + d/2 e_j);
    ``d`` the step (in the coordinate's unit)."""

    base: np.ndarray
    plus: np.ndarray
    minus: np.ndarray
    half: np.ndarray
    d: float

    @property
    def forward(self) -> np.ndarray:
        """The forward difference (P(x + d) - P(x)) / d."""
        return (self.plus - self.base) / self.d

    @property
    def backward(self) -> np.ndarray:
        """The backward difference (P(x) - P(x - d)) / d."""
        return (self.base - self.minus) / self.d

    def defect(self) -> tuple[float, float]:
        """(defect, smooth scale): the max-norms of ``S(-d) - (4 S(d/2) - 3 S(d))`` and of the
        larger of the gap ``S(d) - S(-d)`` and its prediction ``4 (S(d) - S(d/2))`` (module
        docstring); both in the Jacobian's units."""
        gap = self.forward - self.backward
        predicted = 4.0 * (self.plus + self.base - 2.0 * self.half) / self.d
        defect = float(np.max(np.abs(predicted - gap), initial=0.0))
        scale = max(float(np.max(np.abs(gap), initial=0.0)), float(np.max(np.abs(predicted), initial=0.0)))
        return defect, scale


def kinked_columns(stencils: dict[int, ColumnStencil], jacobian: np.ndarray) -> tuple[int, ...]:
    """The columns (keys of ``stencils``) whose one-sided differences disagree beyond curvature
    and noise (module docstring), in increasing order; ``jacobian`` the central one."""
    floor = KINK_FLOOR * float(np.max(np.abs(jacobian), initial=0.0))
    kinked = []
    for j in sorted(stencils):
        defect, scale = stencils[j].defect()
        if defect > KINK_RATIO * scale and defect > floor:
            kinked.append(j)
    return tuple(kinked)


@dataclass(frozen=True)
class Surroundings:
    """The return map around the point a Jacobian was taken at, for what needs more of it than
    the stencil (``legsim.orbits.sampled_pieces``): ``evaluate`` maps an augmented state z,
    shape (N,), to its augmented return and the event order it took; ``start`` is the point and
    ``base`` its return, ``steps`` each column's difference step (N,, in the state's units)."""

    evaluate: Callable[[np.ndarray], tuple[np.ndarray, tuple[str, ...]]]
    start: np.ndarray
    base: np.ndarray
    steps: np.ndarray


@dataclass
class CheckedJacobian:
    """A finite-difference Jacobian of the return map with its differentiability check.

    central, forward, backward: the Jacobians of central, forward and backward differences,
        shape (size, size) (equal in the columns that were not checked: cyclic ones, e_c, and
        those where one side's simulation failed, one-sided).
    checked: the columns compared; kinked: those whose one-sided differences disagree;
    unchecked: the non-cyclic columns that could not be compared (a simulation of the stencil
    failed: where a map stops being smooth, that is likely).
    orders: for each checked column, the transitions (names, in order) of the returns from
    x + d e_j and x - d e_j: which event order each side of the stencil produced.
    around: the return map around the point, where the check can evaluate it further.
    """

    central: np.ndarray
    forward: np.ndarray
    backward: np.ndarray
    checked: tuple[int, ...]
    kinked: tuple[int, ...]
    unchecked: tuple[int, ...] = ()
    orders: dict[int, tuple[tuple[str, ...], tuple[str, ...]]] = field(default_factory=dict)
    around: Surroundings | None = None

    @property
    def differentiable(self) -> bool | None:
        """False when a checked column is kinked, None when none is but some column could not be
        checked, True when every column was checked and none is kinked."""
        if self.kinked:
            return False
        return None if self.unchecked else True

    @property
    def seen_orders(self) -> set[tuple[str, ...]]:
        """The event orders the stencil's returns took."""
        return {order for pair in self.orders.values() for order in pair}

    def unchecked_names(self, names: Sequence[str]) -> tuple[str, ...]:
        """The coordinates (``names`` of the augmented state) of the unchecked columns."""
        return tuple(names[j] for j in self.unchecked)

    def kinked_names(self, names: Sequence[str]) -> tuple[str, ...]:
        """The coordinates (``names`` of the augmented state) of the kinked columns."""
        return tuple(names[j] for j in self.kinked)
