"""The return's point on a level section, located on the integrator's own step.

``legsim.crossings`` finds a section crossing on the cubic Hermite interpolant of the stored
points. That interpolant errs by about h^4 |x''''| / 384 between them: 1e-5 in a biped's knee
rate at h = 2 ms under its stiff joint servos. Which points a return stores moves with its
start, so that error is noise in the return map, and Newton's method cannot go below it.

Here the crossing is searched again on the step the run's method takes from the stored point
before it: ``x(u) = step(x_i, u (t_{i+1} - t_i))``. That is the point a run stepping to the
section would reach, as accurate as the run's own steps and as smooth in the start as they are.
The search is the loop's bracketed one (``relaxed.rules.crossing_*``), one step per iterate,
from the bracket the stored points give. The step is ``variational.step_from``, compiled like
the loop when the mode's functions are.

Only runs under error control are searched again: nothing vouches for a fixed step, and one
that straddles a jump of the field (a controller's switch at a time or a state) gives a
different curve for every step length from the stored point (0.5 ms off the interpolant's
crossing at the quadruped pronk's apex at h = 1 ms). Error control rejects such steps. A run
whose input is not a function of its stored state (a Python controller keeps its memory outside
the state; a held input is sampled at the run's own step starts) and a linearly implicit method
(its step needs the Jacobian the run kept) keep the interpolated point too.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from ..control import ControlLaw, bind
from ..execution import Segment
from ..hybrid import HybridSystem
from ..methods import Tableau
from ..relaxed.driver import Evaluator
from ..relaxed.rules import RESULT, SEARCHING, STATUS, crossing_point, crossing_start, crossing_update
from .variational import point_on_step

#: Evaluators kept by (system, control, tableau) identity: a mode's tables are built once.
_EVALUATORS: dict[tuple[int, int, int], tuple[Any, Any, Any, Evaluator]] = {}


def evaluator(system: HybridSystem, control: Any, tableau: Tableau) -> Evaluator:
    """The evaluator of ``system``'s modes under ``control`` (a ``ControlLaw``, a Python
    controller or control, or None), kept while the same objects are asked for: a mode's tables
    are built once."""
    key = (id(system), id(control), id(tableau))
    found = _EVALUATORS.get(key)
    if found is None or found[0] is not system or found[1] is not control or found[2] is not tableau:
        if len(_EVALUATORS) > 16:
            _EVALUATORS.clear()
        law = control if isinstance(control, ControlLaw) else None
        made = Evaluator(system, tableau, None if law is not None else bind(control), law)
        found = _EVALUATORS[key] = (system, control, tableau, made)
    return found[3]


def steps_reproducible(control: Any, tableau: Tableau, error_controlled: bool) -> bool:
    """Whether the run's step from a stored point can be retaken and trusted (module
    docstring): an explicit method under error control (its accepted steps' local errors are
    within the tolerance, a step across a jump of the field is rejected), without a controller
    or under a ``ControlLaw`` that does not hold its input."""
    if tableau.implicit or not error_controlled:
        return False
    if control is None:
        return True
    return isinstance(control, ControlLaw) and not control.hold


def crossing_on_step(
    run: Evaluator, seg: Segment, s: Callable[[np.ndarray], float], direction: int, t_hit: float
) -> tuple[float, np.ndarray] | None:
    """(t, x) where s = 0 on the step from the stored point of ``seg`` before ``t_hit`` (the
    crossing found on the interpolant, in ``direction``: -1 down, +1 up), x shape (n,); None
    when the stored points do not bracket it (the interpolant's crossing is then kept)."""
    i = min(max(int(np.searchsorted(seg.t, t_hit, side="right")) - 1, 0), len(seg.t) - 2)
    span = float(seg.t[i + 1] - seg.t[i])
    g0, g1 = s(seg.x[i]), s(seg.x[i + 1])
    sign = 1.0 if g0 > 0.0 >= g1 and direction <= 0 else -1.0 if g0 < 0.0 <= g1 and direction >= 0 else 0.0
    if sign == 0.0 or span <= 0.0:
        return None
    points: dict[float, np.ndarray] = {1.0: np.asarray(seg.x[i + 1], dtype=float)}
    state = crossing_start(sign * g0, sign * g1, 0.0)
    while state[STATUS] == SEARCHING:
        u = crossing_point(state)
        points[u] = point_on_step(run, seg, i, u * span)
        state = crossing_update(state, u, sign * s(points[u]))
    u = state[RESULT]
    x = points.get(u)
    if x is None:  # the search ended at the bracket's start: the stored point itself
        x = np.asarray(seg.x[i], dtype=float)
    return float(seg.t[i]) + u * span, x.copy()
