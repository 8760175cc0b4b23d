"""Landing rules: how a trial step that ends past a strip is shortened until it lands in the
relaxed domain (paper 000 Fig. 12, step 3). All of them accept only steps that land in the
relaxed domain, so the guarantee is the same; aiming and dense landing need fewer trial steps
when eps << h.

* ``Halve``: halve the step (the paper's rule).
* ``Aim``: retry with the step length at which the failed step's own cubic Hermite interpolant
  reaches the middle of the deepest strip (at most ``rules.MAX_AIMS`` aims, then halving).
* ``Dense``: for methods with a continuous extension, once the failed step passes the error
  test, take the landing step on its own dense output (itself a Runge-Kutta step of the
  interpolant's order), so no step is retried; aiming as a fallback.
"""

from __future__ import annotations

from ..errors import ModelBreakdown, SimulationError
from ..methods import ContinuousStep, Tableau
from .outcomes import Landing, Trial
from .rules import MAX_AIMS, aimed_step
from .run import GuardAt, ModeVisit, Run
from .strip import crossing_on_step, hermite


class Halve:
    """Halve a step that ends past a strip."""

    name = "halve"
    lands_on_extension = False

    def retry(self, run: Run, visit: ModeVisit, trial: Trial, aims: int) -> tuple[float, bool]:
        """(the next trial length, whether it was aimed)."""
        return 0.5 * trial.hk, False


class Aim(Halve):
    """Aim the retry at the middle of the deepest strip along the failed step's interpolant."""

    name = "aim"

    def retry(self, run: Run, visit: ModeVisit, trial: Trial, aims: int) -> tuple[float, bool]:
        if aims >= MAX_AIMS:
            return 0.5 * trial.hk, False
        try:
            return self._aim(run, visit, trial), True
        except ModelBreakdown:  # the interpolant left the model's range: halve
            return 0.5 * trial.hk, True

    @staticmethod
    def _aim(run: Run, visit: ModeVisit, trial: Trial) -> float:
        """The step length at which the failed step's Hermite interpolant meets the middle
        (-eps/2) of the deepest strip it crossed. The retried step is checked like any other."""
        gvals = trial.guard_values()
        e = min(range(len(gvals)), key=gvals.__getitem__)
        guard = visit.guards[e]
        t, x, k0, hk, x1 = visit.t, visit.x, visit.k0, trial.hk, trial.x1
        k1 = trial.stages[-1] if run.tableau.fsal else run.f(visit.field, t + hk, x1)
        half = 0.5 * run.eps
        g0 = float(guard(t, x)) + half
        run.guard_evals += 1
        s, evals, converged = crossing_on_step(
            lambda s: guard(t + s * hk, hermite(x, k0, x1, k1, hk, s)) + half, g0, gvals[e] + half, 1e-3 * half
        )
        run.guard_evals += evals
        return aimed_step(hk, s, converged)


