"""The exact execution of the forced oscillator with a stop (``OscillatorReference``).

Eq. (28) of paper 000 between impacts (the forcing integral in closed form), impact times
root-found on it with certified brackets, sticking phases at the stop, and Zeno accumulations
summed in closed form; see the class docstring for the error made.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from ...errors import ModelError, SimulationError
from ...execution import Samples
from .._reference import as_times, make_samples
from .model import EXAMPLES, MODE

#: The largest amplification of the forcing (particular amplitude / static deflection) whose
#: closed form keeps 1e-8 of precision after the homogeneous part cancels it.
RESONANCE_GAIN = 1e8


@dataclass(frozen=True)
class _Phase:
    """A piece of the exact execution starting at ``t``: a ``flight`` (eq. (28) anchored at t),
    ``stick`` (at rest on the stop) or ``chatter`` (a Zeno accumulation summed in closed form,
    reported as rest on the stop)."""

    kind: str
    t: float
    x: float = 0.0
    xd: float = 0.0


class OscillatorReference:
    """The exact execution of the forced oscillator with a stop, built lazily in time.

    Between impacts the solution is eq. (28) of paper 000: the homogeneous part
    ``exp(-a tau) (A cos(w tau) + B sin(w tau))`` with ``w = sqrt(omega^2 - a^2)`` plus the
    periodic particular solution ``P cos(Omega t) + Q sin(Omega t)`` of the forcing
    ``U cos(Omega t)`` (the forcing integral of (28) in closed form). Positions are evaluated as
    increments from the flight's start (``expm1``, half-angle products), so the distance to the
    stop keeps full relative precision even microseconds after an impact.

    Impacts: the next time ``x = x_max`` is root-found (Brent) on a bracket that cannot miss an
    impact: the flight is cut into intervals and on each, ``x - x_max`` is bounded above by
    the quadratic ``g + g' s + (x''(start) + C len) s^2 / 2``, with C a bound on ``|x'''|`` over
    the flight (each derivative of the homogeneous part is at most ``omega^k`` times its
    amplitude, of the particular part ``Omega^k`` times its). Intervals the bound does not
    clear are halved, down to 1e-13 s; a touch of the stop shorter than that (a graze with
    zero speed, whose reset is the identity) is not counted.

    Sticking: at rest on the stop the mass stays while the stop's reaction is compressive,
    i.e. while the free acceleration ``F(t) = u(t)/m - omega^2 x_max`` pushes into the stop
    (paper 000 below Table I); it leaves when F changes sign (found in closed form).

    Zeno accumulation: after an impact with rebound speed ``w < zeno_speed`` while ``F > 0``,
    the remaining impacts form a geometric-like sequence (flights ``2 c^k w / F``) that is summed
    in closed form: the mass sticks from ``t_acc = t + 2 w / (F (1 - c))``. The error of this
    sum is O(w^2) in time; in [t, t_acc] the state is reported as rest at the stop (error
    below ``zeno_speed`` in velocity and ``zeno_speed^2 / (2 F)`` in position). With the
    default 1e-9 m/s both are far below anything a simulation resolves.

    Supports sub-critical damping ``0 <= a < omega`` (eq. (28) needs it), and no undamped
    resonance (``a == 0`` with ``Omega == omega``).
    """

    def __init__(
        self,
        omega: float = 2.5,
        a: float = 0.05,
        x_max: float | None = 14.0,
        c: float = 0.9,
        mass: float = 1.0,
        amplitude: float = 0.0,
        frequency: float = 0.0,
        x0: float = 0.0,
        xd0: float = 0.0,
        t0: float = 0.0,
        zeno_speed: float = 1e-9,
    ) -> None:
        self.omega, self.a, self.c, self.mass = float(omega), float(a), float(c), float(mass)
        self.amplitude, self.frequency = float(amplitude), float(frequency)
        self.x_max = None if x_max is None else float(x_max)
        self.x0, self.xd0, self.t0 = float(x0), float(xd0), float(t0)
        self.zeno_speed = float(zeno_speed)
        if not (self.omega > 0 and 0 <= self.a < self.omega):
            raise ModelError(
                f"oscillator reference: needs sub-critical damping 0 <= a < omega, got a={self.a}, omega={self.omega}"
            )
        if not 0.0 <= self.c <= 1.0:
            raise ModelError(f"oscillator reference: restitution c must lie in [0, 1], got {self.c}")
        if not self.mass > 0:
            raise ModelError(f"oscillator reference: mass must be > 0, got {self.mass}")
        if self.frequency < 0:
            raise ModelError(f"oscillator reference: forcing frequency must be >= 0, got {self.frequency}")
        if self.x_max is not None and self.x0 > self.x_max:
            raise ModelError(f"oscillator reference: x0 = {self.x0} lies beyond the stop x_max = {self.x_max}")
        self.wd = math.sqrt(self.omega**2 - self.a**2)
        # Particular solution of x'' + 2a x' + omega^2 x = (U/m) cos(Omega t): Re(Ubar e^{i Omega t}).
        f_amp = self.amplitude / self.mass
        if self.frequency == 0.0:
            P, Q = f_amp / self.omega**2, 0.0
        else:
            den = complex(self.omega**2 - self.frequency**2, 2.0 * self.a * self.frequency)
            if abs(den) == 0.0:
                raise ModelError(
                    "oscillator reference: undamped resonance (a = 0, forcing frequency = omega) "
                    "has no periodic particular solution"
                )
            ubar = f_amp / den
            P, Q = ubar.real, -ubar.imag
        self.P, self.Q = P, Q
        self.p_amp = math.hypot(P, Q)
        # Near an undamped resonance the particular solution's amplitude is huge, and the
        # homogeneous part cancels it: the closed form keeps only 1e-16 of that amplitude.
        static = f_amp / self.omega**2
        if not math.isfinite(self.p_amp) or self.p_amp > RESONANCE_GAIN * static:
            raise ModelError(
                f"oscillator reference: forcing at {self.frequency:g} rad/s with damping a = {self.a:g} "
                f"is within {RESONANCE_GAIN:.0e} amplification of resonance (omega = {self.omega:g}): "
                f"the closed form would lose its precision"
            )
        # Spacing of the impact search grid: a small fraction of the fastest period.
        self.grid = 0.05 / max(self.omega, self.frequency)
        self.min_interval = 1e-13
        # Bisection nodes one impact search may visit: a search that resolves an impact visits a
        # few per halving level (about 40 levels from the grid down to min_interval); a gap that
        # stays within rounding of zero over a whole interval would visit ~1e11.
        self.max_refinements = 100_000
        self._refinements = 0
        self._phases: list[_Phase] = []
        self._starts: list[float] = []
        self._impacts: list[tuple[float, float]] = []  # (time, speed before the impact)
        self._sticks: list[list[float]] = []  # [start, end]
        self._chatters: list[tuple[float, float]] = []  # (last resolved impact, accumulation time)
        self._horizon = self.t0  # the execution is known on [t0, horizon]
        self._open = True  # the last phase has no known end yet
        self._start(self.t0, self.x0, self.xd0)

    # -- construction from a model -----------------------------------------------------------
    def with_initial(self, mode: str, x: Iterable[float], t0: float = 0.0) -> OscillatorReference:
        """The same oscillator from another initial state ``x = (x, xd)`` at t0."""
        if mode != MODE:
            raise ModelError(f"oscillator reference: unknown mode '{mode}' (modes: ['{MODE}'])")
        x_, xd_ = (float(v) for v in x)
        return OscillatorReference(
            self.omega,
            self.a,
            self.x_max,
            self.c,
            self.mass,
            self.amplitude,
            self.frequency,
            x_,
            xd_,
            t0,
            self.zeno_speed,
        )

    @classmethod
    def example(cls, name: str, **overrides: float) -> OscillatorReference:
        """The reference of Table I ``ex1`` or ``ex2``."""
        p = dict(EXAMPLES[name])
        p.pop("t_max")
        p.update(overrides)
        return cls(**p)

    # -- the closed form ---------------------------------------------------------------------
    def forcing(self, t: np.ndarray | float) -> np.ndarray | float:
        """u(t) (N)."""
        return self.amplitude * np.cos(self.frequency * np.asarray(t, dtype=float))

    def free_acceleration(self, t: np.ndarray | float) -> np.ndarray | float:
        """F(t) = u(t)/m - omega^2 x_max: the acceleration of the mass at rest on the stop (m/s^2);
        the stop's reaction is compressive (the mass stays) while F >= 0."""
        assert self.x_max is not None
        return self.forcing(t) / self.mass - self.omega**2 * self.x_max

    def _particular(self, t):
        th = self.frequency * t
        cs, sn = np.cos(th), np.sin(th)
        return self.P * cs + self.Q * sn, self.frequency * (self.Q * cs - self.P * sn)

    def _flight_coeffs(self, ph: _Phase) -> tuple[float, float, float, float]:
        """Homogeneous initial values (y0, v0) and the sine coefficients of position and velocity."""
        xp, vp = self._particular(ph.t)
        y0, v0 = ph.x - xp, ph.xd - vp
        k_pos = (self.a * y0 + v0) / self.wd
        k_vel = (-(self.omega**2) * y0 - self.a * v0) / self.wd
        return y0, v0, k_pos, k_vel

    def _flight_eval(self, ph: _Phase, tau: np.ndarray | float, coeffs=None):
        """Position and velocity ``tau`` seconds into the flight ``ph`` (arrays or floats)."""
        dx, dv = self._flight_increments(ph, tau, coeffs)
        return ph.x + dx, ph.xd + dv

    def _gap(self, ph: _Phase, tau: np.ndarray | float, coeffs=None):
        """x - x_max and xd ``tau`` seconds into the flight ``ph``, the gap summed from the
        increments so that it keeps its relative precision right after an impact."""
        dx, dv = self._flight_increments(ph, tau, coeffs)
        return (ph.x - self._stop) + dx, ph.xd + dv

    def _flight_increments(self, ph: _Phase, tau: np.ndarray | float, coeffs=None):
        """Increments of position and velocity ``tau`` seconds into the flight ``ph``."""
        y0, v0, k_pos, k_vel = self._flight_coeffs(ph) if coeffs is None else coeffs
        a, wd, om = self.a, self.wd, self.frequency
        e1 = np.expm1(-a * tau)  # e^{-a tau} - 1, exact near tau = 0
        sn = np.sin(wd * tau)
        cm1 = -2.0 * np.sin(0.5 * wd * tau) ** 2  # cos - 1
        hom_x = cm1 * y0 + sn * k_pos  # e^{-a tau}-free increment of the homogeneous position
        hom_v = cm1 * v0 + sn * k_vel
        dx_h = e1 * (y0 + hom_x) + hom_x
        dv_h = e1 * (v0 + hom_v) + hom_v
        # Increments of the particular solution by sum-to-product formulas (no cancellation).
        half = np.sin(0.5 * om * tau)
        mid = om * (ph.t + 0.5 * tau)
        cmid, smid = np.cos(mid), np.sin(mid)
        dx_p = -2.0 * half * (self.P * smid - self.Q * cmid)
        dv_p = -2.0 * om * half * (self.P * cmid + self.Q * smid)
        return dx_h + dx_p, dv_h + dv_p

    def _accel(self, t, x, xd):
        return self.forcing(t) / self.mass - 2.0 * self.a * xd - self.omega**2 * x

    # -- building the execution ---------------------------------------------------------------
    def _push(self, ph: _Phase) -> None:
        self._phases.append(ph)
        self._starts.append(ph.t)

    def _start(self, t: float, x: float, xd: float) -> None:
        """Begin the execution at (t, x, xd), applying an impact or sticking at once if the
        state is at the stop."""
        if self.x_max is not None and x >= self.x_max:
            if xd > 0:
                self._impact(t, xd)
                return
            if xd == 0.0 and self._stays(t):
                self._stick(t)
                return
        self._push(_Phase("flight", t, x, xd))
        self._open = True

    def _impact(self, t: float, speed: float) -> None:
        """An impact at time t with speed ``speed`` >= 0 into the stop."""
        self._impacts.append((t, speed))
        rebound = self.c * speed
        F = self.free_acceleration(t)
        if rebound < self.zeno_speed and (F > 0 or (rebound == 0 and self._stays(t))):
            if rebound > 0 and self.c < 1.0:
                t_acc = float(t + 2.0 * rebound / (F * (1.0 - self.c)))
                self._chatters.append((t, t_acc))
                self._push(_Phase("chatter", t, self._stop, 0.0))
                self._stick(t_acc)
            else:
                self._stick(t)
            return
        self._push(_Phase("flight", t, self._stop, -rebound))
        self._open = True

    def _stick(self, t: float) -> None:
        """At rest on the stop from t until F(t) turns negative."""
        t_release = self._release_time(t)
        if t_release > t:
            self._sticks.append([t, t_release])
            self._push(_Phase("stick", t, self._stop, 0.0))
        if math.isinf(t_release):
            self._open = False
            self._horizon = math.inf
            return
        self._push(_Phase("flight", t_release, self._stop, 0.0))
        self._open = True
        self._horizon = t_release

    def _stays(self, t: float) -> bool:
        """True when a mass at rest on the stop at t stays there: F(t) > 0 presses it on, and an F
        that is identically zero (constant forcing that balances the spring exactly, or no forcing
        with the stop at the spring's equilibrium) leaves it in equilibrium for ever. The latter
        must not start a flight: its gap is zero everywhere and no impact search can clear it."""
        F = self.free_acceleration(t)
        constant = self.frequency == 0.0 or self.amplitude == 0.0
        return bool(F > 0 or (F == 0 and constant))

    def _release_time(self, t: float) -> float:
        """First time >= t at which F turns negative (inf if never)."""
        F0 = self.omega**2 * self._stop
        amp = abs(self.amplitude) / self.mass
        if self.frequency == 0.0 or amp == 0.0:
            return t if self.free_acceleration(t) < 0 else math.inf
        # F = amp cos(theta) - F0 with theta = Omega t + phi; F < 0 on theta in (alpha, 2 pi - alpha).
        kappa = F0 / amp
        if kappa <= -1.0:
            return math.inf
        if kappa >= 1.0:
            return t
        phi = 0.0 if self.amplitude > 0 else math.pi
        alpha = math.acos(kappa)
        theta = self.frequency * t + phi
        two_pi = 2.0 * math.pi
        rel = theta % two_pi
        if alpha < rel < two_pi - alpha:
            return t
        k = math.ceil((theta - alpha) / two_pi)
        t_r = (alpha + two_pi * k - phi) / self.frequency
        return max(t_r, t)

    def _extend(self, t_goal: float) -> None:
        """Compute the execution up to at least t_goal."""
        while self._horizon < t_goal:
            ph = self._phases[-1]
            assert ph.kind == "flight" and self._open
            if self.x_max is None:
                self._horizon = math.inf
                return
            tau_from = self._horizon - ph.t
            tau_to = t_goal - ph.t
            if tau_from == 0.0 and ph.x == self.x_max and ph.xd == 0.0:
                tau_from = min(self._departure(ph), tau_to)
            tau = self._next_impact(ph, tau_from, tau_to)
            if tau is None:
                self._horizon = t_goal
                return
            _, speed = self._gap(ph, tau)
            t_hit = ph.t + tau
            self._horizon = t_hit
            self._impact(t_hit, max(float(speed), 0.0))

    def _departure(self, ph: _Phase) -> float:
        """A time into a flight that starts at rest on the stop before which the mass is
        certainly off the stop, from its Taylor expansion with a bound on the fourth derivative:
        ``x - x_max <= c2 s^2 + c3 s^3 + D4 s^4 / 24``. Without it the interval search would
        have to halve its way out of the triple root of a release (where F(t) = 0)."""
        y0, _v0, k_pos, _ = self._flight_coeffs(ph)
        d4 = math.hypot(y0, k_pos) * self.omega**4 + self.p_amp * self.frequency**4
        acc = float(self._accel(ph.t, ph.x, 0.0))
        jerk = (
            float(-self.amplitude * self.frequency * math.sin(self.frequency * ph.t)) / self.mass - 2.0 * self.a * acc
        )
        c2, c3 = 0.5 * acc, jerk / 6.0
        # At a release F(t) = 0 exactly but is known only to rounding: such a c2 counts as zero.
        if abs(c2) <= 1e-12 * (abs(self.amplitude) / self.mass + self.omega**2 * abs(self._stop)):
            c2 = 0.0
        if d4 == 0.0 or c2 > 0.0 or (c2 == 0.0 and c3 >= 0.0):
            return 0.0
        # The bound divided by s^2 is c2 + c3 s + d4 s^2 / 24 <= c2 + |c3| s + d4 s^2 / 24 when c2 < 0.
        b = abs(c3) if c2 < 0 else c3
        q = d4 / 24.0
        disc = b * b - 4.0 * q * c2
        root = (-b + math.sqrt(disc)) / (2.0 * q) if c2 < 0 else -c3 / q
        return 0.5 * root

    def _next_impact(self, ph: _Phase, tau_from: float, tau_to: float) -> float | None:
        """First tau in (tau_from, tau_to] where the flight reaches the stop, or None."""
        coeffs = self._flight_coeffs(ph)
        y0, _v0, k_pos, _ = coeffs
        hom_amp = math.hypot(y0, k_pos)  # amplitude of the homogeneous position at the flight start
        ctx = (ph, coeffs, hom_amp)
        self._refinements = 0
        lo = tau_from
        while lo < tau_to:
            edges = lo + self.grid * np.arange(65)
            edges = edges[edges < tau_to]
            edges = np.append(edges, tau_to) if edges[-1] < tau_to else edges
            if len(edges) < 2:
                break
            g, xd = self._gap(ph, edges, coeffs)
            ok = self._cleared(ctx, edges[:-1], edges[1:], g[:-1], xd[:-1])
            for i in np.nonzero(~ok)[0]:
                root = self._refine(ctx, float(edges[i]), float(edges[i + 1]))
                if root is not None:
                    return root
            lo = float(edges[-1])
        return None

    def _cleared(self, ctx, tl, tr, g, gd) -> np.ndarray:
        """True where x < x_max is certain on (tl, tr] (arrays), from the quadratic upper bound."""
        ph, _coeffs, hom_amp = ctx
        length = tr - tl
        C = hom_amp * np.exp(-self.a * tl) * self.omega**3 + self.p_amp * self.frequency**3
        gdd = self._accel(ph.t + tl, g + self.x_max, gd)
        beta = gdd + C * length
        end = g + gd * length + 0.5 * beta * length**2
        # A concave bound (beta < 0) may peak inside the interval, at s* = -g'/beta.
        concave = beta < 0
        safe_beta = np.where(concave, beta, -1.0)
        s_star = -gd / safe_beta
        interior = concave & (s_star > 0) & (s_star < length)
        peak = np.where(interior, g - gd * gd / (2.0 * safe_beta), -np.inf)
        # At a flight's first instant (on the stop, g == 0) the left end is excluded: it is cleared
        # when the bound falls below zero at once.
        leaving = (g == 0) & ((gd < 0) | ((gd == 0) & (beta < 0)))
        left = np.where(leaving, -np.inf, g)
        return np.maximum(np.maximum(left, end), peak) < 0

    def _refine(self, ctx, tl: float, tr: float) -> float | None:
        """First root of x - x_max in (tl, tr] by bisection of uncleared intervals, then Brent."""
        ph, coeffs, hom_amp = ctx
        self._refinements += 1
        if self._refinements > self.max_refinements:
            raise SimulationError(
                f"oscillator reference: the impact search of the flight from t = {ph.t:g} s (x = {ph.x:g} m, "
                f"xd = {ph.xd:g} m/s) visited {self.max_refinements} intervals near t = {ph.t + tl:g} s without "
                f"clearing the stop x_max = {self.x_max:g} m or crossing it: the gap stays within rounding "
                f"of zero (a mass resting on the stop?)"
            )
        g_l, gd = self._gap(ph, tl, coeffs)
        g_r, _ = self._gap(ph, tr, coeffs)
        g_l, gd, g_r = float(g_l), float(gd), float(g_r)
        length = tr - tl
        C = hom_amp * math.exp(-self.a * tl) * self.omega**3 + self.p_amp * self.frequency**3
        gdd = float(self._accel(ph.t + tl, g_l + self._stop, gd))
        if _bound_clears(g_l, gd, gdd + C * length, length):
            return None
        if g_l < 0 <= g_r:
            low_slope = gd + min(0.0, gdd - C * length) * length
            if low_slope > 0 or length <= self.min_interval:  # one crossing only, or resolution reached
                fn = lambda s: float(self._gap(ph, s, coeffs)[0])  # noqa: E731
                return brentq(fn, tl, tr, xtol=1e-300, rtol=4 * np.finfo(float).eps, maxiter=200)
        if tr - tl <= self.min_interval:
            return None
        mid = 0.5 * (tl + tr)
        root = self._refine(ctx, tl, mid)
        return root if root is not None else self._refine(ctx, mid, tr)

    # -- queries -------------------------------------------------------------------------------
    @property
    def _stop(self) -> float:
        """x_max (m), in the code of impacts and rest, which runs only for an oscillator with a stop."""
        if self.x_max is None:
            raise SimulationError("oscillator reference: an impact without a stop (x_max is None)")
        return self.x_max

    def states(self, times: Iterable[float] | float) -> np.ndarray:
        """Exact states (x, xd) at ``times`` (s), shape (len, 2); right-continuous at impacts
        (the state at an impact time is the reset image)."""
        arr = as_times(times, self.t0)
        if arr.size:
            self._extend(float(arr.max()))
        out = np.empty((len(arr), 2))
        idx = np.searchsorted(np.array(self._starts), arr, side="right") - 1
        for p in np.unique(idx):
            sel = idx == p
            ph = self._phases[p]
            if ph.kind == "flight":
                x, xd = self._flight_eval(ph, arr[sel] - ph.t)
                out[sel, 0], out[sel, 1] = x, xd
            else:
                out[sel] = (ph.x, ph.xd)
        return out

    def state(self, t: float) -> np.ndarray:
        """Exact state (x, xd) at time t (s)."""
        return self.states([t])[0]

    def position(self, t: Sequence[float] | np.ndarray | float) -> np.ndarray | float:
        """Exact position x(t) (m), for a float or an array of times."""
        out = self.states(t)[:, 0]
        return float(out[0]) if np.ndim(t) == 0 else out

    def velocity(self, t: Sequence[float] | np.ndarray | float) -> np.ndarray | float:
        """Exact velocity xd(t) (m/s)."""
        out = self.states(t)[:, 1]
        return float(out[0]) if np.ndim(t) == 0 else out

    def sample(self, times: Iterable[float] | float) -> Samples:
        """The exact execution at ``times``, in the format of ``Execution.sample``."""
        arr = as_times(times, self.t0)
        return make_samples(arr, [MODE] * len(arr), self.states(arr))

    def impact_times(self, t_end: float) -> np.ndarray:
        """Times (s) of the resolved impacts in [t0, t_end] (those of a Zeno accumulation beyond
        the last resolved one are summed, not listed: see ``chatter_intervals``)."""
        self._extend(t_end)
        return np.array([t for t, _ in self._impacts if t <= t_end])

    def impact_speeds(self, t_end: float) -> np.ndarray:
        """Speeds into the stop (m/s) just before the impacts of ``impact_times``."""
        self._extend(t_end)
        return np.array([v for t, v in self._impacts if t <= t_end])

    def sticking_intervals(self, t_end: float) -> list[tuple[float, float]]:
        """(start, end) of each sticking phase that starts before t_end (end may be inf)."""
        self._extend(t_end)
        return [(s, e) for s, e in self._sticks if s <= t_end]

    def chatter_intervals(self, t_end: float) -> list[tuple[float, float]]:
        """(last resolved impact, accumulation time) of each Zeno accumulation before t_end."""
        self._extend(t_end)
        return [(s, e) for s, e in self._chatters if s <= t_end]

    def zeno_times(self, t_end: float) -> np.ndarray:
        """Accumulation times (s) of the Zeno sequences that start before t_end."""
        return np.array([e for _, e in self.chatter_intervals(t_end)])


def _bound_clears(g: float, gd: float, beta: float, length: float) -> bool:
    """True when ``g + gd s + beta s^2 / 2 < 0`` for all s in (0, length] (scalar twin of
    ``OscillatorReference._cleared``; the left end counts only if the bound does not fall at once)."""
    end = g + gd * length + 0.5 * beta * length * length
    if end >= 0:
        return False
    if beta < 0:
        s_star = -gd / beta
        if 0 < s_star < length and g - gd * gd / (2.0 * beta) >= 0:
            return False
    if g < 0:
        return True
    return g == 0 and (gd < 0 or (gd == 0 and beta < 0))
