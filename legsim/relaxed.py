"""The relaxed hybrid integrator (paper 000, Fig. 12; paper 003, Definition 14 for Euler).

Each guard is thickened into a strip ``-eps <= guard < 0``. Inside a mode any Runge-Kutta
method steps with the nominal size h; a trial step that would land past the strip (some
guard < -eps) is halved until it lands in the relaxed domain; a step that lands in a strip
crosses it:

* the strip point is the pair (q, tau): tau = -guard at the landing point and q a point of the
  guard. We take q where the step's own cubic Hermite interpolant (built from the step's ends
  and the field there) meets the guard, found by a bracketed root search on the interpolant.
  Bringing the state back *along the flow* keeps conserved quantities to the interpolant's
  accuracy (O(tau^4) here, O(tau^2) for any consistent interpolant), whereas projecting the
  landing point along the guard gradient changes a runner's energy by O(tau) at every
  touchdown. The bracket (guard >= 0 at the step start, < 0 at the landing) always exists, so
  the search needs no division by the guard's rate and stays safe where the flow is nearly
  tangent to the guard; should the guard be discontinuous along the interpolant, the
  domain-side end of the final bracket is used, which is never past the guard.
* the state is held at q for the remaining strip time eps - tau (paper 000 Fig. 12, step 12),
  then the reset is applied to q, not to the overshot landing point. Resetting the overshot
  point would sink the state deeper at every transition and stall a Zeno run in a stream of
  near-zero-time transitions.
* when a step lands in several strips at once (simultaneous guards) the transition whose
  crossing on the interpolant comes first is taken; the next mode then sees its own guard
  already crossed and transitions again at once. Overlapping guards need no special case.

Each step starts from the nominal h again (Fig. 12, step 3), so the nominal step is restored
after every transition.
"""

from __future__ import annotations

import math
import time as _time
from math import isfinite
from typing import Any, Callable

import numpy as np

from .errors import LegsimError, ModelBreakdown, ModelError, SimulationError
from .execution import Execution, SegmentBuffer, Strip, TransitionRecord
from .hybrid import HybridSystem, check_field_output, check_reset_output
from .methods import ContinuousStep, Tableau, dense_output, get_method, make_error_norm, make_stepper

ProgressFn = Callable[[float, float, float], None]