class Dense(Aim):
    """Land on the failed step's own continuous extension."""

    name = "dense"
    lands_on_extension = True

    def __init__(self, tableau: Tableau) -> None:
        if tableau.dense is None:
            raise SimulationError(
                f"landing 'dense' needs a method with a continuous extension (bs32, dopri5, "
                f"dop853, or a Tableau with dense output); method '{tableau.name}' has none: "
                f"use landing 'aim'"
            )

    def land(self, run: Run, visit: ModeVisit, trial: Trial) -> Landing | float:
        """The landing on the step's dense output, or, when no point of it lies in the relaxed
        domain (a guard turning back within the strip, a second guard deeper than eps there),
        the fraction of the step to retry as a real step."""
        t, x, hk = visit.t, visit.x, trial.hk
        try:
            curve = ContinuousStep(run.tableau, visit.field, t, x, hk, trial.stages, run.control)
            run.field_evals += curve.extra_evals
            return self._land_on(run, visit, trial, curve)
        except ModelBreakdown:  # the interpolant left the model's range: halve
            return 0.5

    def _land_on(self, run: Run, visit: ModeVisit, trial: Trial, curve: ContinuousStep) -> Landing | float:
        t, hk, eps = visit.t, trial.hk, run.eps
        gvals = trial.guard_values()
        e, s_q, converged = self._first_crossing(run, visit, trial, curve, gvals)
        theta = self._middle_of_strip(run, visit, trial, curve, e, s_q, gvals[e])
        if s_q <= theta < 1.0:
            x_land = curve.point(theta)
            t_land = t + theta * hk
            g_land = visit.guard_values(t_land, x_land)
            run.guard_evals += len(g_land)
            # In the relaxed domain, every guard finite (min() skips a nan that is not first),
            # and the crossed guard itself in its strip (its depth is the landing's tau).
            if (
                all(g - g == 0.0 for g in g_land)
                and -eps <= min(g_land)
                and g_land[e] < 0.0
                and all(v - v == 0.0 for v in x_land.tolist())
            ):
                return Landing(
                    t,
                    visit.x,
                    visit.k0,
                    t_land,
                    x_land,
                    g_land,
                    lambda s: curve.point(s * theta),
                    lambda s: curve.slope(s * theta),
                    (e, s_q / theta if theta > 0.0 else 0.0, converged),
                )
        # Not in the relaxed domain there: a real step of that length decides.
        return min(max(theta, s_q), 1.0) if s_q > 0.0 else 0.5

    @staticmethod
    def _first_crossing(
        run: Run, visit: ModeVisit, trial: Trial, curve: ContinuousStep, gvals: list[float]
    ) -> tuple[int, float, bool]:
        """q on the dense output: the earliest guard to reach zero, located to a 1e-12 share
        of the strip."""
        t, hk = visit.t, trial.hk
        best = None
        for e, g1 in enumerate(gvals):
            if g1 < 0.0:
                guard = visit.guards[e]

                def on_curve(s: float, guard: GuardAt = guard) -> float:
                    return guard(t + s * hk, curve.point(s))

                s, evals, converged = crossing_on_step(on_curve, visit.g_here[e], g1, 1e-12 * run.eps)
                run.guard_evals += evals
                if best is None or s < best[1]:
                    best = (e, s, converged)
        assert best is not None, "a step past a strip crossed at least one guard"
        return best

    @staticmethod
    def _middle_of_strip(
        run: Run, visit: ModeVisit, trial: Trial, curve: ContinuousStep, e: int, s_q: float, g1: float
    ) -> float:
        """The fraction of the step at which guard e is in the middle of its strip (-eps/2):
        by the secant from q (the guard is nearly linear across a strip, so one guess usually
        lands), else by a search on the rest of the step."""
        t, hk, half = visit.t, trial.hk, 0.5 * run.eps
        guard = visit.guards[e]

        def past_middle(theta: float) -> float:
            return float(guard(t + theta * hk, curve.point(theta))) + half

        theta = s_q + half * (1.0 - s_q) / -g1
        gap = past_middle(theta)
        run.guard_evals += 1
        if abs(gap) <= 0.5 * half:
            return theta
        # Outside the strip's middle half: a guard with a kink (the oscillator's max(x_max - x,
        # -xd) while the mass sticks) fools the secant, and a landing at the strip's edge, valid
        # but shallow, would hold the state for almost no time, so a chattering contact would
        # take ~1e5 times more transitions. Search for the middle.
        u, evals, _ = crossing_on_step(lambda u: past_middle(s_q + u * (1.0 - s_q)), half, g1 + half, 0.5 * half)
        run.guard_evals += evals
        return s_q + u * (1.0 - s_q)


def landing_rule(name: str, tableau: Tableau) -> Halve:
    """The landing rule called ``name`` (``halve``, ``aim`` or ``dense``) for ``tableau``."""
    if name == "halve":
        return Halve()
    if name == "aim":
        return Aim()
    if name == "dense":
        return Dense(tableau)
    raise SimulationError(f"landing must be one of 'halve', 'aim', 'dense', got {name!r}")
