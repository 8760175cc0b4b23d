"""The walk along one visit's error cone: which guards it meets, the computed event, the exit
(paper 004 Algorithm 1, per visit)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.optimize import brentq

from ..bounds import ModeFlow, guard_gradient, reset_lipschitz
from .records import CertifiedTransition, _Visit

if TYPE_CHECKING:
    from . import _ConeRun

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
            if tk > horizon and (
                self.event is not None
                or tk > tail
                or prev is None
                or not np.any((np.abs(prev[3]) <= prev[4]) & self.met)
            ):
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

    def _visit_sample(
        self, n: int, s: float, tk: float, xk: np.ndarray, rk: float, gk: np.ndarray, dk: np.ndarray
    ) -> bool:
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
            rec = self._record(
                index,
                je,
                True,
                "zeno",
                window,
                re,
                f"the entry ball (radius {self.entry_radius:.3g}) already meets the guard of "
                f"{trs[jz].name} {self.entry_distance[jz]:.3g} away, which the flow moves towards: "
                f"the visit may last no time",
                time=te,
            )
            return _Visit("zeno", rec, max(float(self.entry_distance[jz]), 0.0), self.entry_radius)
        others = [j for j in np.flatnonzero(self.met) if j != je]
        if others:
            distances = self.event_distance
            assert distances is not None
            jo = min(others, key=lambda j: abs(float(distances[j])))
            rec = self._record(
                index,
                je,
                True,
                "intersecting_guards",
                window,
                re,
                f"the cone meets the guards of {', '.join(self._names_met())} before leaving the "
                f"domain (the event point is {abs(float(distances[jo])):.3g} from the "
                f"guard of {trs[jo].name}, bound {re:.3g})",
                time=te,
            )
            return _Visit("intersecting_guards", rec, abs(float(distances[jo])), re)
        if self.t_exit is None:
            rec = self._record(
                index,
                je,
                True,
                "grazing",
                window,
                re,
                f"the computed trajectory crosses the guard of {trs[je].name} but the cone never "
                f"leaves the domain (deepest {self.deepest[1]:.3g} past, bound {self.deepest[2]:.3g})",
                time=te,
            )
            return _Visit("grazing", rec, max(float(self.deepest[1]), 0.0), self.deepest[2])
        return self._certified(index, window, self.event)

    def _names_met(self) -> list[str]:
        trs = self.flow.transitions
        return [trs[j].name for j in np.flatnonzero(self.met)]

    def _record(
        self,
        index: int,
        j: int,
        taken: bool,
        reason: str | None,
        window: tuple[float, float],
        radius: float,
        detail: str,
        time: float,
    ) -> CertifiedTransition:
        """The verdict on guard j of this visit, at ``time`` (s)."""
        return self.run_._record(
            index,
            self.flow.mode_name,
            self.flow.transitions[j],
            time,
            taken,
            reason is None,
            reason,
            window,
            radius,
            self.b0,
            self._names_met(),
            detail,
        )

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
        rec = self._record(
            index,
            j,
            False,
            "grazing",
            (self.first_touch[j], self.last_touch[j]),
            r,
            f"near miss: the cone reaches the guard of {name} (closest approach of the computed "
            f"trajectory {closest:.3g}, bound {r:.3g}) but the computed trajectory does not cross it",
            time=t,
        )
        return _Visit("grazing", rec, closest, r)

    def _certified(self, index: int, window: tuple[float, float], event: _Event) -> _Visit:
        """The certified transition, and the next visit's start: the reset image of the event
        point with an entry ball that holds the cone's trace on the guard, stretched by the reset."""
        te, je, xe, re = event
        tr = self.flow.transitions[je]
        r_trace, half = self._trace_on_guard(event)
        window = (min(window[0], te - half), max(window[1], te + half))
        rec = self._record(
            index,
            je,
            True,
            None,
            window,
            re,
            f"the cone meets only the guard of {tr.name} and leaves the domain at t={self.t_exit:.6g}",
            time=te,
        )
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
