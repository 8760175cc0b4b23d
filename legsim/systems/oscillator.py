"""The forced linear oscillator with a stop (paper 000, Section V-B, Fig. 14, Table I).

A mass m on a spring, with viscous damping, forced by ``u(t) = U cos(Omega t)`` (N), moves along
x and may hit a rigid stop at ``x_max``::

    x'' + 2 a x' + omega^2 x = u(t) / m          while x < x_max,
    (x, x') -> (x, -c x')                         when x reaches x_max moving towards it.

One mode ``free`` with state ``(x, xd)`` (m, m/s). With the stop there is one transition
``impact`` (``free -> free``) with guard ``max(x_max - x, -xd)``: past the guard means beyond
the stop *and* moving into it, so near an impact the guard's value is the distance to the stop
and eps is measured in metres. Without the stop there is no transition. The forcing is the
model's *control* ``u(t, x) = U cos(Omega t)``, so that it travels the integrator's control
path (sampled at every Runge-Kutta stage).

With the effect ``zeno = { window = h + eps }`` (Zeno continuation, off by default) an impact
whose next flight would be shorter than the window sticks instead of chattering: transition
``stick`` into mode ``stuck`` (state held), left through ``release`` when the free acceleration
at the stop ``F = u/m - omega^2 x_max`` changes sign, as the exact mass does (guards on
(t, x, u); see ``make_system`` and docs/stress.md).

Table I of paper 000 (m = 1):

=========  ====  ===  =======  ===============  =====  =====  =====  =====
example    a     c    t_max    u(t)             x0     xd0    x_max  omega
=========  ====  ===  =======  ===============  =====  =====  =====  =====
Example 1  0.05  0.9  40 pi    20 cos(5 t / 2)  11.36  31.4   14     2.5
Example 2  0.95  0.5  4 pi     cos(t)           -0.8   0      -0.8   1
=========  ====  ===  =======  ===============  =====  =====  =====  =====

``OscillatorReference`` is the exact execution: eq. (28) between impacts (the forcing integral
in closed form), impact times root-found on it with certified brackets, sticking phases at the
stop, and Zeno accumulations summed in closed form (see its docstring for the error made).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, Iterable

import numpy as np
from scipy.optimize import brentq

from ..builders import Builder, Effect, Model, Param
from ..errors import ModelError, SimulationError
from ..execution import Samples
from ..hybrid import HybridSystem, Mode, Transition
from ._reference import as_times, box, make_samples, segment, zigzag

MODE = "free"
STUCK = "stuck"  # at rest on the stop (Zeno continuation only)
NAMES = ("x", "xd")

#: Table I of paper 000, as keyword arguments of ``make_system``/``OscillatorReference`` plus the
#: initial state and the end time.
EXAMPLES: dict[str, dict[str, float]] = {
    "ex1": {"a": 0.05, "c": 0.9, "t_max": 40.0 * math.pi, "amplitude": 20.0, "frequency": 2.5,
            "x0": 11.36, "xd0": 31.4, "x_max": 14.0, "omega": 2.5, "mass": 1.0},
    "ex2": {"a": 0.95, "c": 0.5, "t_max": 4.0 * math.pi, "amplitude": 1.0, "frequency": 1.0,
            "x0": -0.8, "xd0": 0.0, "x_max": -0.8, "omega": 1.0, "mass": 1.0},
}


def forcing(amplitude: float, frequency: float, counters: dict[str, int] | None = None
            ) -> Callable[[float, np.ndarray], float]:
    """The control ``u(t, x) = amplitude * cos(frequency * t)`` (N; frequency in rad/s).

    ``counters``, when given, counts the evaluations under ``forcing_evals``.
    """
    amplitude, frequency = float(amplitude), float(frequency)

    if counters is None:
        def u(t: float, x: np.ndarray) -> float:
            return amplitude * math.cos(frequency * t)
    else:
        counters.setdefault("forcing_evals", 0)

        def u(t: float, x: np.ndarray) -> float:
            counters["forcing_evals"] += 1
            return amplitude * math.cos(frequency * t)

    return u


def make_system(omega: float = 2.5, a: float = 0.05, x_max: float | None = 14.0, c: float = 0.9,
                mass: float = 1.0, counters: dict[str, int] | None = None,
                zeno_window: float = 0.0) -> HybridSystem:
    """The oscillator as a hybrid system; pass ``x_max=None`` for no stop (no guard).

    Parameters
    ----------
    omega: natural frequency sqrt(k / m) (rad/s), > 0.
    a: damping rate mu / (2 m) (1/s), >= 0.
    x_max: position of the stop (m), or None.
    c: coefficient of restitution at the stop, in [0, 1].
    mass: m (kg), > 0; the control u is a force (N), the field uses u / m (None means u = 0).
    counters: when given, ``damping_evals`` counts the evaluations of the damping term (none
        at all when a = 0: the field then has no such term).
    zeno_window: Zeno continuation (s; 0, the default, switches it off): an impact whose next
        flight would be shorter than the window (rebound ``c v0 < F zeno_window / 2``, F the free
        acceleration pressing the mass on the stop, v0 the approach speed back at the stop) and
        after which the stop would push (F > 0) sticks instead: mode ``stuck`` (x, xd held), left
        through ``release`` when F changes sign. Set it to h + eps of the run (see
        docs/stress.md). The guards then depend on the forcing, so they are declared on (t, x, u).
    """
    omega, a, c, mass = float(omega), float(a), float(c), float(mass)
    if not (omega > 0 and math.isfinite(omega)):
        raise ModelError(f"oscillator: omega must be finite and > 0, got {omega}")
    if not (a >= 0 and math.isfinite(a)):
        raise ModelError(f"oscillator: damping a must be finite and >= 0, got {a}")
    if not 0.0 <= c <= 1.0:
        raise ModelError(f"oscillator: restitution c must lie in [0, 1], got {c}")
    if not (mass > 0 and math.isfinite(mass)):
        raise ModelError(f"oscillator: mass must be finite and > 0, got {mass}")
    w2 = omega * omega
    two_a = 2.0 * a
    inv_m = 1.0 / mass
    # Finite parameters can still overflow the field's coefficients (omega = 1e300): refuse
    # them here by name rather than let every field value be inf or nan.
    for label, value in (("omega^2", w2), ("2 a", two_a), ("1 / mass", inv_m)):
        if not math.isfinite(value):
            raise ModelError(f"oscillator: {label} overflows (omega = {omega:g}, a = {a:g}, mass = {mass:g})")

    if a == 0.0:
        def field(t: float, x: np.ndarray, u: Any) -> np.ndarray:
            force = 0.0 if u is None else u
            return np.array([x[1], force * inv_m - w2 * x[0]])
    elif counters is None:
        def field(t: float, x: np.ndarray, u: Any) -> np.ndarray:
            force = 0.0 if u is None else u
            return np.array([x[1], force * inv_m - two_a * x[1] - w2 * x[0]])
    else:
        counters.setdefault("damping_evals", 0)

        def field(t: float, x: np.ndarray, u: Any) -> np.ndarray:
            counters["damping_evals"] += 1
            force = 0.0 if u is None else u
            return np.array([x[1], force * inv_m - two_a * x[1] - w2 * x[0]])

    def jacobian(t: float, x: np.ndarray, u: Any) -> np.ndarray:
        return np.array([[0.0, 1.0], [-w2, -two_a]])

    def energy(mode: str, x: np.ndarray) -> float:
        # Products, not float powers: ** raises OverflowError where * gives inf.
        q, qd = float(x[0]), float(x[1])
        return 0.5 * mass * (qd * qd + w2 * q * q)

    transitions = []
    x0 = 0.0
    if x_max is not None:
        stop = float(x_max)
        if not math.isfinite(stop):
            raise ModelError(f"oscillator: stop position x_max must be finite, got {x_max}")
        x0 = min(0.0, stop)

        def guard(x: np.ndarray) -> float:
            d = stop - x[0]
            return d if d > -x[1] else -x[1]

        def guard_gradient(x: np.ndarray) -> np.ndarray:
            return np.array([-1.0, 0.0]) if stop - x[0] > -x[1] else np.array([0.0, -1.0])

        def reset(x: np.ndarray) -> np.ndarray:
            return np.array([x[0], -c * x[1]])

        window = float(zeno_window)
        if not (window >= 0.0 and math.isfinite(window)):
            raise ModelError(f"oscillator: zeno_window must be finite and >= 0 s, got {zeno_window}")
        if window == 0.0:
            transitions.append(Transition(MODE, MODE, guard, reset, name="impact", guard_gradient=guard_gradient,
                                          reset_jacobian=lambda x: np.diag([1.0, -c])))
        else:
            transitions.extend(_zeno_transitions(guard, reset, stop, c, w2, inv_m, window))
    modes = {MODE: Mode(2, field, NAMES, jacobian)}
    if any(tr.target == STUCK for tr in transitions):
        modes[STUCK] = Mode(2, lambda t, x, u: np.zeros(2), NAMES, lambda t, x, u: np.zeros((2, 2)))
    return HybridSystem(modes, transitions,
                        name="oscillator with stop" if transitions else "oscillator",
                        energy=energy, initial=(MODE, np.array([x0, 0.0])))


def _zeno_transitions(gap: Callable[[np.ndarray], float], bounce: Callable[[np.ndarray], np.ndarray], stop: float,
                      c: float, w2: float, inv_m: float, window: float) -> list[Transition]:
    """Zeno continuation at the stop: ``impact`` (bounce) and ``stick`` (plastic, into ``stuck``)
    from ``free`` with complementary guards, and ``release`` from ``stuck``.

    Past the stop's guard the impact *accumulates* when the free acceleration at rest on the stop,
    ``F = u/m - omega^2 x`` (m/s^2, > 0 pressing), is positive and the rebound ``c v0`` with
    ``v0^2 = xd^2 - 2 F (x - x_max)`` (the approach speed back at the stop, so that the decision is
    the same all along a step through the strip) is below ``F window / 2``. The branch taken has
    the stop's guard itself (m), the other its opposite (not past). ``release``: guard F itself,
    the stop pushes while F >= 0 (paper 000 below Table I)."""

    def pressing(x: np.ndarray, u: Any) -> float:
        return (0.0 if u is None else u) * inv_m - w2 * x[0]

    def branch(sticks: bool):
        def g(t: float, x: np.ndarray, u: Any) -> float:
            base = gap(x)
            if base >= 0.0:
                return base
            F = pressing(x, u)
            v0 = math.sqrt(max(x[1] * x[1] - 2.0 * F * max(x[0] - stop, 0.0), 0.0))
            accumulating = F > 0.0 and c * v0 < 0.5 * F * window
            return base if accumulating == sticks else -base
        return g

    def stick(x: np.ndarray) -> np.ndarray:
        return np.array([x[0], 0.0])

    return [Transition(MODE, MODE, branch(False), bounce, name="impact", guard_args="t,x,u"),
            Transition(MODE, STUCK, branch(True), stick, name="stick", guard_args="t,x,u"),
            Transition(STUCK, MODE, lambda t, x, u: pressing(x, u), name="release", guard_args="t,x,u")]


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

    def __init__(self, omega: float = 2.5, a: float = 0.05, x_max: float | None = 14.0, c: float = 0.9,
                 mass: float = 1.0, amplitude: float = 0.0, frequency: float = 0.0, x0: float = 0.0,
                 xd0: float = 0.0, t0: float = 0.0, zeno_speed: float = 1e-9) -> None:
        self.omega, self.a, self.c, self.mass = float(omega), float(a), float(c), float(mass)
        self.amplitude, self.frequency = float(amplitude), float(frequency)
        self.x_max = None if x_max is None else float(x_max)
        self.x0, self.xd0, self.t0 = float(x0), float(xd0), float(t0)
        self.zeno_speed = float(zeno_speed)
        if not (self.omega > 0 and 0 <= self.a < self.omega):
            raise ModelError(f"oscillator reference: needs sub-critical damping 0 <= a < omega, "
                             f"got a={self.a}, omega={self.omega}")
        if not 0.0 <= self.c <= 1.0:
            raise ModelError(f"oscillator reference: restitution c must lie in [0, 1], got {self.c}")
        if not self.mass > 0:
            raise ModelError(f"oscillator reference: mass must be > 0, got {self.mass}")
        if self.frequency < 0:
            raise ModelError(f"oscillator reference: forcing frequency must be >= 0, got {self.frequency}")
        if self.x_max is not None and self.x0 > self.x_max:
            raise ModelError(f"oscillator reference: x0 = {self.x0} lies beyond the stop x_max = {self.x_max}")
        self.wd = math.sqrt(self.omega ** 2 - self.a ** 2)
        # Particular solution of x'' + 2a x' + omega^2 x = (U/m) cos(Omega t): Re(Ubar e^{i Omega t}).
        f_amp = self.amplitude / self.mass
        if self.frequency == 0.0:
            P, Q = f_amp / self.omega ** 2, 0.0
        else:
            den = complex(self.omega ** 2 - self.frequency ** 2, 2.0 * self.a * self.frequency)
            if abs(den) == 0.0:
                raise ModelError("oscillator reference: undamped resonance (a = 0, forcing frequency = omega) "
                                 "has no periodic particular solution")
            ubar = f_amp / den
            P, Q = ubar.real, -ubar.imag
        self.P, self.Q = P, Q
        self.p_amp = math.hypot(P, Q)
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
    def with_initial(self, mode: str, x: Iterable[float], t0: float = 0.0) -> "OscillatorReference":
        """The same oscillator from another initial state ``x = (x, xd)`` at t0."""
        if mode != MODE:
            raise ModelError(f"oscillator reference: unknown mode '{mode}' (modes: ['{MODE}'])")
        x_, xd_ = (float(v) for v in x)
        return OscillatorReference(self.omega, self.a, self.x_max, self.c, self.mass, self.amplitude,
                                   self.frequency, x_, xd_, t0, self.zeno_speed)

    @classmethod
    def example(cls, name: str, **overrides: float) -> "OscillatorReference":
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
        return self.forcing(t) / self.mass - self.omega ** 2 * self.x_max

    def _particular(self, t):
        th = self.frequency * t
        cs, sn = np.cos(th), np.sin(th)
        return self.P * cs + self.Q * sn, self.frequency * (self.Q * cs - self.P * sn)

    def _flight_coeffs(self, ph: _Phase) -> tuple[float, float, float, float]:
        """Homogeneous initial values (y0, v0) and the sine coefficients of position and velocity."""
        xp, vp = self._particular(ph.t)
        y0, v0 = ph.x - xp, ph.xd - vp
        k_pos = (self.a * y0 + v0) / self.wd
        k_vel = (-self.omega ** 2 * y0 - self.a * v0) / self.wd
        return y0, v0, k_pos, k_vel

    def _flight_eval(self, ph: _Phase, tau: np.ndarray | float, coeffs=None):
        """Position and velocity ``tau`` seconds into the flight ``ph`` (arrays or floats)."""
        dx, dv = self._flight_increments(ph, tau, coeffs)
        return ph.x + dx, ph.xd + dv

    def _gap(self, ph: _Phase, tau: np.ndarray | float, coeffs=None):
        """x - x_max and xd ``tau`` seconds into the flight ``ph``, the gap summed from the
        increments so that it keeps its relative precision right after an impact."""
        dx, dv = self._flight_increments(ph, tau, coeffs)
        return (ph.x - self.x_max) + dx, ph.xd + dv

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
        return self.forcing(t) / self.mass - 2.0 * self.a * xd - self.omega ** 2 * x

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
                self._push(_Phase("chatter", t, self.x_max, 0.0))
                self._stick(t_acc)
            else:
                self._stick(t)
            return
        self._push(_Phase("flight", t, self.x_max, -rebound))
        self._open = True

    def _stick(self, t: float) -> None:
        """At rest on the stop from t until F(t) turns negative."""
        t_release = self._release_time(t)
        if t_release > t:
            self._sticks.append([t, t_release])
            self._push(_Phase("stick", t, self.x_max, 0.0))
        if math.isinf(t_release):
            self._open = False
            self._horizon = math.inf
            return
        self._push(_Phase("flight", t_release, self.x_max, 0.0))
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
        F0 = self.omega ** 2 * self.x_max
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
        y0, v0, k_pos, _ = self._flight_coeffs(ph)
        d4 = math.hypot(y0, k_pos) * self.omega ** 4 + self.p_amp * self.frequency ** 4
        acc = float(self._accel(ph.t, ph.x, 0.0))
        jerk = float(-self.amplitude * self.frequency * math.sin(self.frequency * ph.t)) / self.mass \
            - 2.0 * self.a * acc
        c2, c3 = 0.5 * acc, jerk / 6.0
        # At a release F(t) = 0 exactly but is known only to rounding: such a c2 counts as zero.
        if abs(c2) <= 1e-12 * (abs(self.amplitude) / self.mass + self.omega ** 2 * abs(self.x_max)):
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
        y0, v0, k_pos, _ = coeffs
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
        ph, coeffs, hom_amp = ctx
        length = tr - tl
        C = hom_amp * np.exp(-self.a * tl) * self.omega ** 3 + self.p_amp * self.frequency ** 3
        gdd = self._accel(ph.t + tl, g + self.x_max, gd)
        beta = gdd + C * length
        end = g + gd * length + 0.5 * beta * length ** 2
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
                f"of zero (a mass resting on the stop?)")
        g_l, gd = self._gap(ph, tl, coeffs)
        g_r, _ = self._gap(ph, tr, coeffs)
        g_l, gd, g_r = float(g_l), float(gd), float(g_r)
        length = tr - tl
        C = hom_amp * math.exp(-self.a * tl) * self.omega ** 3 + self.p_amp * self.frequency ** 3
        gdd = float(self._accel(ph.t + tl, g_l + self.x_max, gd))
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

    def position(self, t: Iterable[float] | float) -> np.ndarray | float:
        """Exact position x(t) (m), for a float or an array of times."""
        out = self.states(t)[:, 0]
        return float(out[0]) if np.ndim(t) == 0 else out

    def velocity(self, t: Iterable[float] | float) -> np.ndarray | float:
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


def _build(params: dict[str, Any], effects: dict[str, dict[str, Any]]) -> Model:
    stop = effects.get("stop")
    damping = effects.get("damping")
    force = effects.get("forcing")
    x_max = None if stop is None else stop["position"]
    c = 0.0 if stop is None else stop["restitution"]
    a = 0.0 if damping is None else damping["a"]
    counts = {"damping_evals": 0, "forcing_evals": 0}
    window = effects["zeno"]["window"] if "zeno" in effects and stop is not None else 0.0
    system = make_system(params["omega"], a, x_max, c, params["mass"], counters=counts, zeno_window=window)
    control = None if force is None else forcing(force["amplitude"], force["frequency"], counts)
    amplitude = 0.0 if force is None else force["amplitude"]
    frequency = 0.0 if force is None else force["frequency"]
    size = params["size"]
    info: dict[str, Any] = {"guard units": {"impact": "m (distance to the stop)"} if stop else {}}
    if window > 0.0:
        info["guard units"].update({"stick": "m (distance to the stop)",
                                    "release": "m/s^2 (free acceleration pressing the mass on the stop)"})
    if x_max is not None:
        info["initial_check"] = _beyond_the_stop(x_max)
    try:
        reference = OscillatorReference(params["omega"], a, x_max, c, params["mass"], amplitude, frequency,
                                        params["x0"], params["xd0"])
    except ModelError as exc:  # over-damped or undamped resonance: no closed form here
        reference = None
        info["reference"] = f"none: {exc}"

    def geometry(mode: str, x: np.ndarray) -> dict[str, np.ndarray]:
        pos = float(x[0])
        wall = -2.0 * size if x_max is None else min(-2.0 * size, x_max - 4.0 * size)
        return {"mass": box(pos - size, pos, 0.0, size),
                "spring": zigzag(min(wall, pos - size), pos - size, 0.5 * size, 0.2 * size)}

    scenery: dict[str, np.ndarray] = {}
    lo = -abs(params["x0"]) - 4.0 * size if x_max is None else min(params["x0"], x_max) - 4.0 * size
    hi = abs(params["x0"]) + 4.0 * size if x_max is None else x_max + size
    scenery["floor"] = segment([lo, 0.0], [hi, 0.0])
    if x_max is not None:
        scenery["stop"] = segment([x_max, 0.0], [x_max, 2.0 * size])
    scenery["rest"] = segment([0.0, -0.25 * size], [0.0, 0.0])
    return Model(system, MODE, {"x": params["x0"], "xd": params["xd0"]}, control, geometry, scenery, reference,
                 counters=lambda: dict(counts), info=info)


def _beyond_the_stop(x_max: float) -> Callable[[str, np.ndarray, float], str | None]:
    """The scene's initial-state check: the guard max(x_max - x, -xd) counts a mass beyond the
    stop as inside while it moves away from it (that is how it leaves the stop after an impact
    in the strip), so a start deeper than the strip must be refused by name."""
    def check(mode: str, x: np.ndarray, eps: float) -> str | None:
        if x[0] > x_max + eps:
            return f"x = {x[0]:g} m lies beyond the stop x_max = {x_max:g} m by more than eps = {eps:g} m"
        return None

    return check


BUILDER = Builder(
    name="oscillator",
    description="Forced linear oscillator with a stop (paper 000 Sec. V-B); defaults are Table I Example 1.",
    parameters={
        "omega": Param(2.5, "natural frequency sqrt(k/m)", "rad/s", low=0.0, low_open=True),
        "mass": Param(1.0, "mass m (the forcing is a force, the field uses u/m)", "kg", low=0.0, low_open=True),
        "x0": Param(11.36, "default initial position", "m"),
        "xd0": Param(31.4, "default initial velocity", "m/s"),
        "size": Param(1.0, "side of the box drawn for the mass", "m", low=0.0, low_open=True),
    },
    effects={
        "stop": Effect("a rigid stop at x = position with the impact law xd -> -c xd", default_on=True,
                       parameters={"position": Param(14.0, "position of the stop x_max", "m"),
                                   "restitution": Param(0.9, "coefficient of restitution c", "", low=0.0,
                                                        high=1.0)}),
        "zeno": Effect("Zeno continuation at the stop: an impact whose next flight would be shorter than "
                       "`window` sticks (mode 'stuck') until the stop force changes sign (needs the stop)",
                       parameters={"window": Param(2e-3, "shortest flight resolved; set it to h + eps of the run",
                                                   "s", low=0.0, low_open=True)}),
        "damping": Effect("viscous damping 2 a xd", default_on=True,
                          parameters={"a": Param(0.05, "damping rate mu / (2 m)", "1/s", low=0.0)}),
        "forcing": Effect("external force u(t) = amplitude cos(frequency t), passed as the control",
                          default_on=True,
                          parameters={"amplitude": Param(20.0, "force amplitude", "N"),
                                      "frequency": Param(2.5, "forcing frequency", "rad/s", low=0.0)}),
    },
    build=_build,
)
