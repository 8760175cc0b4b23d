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
  tangentially, or not at all: a *near miss*, reported with ``taken = false``).

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
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import brentq

from .arguments import count, positive
from .bounds import (
    MAX_STEPS,
    LocalErrorEstimator,
    ModeFlow,
    check_start,
    check_steps,
    check_t_final,
    guard_gradient,
    reset_lipschitz,
)
from .errors import ModelBreakdown, SimulationError
from .hybrid import HybridSystem
from .methods import Tableau

ControlFn = Callable[[float, np.ndarray], Any]
REASONS = ("grazing", "intersecting_guards", "zeno", "refinement_limit")


@dataclass
class CertifiedTransition:
    """The verdict on one transition of the computed execution.

    Attributes
    ----------
    index: position in the execution (0-based).
    name, source, target: the transition.
    time: computed event time t_e (s); for a near miss, the time of closest approach.
    taken: whether the computed trajectory takes it (False for a near miss).
    certified: Proposition 2 holds at step ``h``.
    reason: None when certified, else one of ``REASONS``.
    h: the step (s) of the level that decided.
    window: (first, last) time the cone meets the guard (s): the true switching time lies
        within it when certified.
    radius: the bound B at the event (state units); entry_radius: b0 of the visit.
    guards_met: names of the transitions whose guards the cone meets before leaving the domain.
    detail: a sentence saying why.
    """

    index: int
    name: str
    source: str
    target: str
    time: float
    taken: bool
    certified: bool
    reason: str | None
    h: float
    window: tuple[float, float]
    radius: float
    entry_radius: float
    guards_met: list[str]
    detail: str = ""

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (the items of ``legsim certify --json``)."""
        return {
            "index": self.index, "name": self.name, "source": self.source, "target": self.target,
            "time": _num(self.time), "taken": self.taken, "certified": self.certified, "reason": self.reason,
            "h": self.h, "window": [_num(self.window[0]), _num(self.window[1])], "radius": _num(self.radius),
            "entry_radius": _num(self.entry_radius), "guards_met": list(self.guards_met), "detail": self.detail,
        }


def _num(v: float) -> float | None:
    return float(v) if math.isfinite(v) else None


@dataclass
class Level:
    """One refinement level of Algorithm 1: its step, the transitions it certified and the
    failure that stopped it (kind, index, separation and bound), if any."""

    h: float
    certified: int
    failure: str | None = None
    index: int | None = None
    separation: float = math.nan
    bound: float = math.nan


@dataclass
class Certificate:
    """The outcome of ``certify``: the transitions (certified ones, then at most one refused),
    the refinement levels tried and the settings. ``complete`` is False when the last level
    stopped at its transition budget (``max_transitions``) before t_final; ``message`` then
    says where."""

    transitions: list[CertifiedTransition]
    levels: list[Level]
    settings: dict[str, Any] = field(default_factory=dict)
    end_time: float = math.nan
    complete: bool = True
    message: str = ""

    @property
    def certified(self) -> bool:
        """True when every transition of the execution up to t_final is certified (so never
        when the transition budget ran out before t_final)."""
        return self.complete and all(tr.certified for tr in self.transitions)

    def to_list(self) -> list[dict[str, Any]]:
        """The per-transition verdicts as JSON-ready dicts."""
        return [tr.to_dict() for tr in self.transitions]

    def summary(self) -> dict[str, Any]:
        """JSON-ready summary: settings, levels, verdicts."""
        return {
            **self.settings,
            "certified": self.certified,
            "complete": self.complete,
            "message": self.message,
            "end_time": _num(self.end_time),
            "levels": [{"h": lv.h, "certified": lv.certified, "failure": lv.failure, "index": lv.index}
                       for lv in self.levels],
            "transitions": self.to_list(),
        }


@dataclass
class _Visit:
    kind: str  # "end", "certified", "zeno", "intersecting_guards", "grazing", "non_finite"
    record: CertifiedTransition | None = None
    separation: float = math.nan
    bound: float = math.nan
    next_state: tuple[str, np.ndarray, float, float] | None = None
    end_time: float = math.nan


class _ConeRun:
    """One level of Algorithm 1: the computed execution at step h with its error cones."""

    def __init__(self, system: HybridSystem, h: float, estimator: LocalErrorEstimator, control: ControlFn | None,
                 t_final: float, max_transitions: int, progress: Callable[[float], None] | None = None) -> None:
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
        flow = ModeFlow(self.system, mode, x0, t0, self.h, self.estimator, control=self.control, b0=b0,
                        max_points=budget, progress=self.progress)
        trs = flow.transitions
        m = len(trs)
        p0 = flow.point(0)
        if p0 is None:
            return _Visit("non_finite", self._record(index, mode, None, t0, False, False, "refinement_limit",
                                                     (t0, t0), b0, b0, [], flow.message))
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
            message = (f"the cone had not left the domain after the crossing of {trs[event[1]].name} at "
                       f"t={event[0]:.6g} "
                       f"(bound {event[3]:.3g}) when the flow stopped: {message}")
        return _Visit("non_finite", self._record(index, mode, tr, event[0] if event is not None else last,
                                                 event is not None, False, "refinement_limit", (t0, last), b0, b0,
                                                 [trs[j].name for j in met], message))

    def _locate(self, flow: ModeFlow, n: int, s_lo: float, s_hi: float,
                crossed: np.ndarray) -> tuple[float, int, np.ndarray, float]:
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
        return CertifiedTransition(index, tr.name if tr is not None else "", mode, tr.target if tr is not None else "",
                                   float(time), bool(taken), bool(certified), reason, self.h,
                                   (float(window[0]), float(window[1])), float(radius), float(entry_radius),
                                   list(names), detail)


#: The computed event of a visit: (t_e, guard index j, x_e, B(t_e)).
_Event = tuple[float, int, np.ndarray, float]


class _Walk:
    """The walk along one visit's cone: which guards it meets, the computed event, the exit."""

    def _u(self, t: float, x: np.ndarray) -> Any:
        control = self.flow.control
        return None if control is None else control(t, x)

    def __init__(self, run: _ConeRun, flow: ModeFlow, t0: float, b0: float) -> None:
        self.run_ = run
        self.flow = flow
        self.t0 = t0
        self.b0 = b0
        trs = flow.transitions
        m = len(trs)
        p0 = flow.points[0]
        # Guards the entry ball already meets: departing ones are ignored until the ball has
        # left them; one the flow moves towards makes the visit's very existence uncertain.
        self.departing = np.zeros(m, dtype=bool)
        self.zeno_guard: int | None = None
        for j, tr in enumerate(trs):
            if p0.distance[j] <= p0.radius:
                if float(np.dot(guard_gradient(tr, p0.x, p0.t, self._u(p0.t, p0.x)), p0.f)) > 0.0:
                    self.departing[j] = True
                elif self.zeno_guard is None:
                    self.zeno_guard = j
        self.entry_distance = p0.distance.copy()
        self.entry_radius = p0.radius
        self.met = np.zeros(m, dtype=bool)
        self.first_touch = np.full(m, math.inf)
        self.last_touch = np.full(m, -math.inf)
        self.closest = np.full(m, math.inf)  # smallest distance of x_hat to each plane while met
        self.closest_r = np.full(m, math.nan)
        self.closest_t = np.full(m, math.nan)
        self.event: _Event | None = None
        self.event_distance: np.ndarray | None = None
        self.t_exit: float | None = None
        self.deepest = (-math.inf, math.nan, math.nan)  # (depth / B, depth, B) past the event guard
        self.contact: list[tuple[np.ndarray, float]] = []  # (x, B) where the ball meets the event guard
        self.beyond = False  # the computed trajectory crosses only after t_final
        self.prev: tuple | None = None  # (step, fraction, g, d, B)

    def run(self) -> None:
        run = self.run_
        horizon = run.t_final
        tail = run.t_final + max(10.0 * run.h, 0.5 * (run.t_final - self.t0))
        flow = self.flow
        for n, s, tk, xk, rk, gk, dk in _samples(flow):
            prev = self.prev
            # Past t_final a guard the ball still meets may be about to be crossed: look a
            # little further, so that a crossing just after t_final is not a near miss.
            if tk > horizon and (self.event is not None or tk > tail or prev is None
                                 or not np.any((np.abs(prev[3]) <= prev[4]) & self.met)):
                return
            if self.event is None and prev is not None:
                crossed = (prev[2] >= 0.0) & (gk < 0.0) & ~self.departing
                if crossed.any():
                    s_lo = prev[1] if prev[0] == n else 0.0
                    self.event = run._locate(flow, n, s_lo, s, crossed)
                    te, je, xe, re = self.event
                    if te > run.t_final:
                        self.beyond = True
                        return
                    g_e, self.event_distance = flow.guards_at(xe, te)
                    # The event point and, when the ball gets wholly past the event guard
                    # before this sample, that exit point are samples too: the guards met
                    # must be judged up to the exit, not up to the next (coarser) sample.
                    s_e = (te - flow.points[n].t) / (flow.points[n + 1].t - flow.points[n].t)
                    if self._visit_sample(n, s_e, te, xe, re, g_e, self.event_distance):
                        return
                    s_x = self._exit_fraction(n, s_e, s, je)
                    if s_x is not None and self._virtual(n, s_x):
                        return
                    # Follow the cone past the event for as long again as the visit so far
                    # (at least 10 steps): a transversal crossing leaves within a few B/|d'|.
                    horizon = te + max(10.0 * run.h, te - self.t0)
            if self._visit_sample(n, s, tk, xk, rk, gk, dk):
                return

    def _virtual(self, n: int, s: float) -> bool:
        t, x, r, g, d = self.flow.on_step(n, s)
        return self._visit_sample(n, s, t, x, r, g, d)

    def _exit_fraction(self, n: int, s_lo: float, s_hi: float, j: int) -> float | None:
        """Where on step n the ball gets wholly past guard j (d_j + B = 0), if before s_hi."""
        flow = self.flow

        def excess(s: float) -> float:
            _, _, r, _, d = flow.on_step(n, s)
            return float(d[j]) + r

        if not (excess(s_lo) > 0.0 > excess(s_hi)):
            return None
        return float(brentq(excess, s_lo, s_hi, xtol=1e-15, rtol=8.9e-16))

    def _visit_sample(self, n: int, s: float, tk: float, xk: np.ndarray, rk: float, gk: np.ndarray,
                      dk: np.ndarray) -> bool:
        """Account for one sample; True when the cone has left the domain."""
        prev = self.prev
        touch = np.abs(dk) <= rk
        if prev is not None:
            touch |= (prev[3] >= 0.0) != (dk >= 0.0)  # x_hat went through the plane between samples
        self.departing &= touch
        live = touch & ~self.departing
        for j in np.flatnonzero(live):
            self.met[j] = True
            self.first_touch[j] = min(self.first_touch[j], tk)
            self.last_touch[j] = max(self.last_touch[j], tk)
            if 0.0 <= dk[j] < self.closest[j]:
                self.closest[j], self.closest_r[j], self.closest_t[j] = dk[j], rk, tk
        self.prev = (n, s, gk, dk, rk)
        if self.event is None:
            return False
        te, je, _, _ = self.event
        if live[je] and abs(dk[je]) <= rk:
            self.contact.append((xk, rk))
        if tk >= te and rk > 0.0 and -dk[je] / rk > self.deepest[0]:
            self.deepest = (-dk[je] / rk, -dk[je], rk)
        if np.any((dk < -rk) & ~self.departing):
            self.t_exit = tk
            return True
        return False

    def verdict(self, index: int) -> _Visit:
        """The visit's outcome once the walk has ended: the end of the run, a near miss, a
        refused crossing or a certified one."""
        if self.beyond or (self.event is None and not self.met.any()):
            return _Visit("end", end_time=self.run_.t_final)
        if self.event is None:
            return self._near_miss(index)
        te, je, _, re = self.event
        window = (min(self.first_touch[je], te), max(self.last_touch[je], te))
        trs = self.flow.transitions
        if self.zeno_guard is not None:
            jz = self.zeno_guard
            rec = self._record(index, je, True, "zeno", window, re,
                               f"the entry ball (radius {self.entry_radius:.3g}) already meets the guard of "
                               f"{trs[jz].name} {self.entry_distance[jz]:.3g} away, which the flow moves towards: "
                               f"the visit may last no time", time=te)
            return _Visit("zeno", rec, max(float(self.entry_distance[jz]), 0.0), self.entry_radius)
        others = [j for j in np.flatnonzero(self.met) if j != je]
        if others:
            distances = self.event_distance
            assert distances is not None
            jo = min(others, key=lambda j: abs(float(distances[j])))
            rec = self._record(index, je, True, "intersecting_guards", window, re,
                               f"the cone meets the guards of {', '.join(self._names_met())} before leaving the "
                               f"domain (the event point is {abs(float(distances[jo])):.3g} from the "
                               f"guard of {trs[jo].name}, bound {re:.3g})", time=te)
            return _Visit("intersecting_guards", rec, abs(float(distances[jo])), re)
        if self.t_exit is None:
            rec = self._record(index, je, True, "grazing", window, re,
                               f"the computed trajectory crosses the guard of {trs[je].name} but the cone never "
                               f"leaves the domain (deepest {self.deepest[1]:.3g} past, bound {self.deepest[2]:.3g})",
                               time=te)
            return _Visit("grazing", rec, max(float(self.deepest[1]), 0.0), self.deepest[2])
        return self._certified(index, window, self.event)

    def _names_met(self) -> list[str]:
        trs = self.flow.transitions
        return [trs[j].name for j in np.flatnonzero(self.met)]

    def _record(self, index: int, j: int, taken: bool, reason: str | None, window: tuple[float, float],
                radius: float, detail: str, time: float) -> CertifiedTransition:
        """The verdict on guard j of this visit, at ``time`` (s)."""
        return self.run_._record(index, self.flow.mode_name, self.flow.transitions[j], time, taken, reason is None,
                                 reason, window, radius, self.b0, self._names_met(), detail)

    def _near_miss(self, index: int) -> _Visit:
        """The cone meets a guard that the computed trajectory does not cross: refused as
        grazing, at the closest approach to the nearest such guard."""
        met = self.met
        candidates = np.where(met, self.closest, np.inf)
        j = int(np.argmin(candidates))
        if not math.isfinite(candidates[j]):
            j = int(np.flatnonzero(met)[0])
        closest, r, t = self.closest[j], self.closest_r[j], self.closest_t[j]
        if not math.isfinite(closest):
            closest, r, t = 0.0, math.nan, self.first_touch[j]
        name = self.flow.transitions[j].name
        rec = self._record(index, j, False, "grazing", (self.first_touch[j], self.last_touch[j]), r,
                           f"near miss: the cone reaches the guard of {name} (closest approach of the computed "
                           f"trajectory {closest:.3g}, bound {r:.3g}) but the computed trajectory does not cross it",
                           time=t)
        return _Visit("grazing", rec, closest, r)

    def _certified(self, index: int, window: tuple[float, float], event: _Event) -> _Visit:
        """The certified transition, and the next visit's start: the reset image of the event
        point with an entry ball that holds the cone's trace on the guard, stretched by the reset."""
        te, je, xe, re = event
        tr = self.flow.transitions[je]
        r_trace, half = self._trace_on_guard(event)
        window = (min(window[0], te - half), max(window[1], te + half))
        rec = self._record(index, je, True, None, window, re,
                           f"the cone meets only the guard of {tr.name} and leaves the domain at t={self.t_exit:.6g}",
                           time=te)
        x_next = np.asarray(xe if tr.reset is None else tr.reset(xe), dtype=float)
        b_next = r_trace * reset_lipschitz(tr, xe, len(x_next))
        return _Visit("certified", rec, next_state=(tr.target, x_next, te, b_next))

    def _trace_on_guard(self, event: _Event) -> tuple[float, float]:
        """(radius of a ball around the event point x_e holding the cone's trace on the event
        guard, half-width (s) of the time window in which the true trajectory meets the guard).

        Around x_e the balls of radius B are met while |d| <= B, i.e. for |t - t_e| <= B / |d'|,
        which spreads them along the guard to B |f| / |d'| (d' the rate of the distance to the
        guard); sampled contact points are added in case B varies."""
        te, je, xe, re = event
        r_cone = max([re] + [rk for _, rk in self.contact])
        fe = self.flow.field_at(te, xe)
        grad = guard_gradient(self.flow.transitions[je], xe, te, self._u(te, xe))
        grad_norm = float(np.linalg.norm(grad))
        if grad_norm == 0.0:
            # A guard on time alone (a clock): the true trajectory switches at t_e exactly, where
            # it lies in the ball of radius B(t_e); nothing spreads along the guard.
            spread, half = r_cone, 0.0
        else:
            rate = abs(float(np.dot(grad, fe))) / grad_norm
            spread = r_cone * float(np.linalg.norm(fe)) / rate if rate > 0.0 else math.inf
            half = r_cone / rate if rate > 0.0 else math.inf
        r_trace = max([r_cone, spread] + [float(np.linalg.norm(xk - xe)) + rk for xk, rk in self.contact])
        return r_trace, half


