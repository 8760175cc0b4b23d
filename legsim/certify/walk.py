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
        self.entry_departing = self.departing.copy()
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
        # At the last sample up to t_final (one is put at t_final itself): the guards met so far,
        # the distances d and the radius B there. What happens past t_final only names a refusal.
        self.at_horizon: tuple[np.ndarray, np.ndarray, float] | None = None
        # A departing guard is ignored only while the ball still meets it: if x_hat crosses it
        # back, or the ball gets wholly past it, before the ball ever left it, the return lies
        # within the error. Kept: whether the event guard was still departing, the guard the
        # cone left through, and the farthest x_hat got from a departing guard (d / B, d, B).
        self.event_departing = False
        self.exit_guard: int | None = None
        self.apart = (-math.inf, 0.0, math.nan)

    def run(self) -> None:
        run = self.run_
        tail = run.t_final + max(10.0 * run.h, 0.5 * (run.t_final - self.t0))
        for n, s, tk, xk, rk, gk, dk in _samples(self.flow):
            if tk > run.t_final and self.at_horizon is None and self.prev is not None:
                # A sample at t_final itself: the samples are 1/8 step apart, and a crossing (or
                # the ball reaching a guard) between the last one before t_final and t_final is
                # inside the horizon.
                if self.event is None and self._at_t_final(n, s):
                    return
                self.at_horizon = (self.met.copy(), self.prev[3], float(self.prev[4]))
            prev = self.prev
            horizon = run.t_final
            if self.event is not None:
                # Follow the cone past the event for as long again as the visit so far
                # (at least 10 steps): a transversal crossing leaves within a few B/|d'|.
                te = self.event[0]
                horizon = te + max(10.0 * run.h, te - self.t0)
            # Past t_final a guard the ball still meets may be about to be crossed: look a
            # little further, so that the refusal names a crossing just after t_final.
            if tk > horizon and (
                self.event is not None
                or tk > tail
                or prev is None
                or not np.any((np.abs(prev[3]) <= prev[4]) & self.met)
            ):
                return
            if self._advance(n, s, tk, xk, rk, gk, dk):
                return

    def _at_t_final(self, n: int, s: float) -> bool:
        """Walk to the point of step n at t_final, before its sample at fraction s; True when
        the walk has ended there."""
        flow, prev = self.flow, self.prev
        p0, p1 = flow.points[n], flow.points[n + 1]
        s_f = (self.run_.t_final - p0.t) / (p1.t - p0.t)
        s_lo = 0.0 if prev is None or prev[0] != n else prev[1]
        if not s_lo < s_f < s:
            return False
        t, x, r, g, d = flow.on_step(n, s_f)
        return self._advance(n, s_f, t, x, r, g, d)

    def _advance(self, n: int, s: float, tk: float, xk: np.ndarray, rk: float, gk: np.ndarray, dk: np.ndarray) -> bool:
        """Look for the computed event between the previous sample and this one (fraction s of
        step n, time tk in s), then account for this sample; True when the walk has ended."""
        prev, run, flow = self.prev, self.run_, self.flow
        if self.event is None and prev is not None:
            # Departing guards too: x_hat coming back through the guard it has just crossed is
            # an event, refused in ``verdict`` when the ball has not left that guard in between.
            crossed = (prev[2] >= 0.0) & (gk < 0.0)
            if crossed.any():
                s_lo = prev[1] if prev[0] == n else 0.0
                self.event = run._locate(flow, n, s_lo, s, crossed)
                te, je, xe, re = self.event
                self.event_departing = bool(self.departing[je])
                if te > run.t_final:
                    self.beyond = True
                    return True
                g_e, self.event_distance = flow.guards_at(xe, te)
                # The event point and, when the ball gets wholly past the event guard
                # before this sample, that exit point are samples too: the guards met
                # must be judged up to the exit, not up to the next (coarser) sample.
                s_e = (te - flow.points[n].t) / (flow.points[n + 1].t - flow.points[n].t)
                if self._visit_sample(n, s_e, te, xe, re, g_e, self.event_distance):
                    return True
                s_x = self._exit_fraction(n, s_e, s, je)
                if s_x is not None and self._virtual(n, s_x):
                    return True
        return self._visit_sample(n, s, tk, xk, rk, gk, dk)

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
        self._track_apart(dk, rk)
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
            # Wholly past a guard departing at the entry with no computed crossing (x_hat
            # started a rounding error past it): the cone has left the domain through it.
            past = (dk < -rk) & self.entry_departing & ~self.departing
            if past.any():
                self.t_exit, self.exit_guard = tk, int(np.flatnonzero(past)[0])
                return True
            return False
        te, je, _, _ = self.event
        if live[je] and abs(dk[je]) <= rk:
            self.contact.append((xk, rk))
        if tk >= te and rk > 0.0 and -dk[je] / rk > self.deepest[0]:
            self.deepest = (-dk[je] / rk, -dk[je], rk)
        past = (dk < -rk) & ~self.departing
        if past.any():
            self.t_exit = tk
            self.exit_guard = int(np.flatnonzero(past)[0])
            return True
        return False

    def _track_apart(self, d: np.ndarray, r: float) -> None:
        """Keep the farthest x_hat has got from a departing guard, as (d / B, d, B) with the
        distance d and the radius B in state units: the separation a refusal of its return
        reports, which refining grows when the excursion past the previous guard is real."""
        if not self.departing.any() or r <= 0.0:
            return
        ratio = np.where(self.departing, d / r, -np.inf)
        j = int(np.argmax(ratio))
        if ratio[j] > self.apart[0]:
            self.apart = (float(ratio[j]), float(d[j]), r)

    def verdict(self, index: int) -> _Visit:
        """The visit's outcome once the walk has ended: the end of the run, a near miss, a
        refused crossing or a certified one."""
        if self.event is None:
            if self.met.any():
                return self._near_miss(index)
            if self.exit_guard is not None and self.t_exit is not None:
                return self._returned(index, self.exit_guard, self.t_exit, False)
            return _Visit("end", end_time=self.run_.t_final)
        if self.beyond:
            return self._beyond(index)
        te, je, _, re = self.event
        window = (min(self.first_touch[je], te), max(self.last_touch[je], te))
        if self.zeno_guard is not None:
            return self._zeno(index, window)
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
                f"guard of {self.flow.transitions[jo].name}, bound {re:.3g})",
                time=te,
            )
            return _Visit("intersecting_guards", rec, abs(float(distances[jo])), re)
        if self.event_departing:
            return self._returned(index, je, te, True)
        if self.t_exit is None:
            rec = self._record(
                index,
                je,
                True,
                "grazing",
                window,
                re,
                f"the computed trajectory crosses the guard of {self.flow.transitions[je].name} but "
                f"the cone never leaves the domain (deepest {self.deepest[1]:.3g} past, bound "
                f"{self.deepest[2]:.3g})",
                time=te,
            )
            return _Visit("grazing", rec, max(float(self.deepest[1]), 0.0), self.deepest[2])
        return self._certified(index, window, self.event)

    def _window_past_t_final(self, index: int, window: tuple[float, float]) -> _Visit:
        """Refused as ``t_final``: the true crossing lies in ``window`` (s), which reaches past
        t_final, so the true execution may not take it within the horizon. The separation and
        bound are times (s): the computed crossing's lead on t_final, and the window's reach past
        the computed crossing, which refining shrinks when the lead is real."""
        assert self.event is not None
        te, je, _, re = self.event
        t_final, name = self.run_.t_final, self.flow.transitions[je].name
        why = (
            f"the computed trajectory crosses the guard of {name} at t={te:.9g}, but the true crossing lies in "
            f"[{window[0]:.9g}, {window[1]:.9g}], which reaches past t_final = {t_final:g} s"
        )
        return self._refused_at_horizon(index, window, re, why, (max(t_final - te, 0.0), window[1] - te))

    def _refused_at_horizon(
        self, index: int, window: tuple[float, float], radius: float, why: str, separation: tuple[float, float]
    ) -> _Visit:
        """Refused as ``t_final`` for ``why``: the true execution may switch on either side of
        t_final. ``separation``: (what would certify it, its bound), as refinement compares them."""
        assert self.event is not None
        te, je, _, _ = self.event
        rec = self._record(
            index,
            je,
            True,
            "t_final",
            window,
            radius,
            f"{why}: whether the true execution switches before t_final is not resolved",
            time=te,
        )
        return _Visit("t_final", rec, *separation)

    def _zeno(self, index: int, window: tuple[float, float]) -> _Visit:
        """Refused: the entry ball already meets a guard the flow moves towards."""
        assert self.event is not None and self.zeno_guard is not None
        te, je, _, re = self.event
        jz = self.zeno_guard
        rec = self._record(
            index,
            je,
            True,
            "zeno",
            window,
            re,
            f"the entry ball (radius {self.entry_radius:.3g}) already meets the guard of "
            f"{self.flow.transitions[jz].name} {self.entry_distance[jz]:.3g} away, which the flow "
            f"moves towards: the visit may last no time"
            + (f" (x_hat crosses it only after t_final = {self.run_.t_final:g} s)" if self.beyond else ""),
            time=te,
        )
        return _Visit("zeno", rec, max(float(self.entry_distance[jz]), 0.0), self.entry_radius)

    def _beyond(self, index: int) -> _Visit:
        """The computed trajectory crosses only after t_final: the end of the run when the cone
        meets no guard up to t_final, else a refusal (the true trajectory may switch before)."""
        assert self.event is not None
        met, d_f, r_f = self.at_horizon if self.at_horizon is not None else (self.met, None, math.nan)
        if not met.any():
            return _Visit("end", end_time=self.run_.t_final)
        te, je, _, _ = self.event
        window = (min(self.first_touch[je], te), max(self.last_touch[je], te))
        if self.zeno_guard is not None:
            return self._zeno(index, window)
        self.met = met  # the guards the cone meets up to t_final; later ones are not in question
        if not met[je] or d_f is None:
            return self._near_miss(index)
        t_final, name = self.run_.t_final, self.flow.transitions[je].name
        why = (
            f"the cone meets the guard of {name} from t={self.first_touch[je]:.9g}, by t_final = {t_final:g} s, "
            f"but the computed trajectory crosses it only at t={te:.9g} (at t_final {float(d_f[je]):.3g} from "
            f"it, bound {r_f:.3g})"
        )
        return self._refused_at_horizon(index, window, r_f, why, (max(float(d_f[je]), 0.0), r_f))

    def _returned(self, index: int, j: int, time: float, taken: bool) -> _Visit:
        """Refused as grazing: the cone leaves the domain through (or x_hat crosses back) a
        guard that the entry ball met and that the ball has not left since, at ``time`` (s):
        the previous crossing and this return both lie within the error."""
        _, d, r = self.apart
        # The bound where x_hat crosses back, or where the cone has got wholly past.
        radius = self.event[3] if taken and self.event is not None else self.prev[4] if self.prev else r
        self.met[j] = True
        name = self.flow.transitions[j].name
        how = "x_hat crosses back through" if taken else "the cone gets wholly past"
        rec = self._record(
            index,
            j,
            taken,
            "grazing",
            (self.t0, time),
            radius,
            f"{how} the guard of {name} at t={time:.9g} before the ball has left it since the entry "
            f"(entry ball {self.entry_radius:.3g}; x_hat gets at most {d:.3g} from it, bound {r:.3g}): "
            f"the crossing into {self.flow.mode_name} and this return lie within the error",
            time=time,
        )
        return _Visit("grazing", rec, max(d, 0.0), r)

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
        if window[1] > self.run_.t_final:
            return self._window_past_t_final(index, window)
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
