"""Certified transitions: does the true execution take the computed transition? (paper 004, Section V)

Around the numerical solution of a mode visit, the error cone ``C_h(t)`` is the union of the
balls of radius ``B(s)`` (Section III) for s <= t; it contains the true solution. Following the
cone until ``t_g``, the first time its ball lies wholly outside the domain, gives the set
``J_h`` of guards the cone meets. Proposition 2: when the computed trajectory has an event
(``t_e < inf``), the cone leaves the domain (``t_g < inf``) and ``J_h`` is a single guard, the
true trajectory takes the same transition. Algorithm 1 propagates the cone's intersection
with that guard through the reset into the next mode and, where a visit cannot be certified,
divides h by alpha and starts again.

Here, per visit (``legsim.bounds.ModeFlow`` gives the numerical solution past the guards, its
cubic Hermite interpolant and the bound):

* the visit enters with an uncertainty ball of radius b0 around the reset image of the
  previous event point: ``b0 = sigma_max(DR) * max over the guard contact of (|x_hat(t) -
  x_hat_e| + B(t))``, a ball that contains the cone's intersection with the guard;
* a guard is *met* while the ball reaches its plane (linearised at x_hat) or x_hat crosses it.
  A guard that the entry ball already meets while the flow moves away from it (the guard the
  state has just come through, say) is counted only once the ball has left it;
* ``t_e`` is the first crossing of a guard by x_hat, ``t_g`` the first time some linearised
  guard has the whole ball past it.

A visit is refused, with the reason it can never be certified at any h, when

* ``zeno``: the entry ball already meets a guard that the flow moves towards, so the true
  execution may leave the mode at once: the visits are shorter than the error can resolve,
  as happens on the way to a Zeno point (each refinement certifies a few more transitions);
* ``intersecting_guards``: the cone meets two or more guards (an execution through a guard
  intersection: refining never keeps the cone off the second guard);
* ``grazing``: the cone meets a guard but never leaves the domain (x_hat crosses a guard only
  tangentially, or not at all: a *near miss*, reported with ``taken = false``), or x_hat comes
  back through the guard it entered by before the ball has left that guard (the crossing and
  the return both lie within the error);
* ``t_final``: the cone meets a guard by t_final but x_hat crosses it only after t_final: the
  true execution may switch within the horizon (a crossing computed by t_final is judged as
  any other; "no transition" needs a cone that meets no guard up to t_final itself).

When the last refinement still fails, the failure is reported as ``refinement_limit`` instead
when refining has been making progress on it: the separation that would certify it (the
depth past the guard, the gap to the guard, the distance to the second guard) shrank less
than the square root of the shrinking of the bound between the last two levels, i.e. it is a
real separation that a smaller h would resolve, not a numerical one that shrinks with h.

Certification stops at the first transition it refuses: later transitions would be certified
only conditionally on a branch that is not certain.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
from scipy.optimize import brentq

from ..arguments import check_start, check_t_final, count, positive
from ..bounds import MAX_STEPS, LocalErrorEstimator, ModeFlow, check_steps
from ..errors import ModelBreakdown, SimulationError
from ..hybrid import HybridSystem
from ..methods import Tableau
from .records import REASONS, Certificate, CertifiedTransition, Level, _Visit
from .walk import _Walk

ControlFn = Callable[[float, np.ndarray], Any]

__all__ = ["REASONS", "Certificate", "CertifiedTransition", "Level", "certify"]


class _ConeRun:
    """One level of Algorithm 1: the computed execution at step h with its error cones."""

    def __init__(
        self,
        system: HybridSystem,
        h: float,
        estimator: LocalErrorEstimator,
        control: ControlFn | None,
        t_final: float,
        max_transitions: int,
        progress: Callable[[float], None] | None = None,
    ) -> None:
        self.system = system
        self.h = h
        self.estimator = estimator
        self.control = control
        self.t_final = t_final
        self.max_transitions = max_transitions
        self.progress = progress

    def run(self, mode: str, x: np.ndarray, t: float) -> tuple[list[CertifiedTransition], _Visit | None, float, bool]:
        """(certified records, the refused visit or None, end time, whether the transition
        budget ran out before t_final)."""
        records: list[CertifiedTransition] = []
        b0 = 0.0
        while len(records) < self.max_transitions:
            visit = self.visit(len(records), mode, x, t, b0)
            if visit.kind == "end":
                return records, None, visit.end_time, False
            if visit.kind != "certified":
                return records, visit, visit.record.time if visit.record else t, False
            record, next_state = visit.record, visit.next_state
            assert record is not None and next_state is not None  # a certified visit carries both
            records.append(record)
            mode, x, t, b0 = next_state
        return records, None, t, True

    def visit(self, index: int, mode: str, x0: np.ndarray, t0: float, b0: float) -> _Visit:
        budget = int(4 * (self.t_final - t0) / self.h) + 10_000
        flow = ModeFlow(
            self.system,
            mode,
            x0,
            t0,
            self.h,
            self.estimator,
            control=self.control,
            b0=b0,
            max_points=budget,
            progress=self.progress,
        )
        trs = flow.transitions
        m = len(trs)
        p0 = flow.point(0)
        if p0 is None:
            return _Visit(
                "non_finite",
                self._record(
                    index, mode, None, t0, False, False, "refinement_limit", (t0, t0), b0, b0, [], flow.message
                ),
            )
        if m == 0:
            return _Visit("end", end_time=self.t_final)
        walk = _Walk(self, flow, t0, b0)
        try:
            walk.run()
            # A flow that stopped early still decides the visit if the cone had left the domain.
            if walk.t_exit is not None or flow.status not in ("non_finite", "bound_overflow", "model_breakdown"):
                return walk.verdict(index)
            message = flow.message
        except ModelBreakdown as exc:  # at an interpolated point or in the reset of the event
            message = str(exc)
        last = flow.points[-1].t
        event = walk.event
        met = np.flatnonzero(walk.met)
        tr = trs[event[1]] if event is not None else (trs[met[0]] if len(met) else None)
        if event is not None and walk.t_exit is None:
            message = (
                f"the cone had not left the domain after the crossing of {trs[event[1]].name} at "
                f"t={event[0]:.6g} "
                f"(bound {event[3]:.3g}) when the flow stopped: {message}"
            )
        return _Visit(
            "non_finite",
            self._record(
                index,
                mode,
                tr,
                event[0] if event is not None else last,
                event is not None,
                False,
                "refinement_limit",
                (t0, last),
                b0,
                b0,
                [trs[j].name for j in met],
                message,
            ),
        )

    def _locate(
        self, flow: ModeFlow, n: int, s_lo: float, s_hi: float, crossed: np.ndarray
    ) -> tuple[float, int, np.ndarray, float]:
        """The first crossing among the guards ``crossed`` between fractions s_lo and s_hi of
        step n, found on the Hermite interpolant: (t_e, guard index, x_e, B(t_e))."""
        p0, p1 = flow.points[n], flow.points[n + 1]
        best: tuple[float, int] | None = None
        for j in np.flatnonzero(crossed):

            def g(s: float, j=j) -> float:
                return float(flow.on_step(n, s)[3][j])

            lo_val = g(s_lo)
            s = s_lo if lo_val < 0.0 else brentq(g, s_lo, s_hi, xtol=1e-15, rtol=8.9e-16)
            if best is None or s < best[0]:
                best = (s, int(j))
        assert best is not None  # ``crossed`` names at least one guard
        s_event, j_event = best
        t = p0.t + s_event * (p1.t - p0.t)
        return t, j_event, flow.state(n, s_event), (1.0 - s_event) * p0.radius + s_event * p1.radius

    def _record(self, index, mode, tr, time, taken, certified, reason, window, radius, entry_radius, names, detail):
        return CertifiedTransition(
            index,
            tr.name if tr is not None else "",
            mode,
            tr.target if tr is not None else "",
            float(time),
            bool(taken),
            bool(certified),
            reason,
            self.h,
            (float(window[0]), float(window[1])),
            float(radius),
            float(entry_radius),
            list(names),
            detail,
        )


def certify(
    system: HybridSystem,
    mode: str,
    x0: Any,
    t_final: float,
    h: float,
    method: str | Tableau = "rk4",
    *,
    t0: float = 0.0,
    pair: str | Tableau | None = None,
    control: ControlFn | None = None,
    floor: float = 0.0,
    alpha: float = 2.0,
    max_refinements: int = 6,
    max_transitions: int = 1000,
    progress: Callable[[int, float, float], None] | None = None,
) -> Certificate:
    """Certify the transitions of the execution from ``(mode, x0)`` over [t0, t_final]
    (paper 004 Algorithm 1).

    Parameters
    ----------
    system, mode, x0: the hybrid system, initial mode and state.
    t_final: end time (s); h: initial step (s), divided by ``alpha`` at each refinement.
    method: the Runge-Kutta method of the numerical solution; pair, floor: its local error
        estimation (``legsim.bounds``).
    control: optional control(t, x) -> u.
    alpha: refinement factor (> 1); max_refinements: most refinements (>= 0). Refining stops
        early, with the last level's verdict, when the next level would take more than
        ``legsim.bounds.MAX_STEPS`` steps over [t0, t_final] (the first level raises instead).
    max_transitions: most transitions certified in one level; when a level uses them up
        before t_final the certificate is incomplete (``complete`` False, not ``certified``).
    progress: optional ``progress(level, h, t)``, called every few hundred steps.

    Returns
    -------
    Certificate: per transition ``certified`` and ``reason`` (None or one of ``REASONS``).
    """
    x = check_start(system, mode, x0)
    h = positive("h", h)
    t_final = check_t_final(t_final, t0)
    if isinstance(alpha, bool) or not isinstance(alpha, (int, float)) or not math.isfinite(alpha) or alpha <= 1.0:
        raise SimulationError(f"alpha must be a number > 1, got {alpha!r}")
    max_refinements = count("max_refinements", max_refinements, 0)
    max_transitions = count("max_transitions", max_transitions, 1)
    estimator = LocalErrorEstimator(method, pair, floor)
    check_steps(t_final - float(t0), h, "certify")
    done = _Refinement(system, mode, x, float(t0), t_final, estimator, control, max_transitions, progress)
    done.run(h, alpha, max_refinements)
    settings = {
        "system": system.name,
        "initial_mode": mode,
        "t_final": t_final,
        "h": h,
        "method": estimator.method.name,
        "pair": estimator.pair.name,
        "floor": estimator.floor,
        "alpha": float(alpha),
        "max_refinements": max_refinements,
        "max_transitions": max_transitions,
    }
    incomplete = done.exhausted and done.failure is None
    message = ""
    if incomplete:
        message = (
            f"stopped after max_transitions = {max_transitions} certified transitions at "
            f"t = {done.end_time:.9g} s, before t_final = {t_final:g} s: the rest is not examined"
        )
    return Certificate(done.verdicts(), done.levels, settings, done.end_time, complete=not incomplete, message=message)


class _Refinement:
    """Algorithm 1's levels: the run at h, h / alpha, ... until one is not refused; the last
    level's certified transitions and the failure that stopped it (if any)."""

    def __init__(
        self,
        system: HybridSystem,
        mode: str,
        x: np.ndarray,
        t0: float,
        t_final: float,
        estimator: LocalErrorEstimator,
        control: ControlFn | None,
        max_transitions: int,
        progress: Callable[[int, float, float], None] | None,
    ) -> None:
        self.system, self.mode, self.x, self.t0, self.t_final = system, mode, x, t0, t_final
        self.estimator, self.control = estimator, control
        self.max_transitions, self.progress = max_transitions, progress
        self.levels: list[Level] = []
        self.records: list[CertifiedTransition] = []
        self.failure: _Visit | None = None
        self.end_time = t_final
        self.exhausted = False  # the last level used up its transition budget before t_final
        self.stopped = ""  # why refining stopped before max_refinements, when it did

    def run(self, h: float, alpha: float, max_refinements: int) -> None:
        span = self.t_final - self.t0
        for r in range(max_refinements + 1):
            h_r = h / alpha**r
            if span / h_r > MAX_STEPS:
                self.stopped = (
                    f"refinement stopped at h = {self.levels[-1].h:g}: the next level (h = {h_r:.3g}) "
                    f"would take {span / h_r:.3g} steps, more than {MAX_STEPS:.0e}"
                )
                return
            progress = self.progress
            level_progress = (
                None if progress is None else (lambda t, r=r, h_r=h_r, progress=progress: progress(r, h_r, t))
            )
            run = _ConeRun(
                self.system, h_r, self.estimator, self.control, self.t_final, self.max_transitions, level_progress
            )
            self.records, self.failure, self.end_time, self.exhausted = run.run(self.mode, self.x, self.t0)
            level = Level(h_r, len(self.records))
            if self.failure is not None and self.failure.record is not None:
                level.failure, level.index = self.failure.kind, self.failure.record.index
                level.separation, level.bound = self.failure.separation, self.failure.bound
            self.levels.append(level)
            if self.failure is None:
                return

    def verdicts(self) -> list[CertifiedTransition]:
        """The last level's certified transitions, then the refused one with its final reason."""
        out = list(self.records)
        failure, levels = self.failure, self.levels
        if failure is not None and failure.record is not None:
            rec = failure.record
            rec.reason = _reason(failure.kind, levels)
            if rec.reason == "refinement_limit" and failure.kind in ("grazing", "intersecting_guards", "t_final"):
                rec.detail += (
                    f"; refining is separating it (separation/bound "
                    f"{levels[-2].separation / levels[-2].bound:.3g} -> "
                    f"{levels[-1].separation / levels[-1].bound:.3g}): a smaller h may certify it"
                )
            if self.stopped:
                rec.detail += f" ({self.stopped})"
            out.append(rec)
        return out


def _reason(kind: str, levels: list[Level]) -> str:
    if kind in ("non_finite", "bound_overflow"):
        return "refinement_limit"
    if kind == "zeno":
        return "zeno"
    if len(levels) >= 2:
        last, prev = levels[-1], levels[-2]
        # A real separation stays put while the bound shrinks; a numerical one shrinks with it.
        if (
            prev.failure == last.failure
            and prev.index == last.index
            and last.separation > 0.0
            and prev.separation > 0.0
            and 0.0 < last.bound < prev.bound
            and last.separation / prev.separation > math.sqrt(last.bound / prev.bound)
        ):
            return "refinement_limit"
    return kind