def _samples(flow: ModeFlow):
    """Every sample of the flow in time order, each once: (step, fraction, t, x, B, g, d)."""
    n = 0
    while True:
        smp = flow.step_samples(n)
        if smp is None:
            return
        for k in range(0 if n == 0 else 1, len(smp.s)):
            yield n, float(smp.s[k]), float(smp.t[k]), smp.x[k], float(smp.radius[k]), smp.guard[k], smp.distance[k]
        n += 1


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
    settings = {"system": system.name, "initial_mode": mode, "t_final": t_final, "h": h,
                "method": estimator.method.name, "pair": estimator.pair.name, "floor": estimator.floor,
                "alpha": float(alpha), "max_refinements": max_refinements, "max_transitions": max_transitions}
    incomplete = done.exhausted and done.failure is None
    message = ""
    if incomplete:
        message = (f"stopped after max_transitions = {max_transitions} certified transitions at "
                   f"t = {done.end_time:.9g} s, before t_final = {t_final:g} s: the rest is not examined")
    return Certificate(done.verdicts(), done.levels, settings, done.end_time, complete=not incomplete, message=message)


class _Refinement:
    """Algorithm 1's levels: the run at h, h / alpha, ... until one is not refused; the last
    level's certified transitions and the failure that stopped it (if any)."""

    def __init__(self, system: HybridSystem, mode: str, x: np.ndarray, t0: float, t_final: float,
                 estimator: LocalErrorEstimator, control: ControlFn | None, max_transitions: int,
                 progress: Callable[[int, float, float], None] | None) -> None:
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
                self.stopped = (f"refinement stopped at h = {self.levels[-1].h:g}: the next level (h = {h_r:.3g}) "
                                f"would take {span / h_r:.3g} steps, more than {MAX_STEPS:.0e}")
                return
            progress = self.progress
            level_progress = None if progress is None else (
                lambda t, r=r, h_r=h_r, progress=progress: progress(r, h_r, t))
            run = _ConeRun(self.system, h_r, self.estimator, self.control, self.t_final, self.max_transitions,
                           level_progress)
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
            if rec.reason == "refinement_limit" and failure.kind in ("grazing", "intersecting_guards"):
                rec.detail += (f"; refining is separating it (separation/bound "
                               f"{levels[-2].separation / levels[-2].bound:.3g} -> "
                               f"{levels[-1].separation / levels[-1].bound:.3g}): a smaller h may certify it")
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
        if prev.failure == last.failure and prev.index == last.index and last.separation > 0.0 \
                and prev.separation > 0.0 and 0.0 < last.bound < prev.bound \
                and last.separation / prev.separation > math.sqrt(last.bound / prev.bound):
            return "refinement_limit"
    return kind


__all__: Sequence[str] = ("REASONS", "Certificate", "CertifiedTransition", "Level", "certify")