def _check_positive(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise SimulationError(f"{name} must be a number, got {type(value).__name__} {value!r}")
    value = float(value)
    if not math.isfinite(value) or value <= 0.0:
        raise SimulationError(f"{name} must be finite and > 0, got {value}")
    return value


def hermite(x0: np.ndarray, d0: np.ndarray, x1: np.ndarray, d1: np.ndarray, dt: float, s: float) -> np.ndarray:
    """Cubic Hermite interpolant on a step of length dt at fraction s in [0, 1]."""
    s2 = s * s
    s3 = s2 * s
    return ((2 * s3 - 3 * s2 + 1) * x0 + (s3 - 2 * s2 + s) * dt * d0
            + (-2 * s3 + 3 * s2) * x1 + (s3 - s2) * dt * d1)


def hermite_derivative(x0, d0, x1, d1, dt: float, s: float) -> np.ndarray:
    """d/dt of the cubic Hermite interpolant at fraction s."""
    s2 = s * s
    return ((6 * s2 - 6 * s) * x0 / dt + (3 * s2 - 4 * s + 1) * d0
            + (-6 * s2 + 6 * s) * x1 / dt + (3 * s2 - 2 * s) * d1)


#: Iterates without the bracket halving before crossing_on_step bisects.
_STALL = 3
#: Closest an iterate of crossing_on_step comes to an end of its bracket (step fractions): a few
#: float spacings at 1, so that an end that is the root to rounding is straddled.
_MIN_STEP = 4e-16


def crossing_on_step(guard_at: Callable[[float], float], g0: float, g1: float,
                     tol: float) -> tuple[float, int, bool]:
    """Where a step's interpolant meets a guard: returns (s, guard evaluations, converged).

    ``guard_at(s)`` is the guard on the interpolant at the step fraction s in [0, 1].
    Illinois regula falsi on the bracket [0, 1] with guard_at(0) = g0 >= 0 > g1 = guard_at(1),
    safeguarded as in Brent's method: a bisection whenever the bracket has not halved within
    ``_STALL`` iterates (so that a kink or a jump cannot stall it), and no iterate closer than
    ``_MIN_STEP`` to an end of the bracket (so that an end already at the root, to rounding, is
    straddled at once instead of being approached from one side forever; a fixed bisection
    schedule would reset Illinois' halving of the stale end and crawl to it). The point returned
    is the end of the final bracket *past* the guard (-tol <= g <= 0): a strip point on the
    domain side, however close, would put the reset image past a complementary guard (leave
    through x = 1, come back through x = 1) and make the next mode cross again at once. When
    the guard is discontinuous along the interpolant (no root in the bracket) the domain-side
    end is returned with converged=False: it is never past the guard. ``tol`` is raised to the
    guard's own rounding, 1e-15 of its change over the step: a finer one is met only by
    collapsing the bracket by bisection.
    """
    if g0 <= 0.0:
        return 0.0, 0, True
    tol = max(tol, 1e-15 * (g0 - g1))
    if -g1 <= tol:
        return 1.0, 0, True
    lo, hi, glo, ghi = 0.0, 1.0, g0, g1
    g_hi = g1  # the guard's value at hi (ghi is Illinois' scaled copy)
    evals = 0
    side = 0
    width = 1.0  # the bracket's width when it last halved
    stalled = 0
    for _ in range(200):
        if stalled >= _STALL:
            s = 0.5 * (lo + hi)
        else:
            s = lo + (hi - lo) * glo / (glo - ghi)
            if not (lo < s < hi):
                s = 0.5 * (lo + hi)
        if hi - lo > 2.0 * _MIN_STEP:
            if s - lo < _MIN_STEP:
                s = lo + _MIN_STEP
            elif hi - s < _MIN_STEP:
                s = hi - _MIN_STEP
        g = float(guard_at(s))
        evals += 1
        if not math.isfinite(g):
            return lo, evals, False
        if g == 0.0:
            return s, evals, True
        if g > 0:
            lo, glo = s, g
            if side == 1:
                ghi *= 0.5
            side = 1
        else:
            hi, ghi, g_hi = s, g, g
            if -g <= tol:
                return hi, evals, True
            if side == -1:
                glo *= 0.5
            side = -1
        if hi - lo <= 0.5 * width:
            width = hi - lo
            stalled = 0
        else:
            stalled += 1
        if hi - lo <= 4e-16:
            break
    # A collapsed bracket is a root up to rounding unless the guard jumps there by more than a
    # millionth of what the caller tolerates as a strip (tol is a millionth of that again).
    if hi - lo <= 4e-16 and -g_hi <= 1e6 * tol:
        return hi, evals, True
    return lo, evals, False


def simulate(
    system: HybridSystem,
    x0: Any,
    mode: str,
    t_final: float,
    h: float,
    eps: float,
    method: str | Tableau = "rk4",
    control: Callable[[float, np.ndarray], Any] | None = None,
    *,
    t0: float = 0.0,
    max_transitions: int = 100_000,
    max_halvings: int = 64,
    progress: ProgressFn | None = None,
    rtol: float | None = None,
    atol: float | None = None,
    landing: str = "halve",
) -> Execution:
    """Simulate ``system`` from ``(mode, x0)`` at time ``t0`` to ``t_final`` with the relaxed
    hybrid integrator.

    Parameters
    ----------
    system: the hybrid system.
    x0: initial state, shape (n_mode,); it must lie in the relaxed domain of ``mode``.
    mode: initial mode name.
    t_final: end time (s), > t0.
    h: nominal step size (s), > 0; each step starts from h and is halved as needed.
    eps: strip width (guard units), > 0.
    method: a Runge-Kutta method name (``euler``, ``rk2``, ``heun``, ``rk4``, ``bs32``,
        ``dopri5``) or a ``Tableau``.
    control: optional ``control(t, x) -> u``, evaluated at every stage; u is passed to the
        fields as their third argument (None without control).
    t0: start time (s).
    max_transitions: transition budget; reaching it ends the run with status
        ``max_transitions``.
    max_halvings: most halvings of one step before the run ends with ``halving_exhausted``.
    progress: optional ``progress(t, t0, t_final)`` called about five times a second.
    rtol, atol: with either given, the step size inside modes is error-controlled by the
        method's embedded pair (``bs32`` or ``dopri5``), h being the initial and largest step;
        the guards keep their relaxed treatment (a step that would leave the relaxed domain
        is shortened until it lands inside it). Without them every step starts from h.
    landing: how a step that would leave the relaxed domain is shortened: ``"halve"``
        (paper 000 Fig. 12, step 3); ``"aim"``, which retries with the step length at which
        the failed step's own interpolant reaches the middle of the strip (at most three aims,
        then halving); or ``"dense"`` (methods with a continuous extension: bs32, dopri5, a
        ``Tableau`` with ``dense``), which takes the landing step on the failed step's own
        dense output, itself a Runge-Kutta step of the interpolant's order, once the failed
        step passes the error test, so no step is retried (aiming as a fallback). All three
        accept only steps that land in the relaxed domain, so the guarantee is the same;
        aiming and dense landing need fewer trial steps when eps << h.

    Returns
    -------
    Execution
        with ``status`` one of ``finished``, ``max_transitions``, ``halving_exhausted``,
        ``non_finite``, ``reset_outside_domain`` and a message naming mode, time and state.

    Raises
    ------
    SimulationError
        for invalid arguments (h, eps, t_final, x0, mode, method, control).
    ModelError
        when the model's field, guard or reset misbehaves on the initial state.
    """
    if not isinstance(system, HybridSystem):
        raise SimulationError(f"system must be a legsim.HybridSystem, got {type(system).__name__}")
    h = _check_positive("h", h)
    eps = _check_positive("eps", eps)
    if isinstance(t0, bool) or not isinstance(t0, (int, float, np.floating, np.integer)) or not math.isfinite(t0):
        raise SimulationError(f"t0 must be a finite number, got {t0!r}")
    t0 = float(t0)
    if isinstance(t_final, bool) or not isinstance(t_final, (int, float, np.floating, np.integer)):
        raise SimulationError(f"t_final must be a number, got {type(t_final).__name__} {t_final!r}")
    t_final = float(t_final)
    if not math.isfinite(t_final) or t_final <= t0:
        raise SimulationError(f"t_final must be finite and > t0 = {t0}, got {t_final}")
    scale = max(abs(t0), abs(t_final))
    if scale + h == scale:
        raise SimulationError(
            f"h = {h:g} s is below the time resolution at t = {scale:g} s (float64 times are "
            f"{float(np.spacing(scale)):.3g} s apart there): no step could advance time; "
            f"shift t0 towards 0 or raise h")
    tableau = get_method(method)
    if control is not None and not callable(control):
        raise SimulationError(f"control must be callable control(t, x) -> u or None, got {type(control).__name__}")
    if isinstance(max_transitions, bool) or not isinstance(max_transitions, (int, np.integer)) or max_transitions < 0:
        raise SimulationError(f"max_transitions must be an integer >= 0, got {max_transitions!r}")
    if isinstance(max_halvings, bool) or not isinstance(max_halvings, (int, np.integer)) or max_halvings < 1:
        raise SimulationError(f"max_halvings must be an integer >= 1, got {max_halvings!r}")
    if not isinstance(mode, str) or mode not in _known_modes(system, mode):
        raise SimulationError(f"unknown initial mode {mode!r}; modes: {sorted(system.modes)}")
    dim = system.mode(mode).dim
    try:
        x = np.array(x0, dtype=float).reshape(-1) if np.ndim(x0) <= 1 else None
    except (TypeError, ValueError) as exc:
        raise SimulationError(f"x0 must be a numeric vector of length {dim} for mode '{mode}': {exc}") from exc
    if x is None or x.shape != (dim,):
        raise SimulationError(
            f"x0 has shape {np.shape(x0)}, expected ({dim},) for mode '{mode}' "
            f"with coordinates {system.state_names(mode)}"
        )
    if not np.all(np.isfinite(x)):
        raise SimulationError(f"x0 must be finite, got {x} in mode '{mode}'")
    try:
        u0 = None if control is None else control(t0, x)
    except LegsimError:
        raise
    except Exception as exc:
        raise SimulationError(f"control(t0, x0) failed at t0={t0}: {type(exc).__name__}: {exc}") from exc
    system.check_state(mode, x, t=t0, u=u0, label="x0")
    gvals = system.guard_values(mode, x, t0, u0)
    if gvals.size and gvals.min() < -eps:
        worst = int(np.argmin(gvals))
        raise SimulationError(
            f"x0 lies past the guard of transition {system.outgoing(mode)[worst].name} by "
            f"{-gvals[worst]:.3g} > eps = {eps:g} (guard units); start inside the domain of '{mode}'"
        )

    if landing not in LANDINGS:
        raise SimulationError(f"landing must be one of {', '.join(map(repr, LANDINGS))}, got {landing!r}")
    if landing == "dense" and dense_output(tableau) is None:
        raise SimulationError(f"landing 'dense' needs a method with a continuous extension (bs32, dopri5, or a "
                              f"Tableau with dense output); method '{tableau.name}' has none: use landing 'aim'")
    if rtol is not None or atol is not None:
        if not tableau.embedded:
            raise SimulationError(
                f"rtol/atol need a method with an embedded error estimate (bs32, dopri5), got '{tableau.name}'")
        for label, tol in (("rtol", rtol), ("atol", atol)):
            if tol is not None:
                _check_positive(label, tol)
        if rtol is None:
            rtol = 1e-3 * float(atol)
        if atol is None:
            atol = 1e-3 * float(rtol)
        rtol, atol = float(rtol), float(atol)
    integrator = _Integrator(system, tableau, h, eps, control, max_transitions, max_halvings, progress,
                             rtol, atol, landing)
    integrator._checked_modes.add(mode)  # check_state above already evaluated this mode's field
    return integrator.run(mode, x, t0, t_final)


#: Most halvings of one step for leaving the model's range (ModelBreakdown) before the run ends:
#: a long trial step through the ground needs a few; more means the boundary is at hand.
_BREAKDOWN_HALVINGS = 10

#: Landing rules of ``simulate(landing=...)``.
LANDINGS = ("halve", "aim", "dense")


def _known_modes(system: HybridSystem, mode: str):
    try:
        system.mode(mode)
    except ModelError:
        return ()
    return system.modes


class _Integrator:
    """One run's workspace: stage buffers, counters and the segment under construction.
    The HybridSystem is never modified (the Pinocchio model/data split)."""

    def __init__(self, system, tableau, h, eps, control, max_transitions, max_halvings, progress,
                 rtol=None, atol=None, landing="halve"):
        self.system = system
        self.tableau = tableau
        self.stepper = make_stepper(tableau)
        self.h = h
        self.h_prop = h
        self.eps = eps
        self.control = control
        self.max_transitions = max_transitions
        self.max_halvings = max_halvings
        self.progress = progress
        self.adaptive = rtol is not None or atol is not None
        self.rtol = 0.0 if rtol is None else rtol
        self.atol = 0.0 if atol is None else atol
        if self.adaptive:
            self.err_exponent = -1.0 / (min(tableau.order, tableau.error_order) + 1)
            self._error_norm = make_error_norm(tableau)
        self.aim = landing in ("aim", "dense")
        self.dense = landing == "dense"
        self.landing = landing
        self.t_start = 0.0
        self.steps = 0
        self.halvings = 0
        self.error_rejections = 0
        self.field_evals = 0
        self.guard_evals = 0
        self.reset_evals = 0
        self.strip_time = 0.0
        self.segments = []
        self.strips = []
        self.transitions = []
        self.state_names = {}
        self._checked_modes: set[str] = set()
        self._guard_cache: dict[str, tuple] = {}

    def _guard_fns(self, data) -> tuple[Callable[[float, np.ndarray], Any], ...]:
        """The mode's guards as g(t, x), with the control evaluated for ``t,x,u`` guards;
        built once per mode and run."""
        fns = self._guard_cache.get(data.name)
        if fns is None:
            control = self.control
            built = []
            for tr in data.transitions:
                g = tr.guard
                if tr.guard_args == "x":
                    built.append(lambda t, x, g=g: g(x))
                elif control is None:
                    built.append(lambda t, x, g=g: g(t, x, None))
                else:
                    built.append(lambda t, x, g=g: g(t, x, control(t, x)))
            fns = self._guard_cache[data.name] = tuple(built)
        return fns

    @staticmethod
    def _timed(data) -> bool:
        return any(tr.guard_args != "x" for tr in data.transitions)

    def _f(self, field, t, x):
        self.field_evals += 1
        return field(t, x, None if self.control is None else self.control(t, x))

    def run(self, mode: str, x: np.ndarray, t0: float, t_final: float) -> Execution:
        wall0 = _time.perf_counter()
        self._last_report = wall0
        self.t_start = t0
        status, message = "finished", ""
        t = t0
        final_in_strip = False
        final_pair = None
        while True:
            try:
                outcome = self._run_mode(mode, x, t, t_final)
            except ModelBreakdown as exc:  # raised while entering a mode or crossing a strip
                outcome = ("end", "model_breakdown", f"{exc} (mode '{mode}', t={t:.17g})", t, False, None)
            kind = outcome[0]
            if kind == "end":
                _, status, message, t, final_in_strip, final_pair = outcome
                break
            _, mode, x, t = outcome
        counters = {
            "steps": self.steps,
            "halvings": self.halvings,
            "error_rejections": self.error_rejections,
            "field_evals": self.field_evals,
            "guard_evals": self.guard_evals,
            "reset_evals": self.reset_evals,
            "transitions": len(self.transitions),
            "strip_time": self.strip_time,
            "wall_time_s": _time.perf_counter() - wall0,
        }
        settings = {"h": self.h, "eps": self.eps, "method": self.tableau.name, "rtol": self.rtol if self.adaptive
                    else None, "atol": self.atol if self.adaptive else None, "landing": self.landing,
                    "max_transitions": self.max_transitions, "control": self.control is not None}
        return Execution(status=status, message=message, segments=self.segments, strips=self.strips,
                         transitions=self.transitions, t0=t0, t_end=t, t_final=t_final, counters=counters,
                         settings=settings, state_names=self.state_names, system_name=self.system.name,
                         final_in_strip=final_in_strip, _final=final_pair)

    # The step loop of one mode visit. Returns ("next", mode, x, t) after a transition or
    # ("end", status, message, t, final_in_strip, final_pair). It is the hot path: locals
    # instead of attributes, storage inlined, one guard evaluated without a list when possible.
    def _run_mode(self, mode: str, x: np.ndarray, t: float, t_final: float):
        system = self.system
        data = system.mode_data(mode)
        field = data.mode.field
        guards = self._guard_fns(data)
        eps = self.eps
        h_max = self.h
        tableau = self.tableau
        step = self.stepper
        control = self.control
        fsal = tableau.fsal
        evals_per_step = tableau.stages - 1
        n_guards = len(guards)
        single_guard = guards[0] if n_guards == 1 else None
        adaptive = self.adaptive
        aim = self.aim
        dense = self.dense
        error_norm = self._error_norm if adaptive else None
        rtol, atol = self.rtol, self.atol
        dim = data.mode.dim
        self.state_names.setdefault(mode, data.mode.names)
        buf = SegmentBuffer(mode, dim)

        if mode not in self._checked_modes:
            check_field_output(system.name, mode, data.mode, t, x, None if control is None else control(t, x))
            self._checked_modes.add(mode)
        k0 = np.asarray(self._f(field, t, x), dtype=float)
        if not np.all(np.isfinite(k0)):
            buf.append(t, x, np.zeros_like(x))
            self.segments.append(buf.freeze())
            return ("end", "non_finite", f"field of mode '{mode}' is not finite at t={t:.17g}, x={x.tolist()}: "
                    f"f={k0.tolist()}", t, False, None)
        buf.append(t, x, k0)

        # A state that enters a mode already inside one of its strips (a reset image at a guard
        # intersection, or an initial state in a strip) crosses that strip at once: q = x.
        gvals = [float(g(t, x)) for g in guards]
        g_here = gvals  # guard values at the current (t, x), kept for the landing searches
        self.guard_evals += n_guards
        bad = _first_nonfinite(gvals)
        if bad is not None:
            return self._end_segment(buf, "non_finite",
                                     f"guard of transition {data.transitions[bad].name} is {gvals[bad]} "
                                     f"at t={t:.17g} in mode '{mode}', x={x.tolist()}", t)
        # A guard within rounding of zero (a constrained mode released onto the guard it lives
        # on, an identity reset between complementary guards) counts as *on* the guard, not past
        # it: the first step decides. If the flow leaves, that step lands in the strip and the
        # crossing is found at its start, at this same instant; if it goes inward, no spurious
        # transition (and no spurious eps of delay) happens.
        if n_guards and min(gvals) < -1e-9 * eps:
            e = int(np.argmin(gvals))
            if gvals[e] < -eps:
                return self._end_segment(buf, "reset_outside_domain",
                                         f"state entering mode '{mode}' at t={t:.17g} lies past the guard of "
                                         f"transition {data.transitions[e].name} by {-gvals[e]:.3g} > eps={eps:g}: "
                                         f"x={x.tolist()}", t)
            return self._transition(buf, data, e, t, x, t, -gvals[e], t_final)

        # A new mode's flow (a stance after a touchdown) may want a much shorter step than the
        # one the previous mode ended with, which was tuned to another field: start it at the
        # smaller of that and the standard starting step, as an event-driven integrator does at
        # every restart. For one field evaluation a tolerance then buys the accuracy it buys
        # solve_ivp (the pronk at rtol 1e-6: 9.6e-6 m, against 1.8e-5 carrying the step over).
        # Not after a self-transition (same field; the compiled kernel crosses those in place).
        if adaptive and self.transitions and self.transitions[-1].source != mode:
            self.h_prop = min(self.h_prop, self._starting_step(field, t, x, k0))
            if dense and n_guards:
                # Entering a mode a hair before another guard's strip (the second foot of a
                # symmetric touchdown, within rounding of the ground and moving down): the first
                # step only has to reach that strip, a tiny step; see _short_first_step.
                crossed = self._short_first_step(buf, data, guards, gvals, field, t, x, k0, t_final)
                if crossed is not None:
                    return crossed

        if data.mode.compiled is not None and control is None and not self.dense and not self._timed(data):
            from .compiled import run_mode_compiled  # numba is imported only by systems that use it

            return run_mode_compiled(self, data, buf, t, x, k0, t_final)

        # Finished once t_final is a few float spacings away (an absolute test: a relative one
        # would call a run near t = 1e15 finished before its first step).
        finish_tol = 8.0 * 2.220446049250313e-16 * abs(t_final)
        progress = self.progress
        T, X, DX, size = buf.t, buf.x, buf.dx, buf.size
        steps = halvings = rejections = field_evals = guard_evals = 0
        h_prop = self.h_prop
        outcome = None
        try:
            while True:
                remaining = t_final - t
                if remaining <= finish_tol:
                    outcome = ("finished", "", t_final if remaining > 0 else t)
                    break
                hk = h_prop if h_prop < h_max else h_max
                last = hk >= remaining
                if last:
                    hk = remaining
                shortened = aimed = broke = 0
                rejected = False
                while True:
                    # A trial step whose stages or end leave the model's range (ModelBreakdown: a
                    # runner's hip through the ground) has left the relaxed domain like one past a
                    # strip: it is shortened. Unlike a strip, the model's boundary has no width to
                    # land in, so once the boundary is within 2^-_BREAKDOWN_HALVINGS of the step
                    # the flow itself is leaving the range: the run ends there rather than creep
                    # towards the boundary by ever shorter steps.
                    try:
                        # Counted first: a trial that breaks down has made (at most) these.
                        field_evals += evals_per_step
                        x_new, stages = step(field, t, x, hk, k0, control)
                        # Exact and warning-free (a sum of squares would overflow, and warn, for
                        # finite states above ~1e154); for the small states of these models it is
                        # also the cheapest test numpy or Python offers.
                        if not all(map(isfinite, x_new.tolist())):
                            reason = "non_finite"
                        else:
                            reason = None
                            t_trial = t_final if last else t + hk
                            if single_guard is not None:
                                gmin = float(single_guard(t_trial, x_new))
                                guard_evals += 1
                            elif n_guards:
                                gvals = [float(g(t_trial, x_new)) for g in guards]
                                guard_evals += n_guards
                                gmin = min(gvals)
                                if gmin == gmin and math.isnan(sum(gvals)):
                                    gmin = math.nan  # min() keeps a nan only when it comes first
                            else:
                                gmin = 0.0
                    except ModelBreakdown as exc:
                        reason, breakdown = "model_breakdown", exc
                    if reason is None:
                        if gmin != gmin:  # a guard returned nan
                            gvals = [float(g(t_trial, x_new)) for g in guards]
                            bad = _first_nonfinite(gvals)
                            outcome = ("non_finite", f"guard of transition {data.transitions[bad].name} is nan at "
                                       f"t={t + hk:.17g} in mode '{mode}', x={x_new.tolist()}", t)
                            break
                        inside = gmin >= -eps
                        # The error test: for a step inside the relaxed domain, and for a step past
                        # a strip that is to carry the landing on its own interpolant (dense).
                        if adaptive and (inside or (dense and aimed == 0)):
                            err = error_norm(hk, stages, x, x_new, rtol, atol)
                            if err > 1.0:
                                rejections += 1
                                rejected = True
                                hk *= max(0.2, 0.9 * err ** self.err_exponent)
                                last = False
                                continue
                            proposal = hk * min(5.0, max(0.2, 0.9 * err ** self.err_exponent)) if err > 0 else 5.0 * hk
                            if rejected and proposal > hk:
                                proposal = hk  # no growth right after a rejection (Hairer, scipy)
                        if inside:
                            if adaptive:
                                # A step shortened to land in the relaxed domain says nothing about
                                # the step the error allows: its tiny error must not shrink the next
                                # proposal (after a landing the next mode would restart near eps and
                                # creep back up by 5x per step).
                                h_prop = max(h_prop, proposal) if shortened and not rejected else proposal
                            break
                        reason = "past"
                        if dense and aimed == 0:
                            try:
                                landed = self._dense_landing(guards, gvals if single_guard is None else [gmin],
                                                             g_here, field, t, x, hk, stages)
                            except ModelBreakdown:  # the interpolant left the model's range: halve
                                landed = (None, None, 0.5, None, None, 0)
                            else:
                                field_evals += landed[0].extra_evals
                            guard_evals += landed[-1]
                            if landed[1] is not None:
                                curve, theta, x_land, g_land, crossing, _ = landed
                                if adaptive:
                                    h_prop = max(h_prop, proposal) if shortened and not rejected else proposal
                                steps += 1
                                halvings += shortened + 1
                                buf.size = size
                                self._flush(steps, halvings, rejections, field_evals, guard_evals, h_prop)
                                t_land = t + theta * hk

                                def point(s, curve=curve, theta=theta):
                                    return curve.point(s * theta)

                                def slope(s, curve=curve, theta=theta):
                                    return curve.slope(s * theta)

                                return self._step_transition(buf, data, g_land, t, x, k0, t_land, x_land,
                                                             curve.slope(theta), t_final, point, slope, crossing)
                            aimed += 1  # the interpolant did not land: retry at its aim, checked as usual
                            shortened += 1
                            hk = landed[2] * hk
                            last = False
                            continue
                    shortened += 1
                    if reason == "model_breakdown":
                        broke += 1
                    hk_old = hk
                    if aim and reason == "past" and aimed < 3:
                        try:
                            hk = self._aim(guards, gvals if single_guard is None else [gmin], field, t, x, k0, hk,
                                           x_new, stages)
                        except ModelBreakdown:  # the interpolant left the model's range: halve
                            hk *= 0.5
                        aimed += 1
                    else:
                        hk *= 0.5
                    last = False
                    if shortened > self.max_halvings or t + hk <= t or broke > _BREAKDOWN_HALVINGS:
                        if reason == "non_finite":
                            outcome = ("non_finite", f"the step from t={t:.17g} in mode '{mode}' gives a non-finite "
                                       f"state even at h={hk_old:.3g}: x={x.tolist()}", t)
                        elif reason == "model_breakdown":
                            outcome = ("model_breakdown", f"{breakdown} (mode '{mode}', after t={t:.17g}: the flow "
                                       f"leaves the model's range within {hk_old:.3g} s)", t)
                        else:
                            if single_guard is None:
                                e = int(np.argmin(gvals))
                            else:
                                e = 0
                            outcome = ("halving_exhausted",
                                       f"no step from t={t:.17g} in mode '{mode}' lands in the relaxed domain after "
                                       f"{shortened - 1} halvings: the flow leaves through the guard of transition "
                                       f"{data.transitions[e].name} without entering its strip (x={x.tolist()})"
                                       + _resolution_hint(eps, x), t)
                        break
                halvings += shortened
                if outcome is not None:
                    break
                t_new = t_final if last else t + hk
                steps += 1
                if n_guards and gmin < 0.0:
                    if single_guard is not None:
                        gvals = [gmin]
                    k1 = stages[-1] if fsal else field(t_new, x_new, None if control is None else control(t_new, x_new))
                    if not fsal:
                        field_evals += 1
                    buf.size = size
                    self._flush(steps, halvings, rejections, field_evals, guard_evals, h_prop)
                    return self._step_transition(buf, data, gvals, t, x, k0, t_new, x_new, np.asarray(k1, dtype=float),
                                                 t_final)
                t = t_new
                x = x_new
                if dense:
                    g_here = gvals if single_guard is None else [gmin]
                if fsal:
                    k0 = stages[-1]
                else:
                    k0 = field(t, x, None if control is None else control(t, x))
                    field_evals += 1
                if size == len(T):
                    buf.size = size
                    buf.append(t, x, k0)
                    T, X, DX, size = buf.t, buf.x, buf.dx, buf.size
                else:
                    T[size] = t
                    X[size] = x
                    DX[size] = k0
                    size += 1
                if progress is not None and (steps & 63) == 0:
                    now = _time.perf_counter()
                    if now - self._last_report > 0.2:
                        self._last_report = now
                        progress(t, self.t_start, t_final)
        except ModelBreakdown as exc:
            outcome = ("model_breakdown", f"{exc} (mode '{mode}', after t={t:.17g})", t)
        except LegsimError:
            raise
        except Exception as exc:
            # A model's callable failed mid-run: name where, rather than leak a numpy traceback.
            raise ModelError(f"{system.name}: evaluating mode '{mode}' failed in the step from t={t:.17g} "
                             f"(x={x.tolist()}): {type(exc).__name__}: {exc}") from exc
        buf.size = size
        self._flush(steps, halvings, rejections, field_evals, guard_evals, h_prop)
        status, message, t_end = outcome
        return self._end_segment(buf, status, message, t_end)

    def _flush(self, steps, halvings, rejections, field_evals, guard_evals, h_prop) -> None:
        self.steps += steps
        self.halvings += halvings
        self.error_rejections += rejections
        self.field_evals += field_evals
        self.guard_evals += guard_evals
        self.h_prop = h_prop

    def _short_first_step(self, buf, data, guards, gvals, field, t: float, x: np.ndarray, k0: np.ndarray,
                          t_final: float):
        """The first step of a newly entered mode when the flow reaches the middle of some
        guard's strip within a thousandth of the step it would take (a simultaneous event):
        a step of exactly that length by Heun's method, whose Euler estimate must pass the error
        test (its local error is O(tau^3), tau ~ eps / speed). It is an ordinary relaxed step:
        accepted only if it lands in the relaxed domain, the crossing then found on its own
        quadratic interpolant. One field evaluation instead of a full step of the pair (12 for
        DOP853, and the same for the mode's neighbours in the initial state, so the execution
        stays continuous in it). Returns the transition's outcome, or None to step as usual.
        Guards leading straight back to the mode just left are not considered (complementary
        guards: a shallow graze must be stepped over, not crossed back and forth)."""
        eps = self.eps
        h_next = min(self.h_prop, self.h)
        came_from = self.transitions[-1].source
        speed = float(np.sqrt(np.dot(k0, k0)))
        if not (math.isfinite(speed) and speed > 0.0):
            return None
        dt = 1e-7 / max(1.0, speed)
        tau = None
        for e, g in enumerate(gvals):
            if data.targets[e] == came_from or not 0.0 <= g <= eps:
                continue
            try:
                g_ahead = float(guards[e](t + dt, x + dt * k0))
            except Exception:  # the ordinary first step will meet it and report it properly
                continue
            self.guard_evals += 1
            rate = (g_ahead - g) / dt
            if not rate < 0.0:
                continue
            reach = (g + 0.5 * eps) / -rate
            if reach <= 1e-3 * h_next and (tau is None or reach < tau):
                tau = reach
        if tau is None or not t + tau > t or t + tau >= t_final:
            return None  # (a strip reached only after t_final is for the ordinary last step)
        try:
            k1 = np.asarray(self._f(field, t + tau, x + tau * k0), dtype=float)
            x1 = x + (0.5 * tau) * (k0 + k1)
            scale = self.atol + self.rtol * np.maximum(np.abs(x), np.abs(x1))
            err = _rms((0.5 * tau) * (k1 - k0) / scale)
            if not err <= 1.0:
                return None
            g1 = [float(g(t + tau, x1)) for g in guards]
        except Exception:  # the ordinary first step will meet it and report it properly
            return None
        self.guard_evals += len(guards)
        lowest = min(g1)
        if not (all(map(isfinite, g1)) and -eps <= lowest < 0.0 and all(map(isfinite, x1.tolist()))):
            return None
        self.steps += 1

        def point(s):
            return x + tau * (s * k0 + (0.5 * s * s) * (k1 - k0))

        def slope(s):
            return k0 + s * (k1 - k0)

        return self._step_transition(buf, data, g1, t, x, k0, t + tau, x1, k1, t_final, point, slope)

    def _starting_step(self, field, t: float, x: np.ndarray, k0: np.ndarray) -> float:
        """The starting step size of Hairer, Norsett and Wanner (Solving ODEs I, Sec. II.4): a step
        whose estimated local error is about 1% of the tolerance, from f at x and at one explicit
        Euler step away (one field evaluation). On any failure the current proposal stands."""
        scale = self.atol + self.rtol * np.abs(x)
        d0 = _rms(x / scale)
        d1 = _rms(k0 / scale)
        h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
        h0 = min(h0, self.h)
        try:
            x1 = x + h0 * k0
            f1 = np.asarray(self._f(field, t + h0, x1), dtype=float)
        except Exception:
            return self.h_prop  # the steps themselves will meet it and report it properly
        d2 = _rms((f1 - k0) / scale) / h0
        if not math.isfinite(d2):
            return self.h_prop
        worst = max(d1, d2)
        h1 = max(1e-6, 1e-3 * h0) if worst <= 1e-15 else (0.01 / worst) ** -self.err_exponent
        return min(100.0 * h0, h1)

    def _dense_landing(self, guards, gvals, g_start, field, t, x, hk, stages):
        """Land on the failed step's own dense output. The crossing q is found on it first (the
        earliest guard to reach zero), then the landing point, in the middle of that guard's
        strip, by secant from q (the guard is nearly linear across a strip, so one guess
        usually lands). Returns ``(curve, theta, x_land, guards_at_landing, crossing, evals)``
        with crossing = (guard index, s of q on [t, t + theta hk], converged); theta is None
        when no point of the interpolant was found in the relaxed domain (a guard that turns
        back within the strip, or a second guard deeper than eps there): the caller retries a
        real step of theta hk, with theta then the best guess."""
        curve = ContinuousStep(self.tableau, field, t, x, hk, stages, self.control)
        eps = self.eps
        evals = 0
        best = None
        for e, g1 in enumerate(gvals):
            if g1 < 0.0:
                guard = guards[e]

                def guard_at(s, guard=guard):
                    return float(guard(t + s * hk, curve.point(s)))

                # q to a 1e-12 share of the strip, as in _step_transition.
                s, n_evals, converged = crossing_on_step(guard_at, g_start[e], g1, 1e-12 * eps)
                evals += n_evals
                if best is None or s < best[1]:
                    best = (e, s, converged, g1)
        e, s_q, converged, g1 = best
        guard = guards[e]
        half = 0.5 * eps

        def past_middle(theta):  # the guard plus eps/2 at theta: 0 in the middle of the strip
            return float(guard(t + theta * hk, curve.point(theta))) + half

        # The middle of the strip, by the secant from q (g = 0) to the step's end (g1 < -eps).
        theta = s_q + half * (1.0 - s_q) / -g1
        gap = past_middle(theta)
        evals += 1
        if not abs(gap) <= 0.5 * half:
            # Outside the strip's middle half: a guard with a kink (the oscillator's
            # max(x_max - x, -xd) while the mass sticks) fools the secant, and a landing at the
            # strip's edge, valid but shallow, would hold the state for almost no time, so a
            # chattering contact would take ~1e5 times more transitions. Search for the middle.
            def on_rest(u):
                return past_middle(s_q + u * (1.0 - s_q))

            u, n_evals, _ = crossing_on_step(on_rest, half, g1 + half, 0.5 * half)
            evals += n_evals
            theta = s_q + u * (1.0 - s_q)
        if s_q <= theta < 1.0:
            x_land = curve.point(theta)
            t_land = t + theta * hk
            g_land = [float(g(t_land, x_land)) for g in guards]
            evals += len(guards)
            # In the relaxed domain, every guard finite (min() skips a nan that is not first),
            # and the crossed guard itself in its strip (its depth is the landing's tau).
            if (all(map(isfinite, g_land)) and -eps <= min(g_land) and g_land[e] < 0.0
                    and all(map(isfinite, x_land.tolist()))):
                return curve, theta, x_land, g_land, (e, s_q / theta if theta > 0.0 else 0.0, converged), evals
        # Not in the relaxed domain there (another guard deeper than eps, a guard turning back):
        # a real step of that length decides.
        return curve, None, min(max(theta, s_q), 1.0) if s_q > 0.0 else 0.5, None, None, evals

    def _aim(self, guards, gvals, field, t, x, k0, hk, x_new, stages) -> float:
        """A shorter step aimed at the middle of the deepest strip, found on the failed step's
        own Hermite interpolant. The retried step is checked like any other, so the
        guarantee of halving (never accept a state past the strip) is kept."""
        e = int(np.argmin(gvals))
        guard = guards[e]
        if self.tableau.fsal:
            k1 = stages[-1]
        else:
            k1 = np.asarray(self._f(field, t + hk, x_new), dtype=float)
        half = 0.5 * self.eps
        g0 = float(guard(t, x)) + half
        self.guard_evals += 1

        def shifted(s):  # root of g = -eps/2 on the failed step's interpolant
            return float(guard(t + s * hk, hermite(x, k0, x_new, k1, hk, s))) + half

        s, n_evals, converged = crossing_on_step(shifted, g0, gvals[e] + half, 1e-3 * half)
        self.guard_evals += n_evals
        if not converged or not (0.0 < s < 1.0):
            return 0.5 * hk
        return s * hk

    def _end_segment(self, buf: SegmentBuffer, status: str, message: str, t: float):
        self.segments.append(buf.freeze())
        return ("end", status, message, t, False, None)

    def _step_transition(self, buf, data, gvals, t, x, k0, t1, x1, k1, t_final, point=None, slope=None,
                         crossing=None):
        """A step from (t, x) landed at (t1, x1) inside one or more strips. ``point(s)`` and
        ``slope(s)`` give the step's own interpolant at t + s (t1 - t) (default: cubic Hermite);
        ``crossing`` = (guard index, s, converged) when the caller has already found q."""
        dt = t1 - t
        if point is None:
            def point(s):
                return hermite(x, k0, x1, k1, dt, s)

            def slope(s):
                return hermite_derivative(x, k0, x1, k1, dt, s)
        # Locating q costs guard evaluations only: take it to a 1e-12 share of the strip.
        tol = 1e-12 * self.eps
        best = crossing
        guard_fns = self._guard_fns(data)
        for e, g1 in enumerate(gvals if crossing is None else ()):
            if g1 < 0.0:
                guard = guard_fns[e]
                g0 = float(guard(t, x))

                def guard_at(s, guard=guard):
                    return guard(t + s * dt, point(s))

                s, n_evals, converged = crossing_on_step(guard_at, g0, g1, tol)
                self.guard_evals += 1 + n_evals
                if best is None or s < best[1]:
                    best = (e, s, converged)
        e, s, converged = best
        if s <= 0.0:
            q, tc = x.copy(), t
        else:
            q = point(s)
            tc = t + s * dt
            if not np.all(np.isfinite(q)):
                q, tc = x.copy(), t
            elif tc <= t:
                # s so small that t + s dt rounds to t: q replaces the step's start (they differ by
                # rounding) rather than adding a second point at the same time.
                buf.x[buf.size - 1] = q
                buf.dx[buf.size - 1] = slope(s)
                tc = t
            else:
                buf.append(tc, q, slope(s))
        tau = -gvals[e]
        return self._transition(buf, data, e, tc, q, t1, tau, t_final)

    def _transition(self, buf, data, e, tc, q, t_land, tau, t_final):
        """Cross the strip of transition e: hold q from tc to t_land + eps - tau, then reset."""
        tr = data.transitions[e]
        mode = data.name
        self.segments.append(buf.freeze())
        if len(self.transitions) >= self.max_transitions:
            self.strips.append(Strip(mode, tr.name, tc, tc, q.copy(), t_land, tau))
            return ("end", "max_transitions",
                    f"transition budget max_transitions={self.max_transitions} used up at t={tc:.17g} "
                    f"(next transition {tr.name} from mode '{mode}')", tc, True, None)
        exit_time = t_land + (self.eps - tau)
        if exit_time >= t_final:
            self.strips.append(Strip(mode, tr.name, tc, t_final, q.copy(), t_land, tau))
            self.strip_time += t_final - tc
            return ("end", "finished", "", t_final, True, None)
        target = data.targets[e]
        self.reset_evals += 1
        try:
            x_after = np.asarray(data.resets[e](q), dtype=float)
        except ModelBreakdown as exc:
            # Ends the run here: the segment is already stored and the counters flushed (the
            # step loop's own handler would store them a second time).
            return ("end", "model_breakdown", f"{exc} (reset of transition {tr.name} from mode '{mode}', "
                    f"t={tc:.17g})", tc, False, None)
        except Exception as exc:
            raise ModelError(f"{self.system.name}: reset of transition {tr.name} failed at t={tc:.17g}, "
                             f"q={q.tolist()}: {type(exc).__name__}: {exc}") from exc
        target_dim = self.system.mode(target).dim
        if x_after.shape != (target_dim,):
            check_reset_output(self.system.name, tr, target_dim, q)  # raises with the shapes named
        self.strips.append(Strip(mode, tr.name, tc, exit_time, q.copy(), t_land, tau))
        self.strip_time += exit_time - tc
        self.transitions.append(TransitionRecord(tr.name, mode, target, e, tc, t_land, exit_time, q.copy(),
                                                 x_after.copy(), tau))
        if not np.all(np.isfinite(x_after)):
            seg = SegmentBuffer(target, target_dim, capacity=1)
            seg.append(exit_time, x_after, np.zeros(target_dim))
            self.segments.append(seg.freeze())
            return ("end", "non_finite", f"reset of transition {tr.name} at t={exit_time:.17g} gives a non-finite "
                    f"state {x_after.tolist()} from q={q.tolist()}", exit_time, False, None)
        return ("next", target, x_after, exit_time)


def _resolution_hint(eps: float, x: np.ndarray) -> str:
    """A second explanation when eps is too thin for float64 near x: no step can land inside it."""
    spacing = float(np.spacing(1.0 + float(np.max(np.abs(x)))))
    if eps < 1e3 * spacing:
        return f"; or eps = {eps:g} is thinner than float64 can resolve near this state (spacing {spacing:.3g}): raise eps"
    return ""


def _rms(v: np.ndarray) -> float:
    """Root mean square of a scaled vector (the error norms of Hairer's codes)."""
    return math.sqrt(float(np.dot(v, v)) / len(v))


def _first_nonfinite(values) -> int | None:
    for i, v in enumerate(values):
        if not math.isfinite(v):
            return i
    return None
