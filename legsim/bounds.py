"""Global error bounds around computed trajectories (paper 004, Section III).

For one mode visit (one initial value problem) computed at the points ``(t_n, x_n)``, the
local error of step n is ``error_n = x^[n](t_{n+1}) - x_{n+1}``, where ``x^[n]`` is the exact
solution through ``x_n``. Paper 004 turns local errors into a global bound,

    B(t_n) = ||error_n|| + sum_{i<n} ||error_i|| exp(L (t_n - t_i)),

with L a Lipschitz constant of the field, estimated as the largest singular value of the
field's Jacobian at the computed points: ``L = max_n sigma_max(Df(x_n))``. Between points B
is interpolated linearly, like the trajectory itself.

Local errors come from an embedded Runge-Kutta pair (``bs32`` or ``dopri5``): a step of the
pair from ``x_n`` over ``h_n`` gives its propagated solution ``x_hi`` and the estimate
``est_n = h_n sum_j b_err_j k_j ~ x_hi - x_lo``. We take

    ||error_n|| ~ ||x_{n+1} - x_hi|| + ||est_n|| (+ floor * h_n^(p+1)),

the triangle inequality with ``||x_true - x_hi|| <= ||est_n||`` (the estimate measures the
error of the pair's lower-order member, which exceeds that of x_hi). When the trajectory was
computed by the pair itself the first term vanishes except at the interpolated strip point
that ends a segment, whose interpolation error it then measures. The optional ``floor`` adds
a declared local error ``floor * h^(p+1)`` (p the order of the computing method), standing for
the local tolerance an adaptive solver would have used for step h (paper 004 uses Matlab's
``Rtol ||x_n|| + Atol`` in its simulations); it matters for fields on which every
Runge-Kutta method is exact (constant fields, such as the two tanks), where the estimates
vanish and the bound would be zero.

``ModeFlow`` steps one mode with a fixed step, ignoring the guards (the numerical solution
flows on past them, as the stochastic approximation of Section IV and the error cone of
Section V need), and carries the bound along with the signed distances to the mode's guards.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import minimize_scalar
from scipy.special import betainc

from .derivatives import gradient, jacobian
from .errors import ModelBreakdown, SimulationError
from .execution import Execution
from .hybrid import HybridSystem, Mode, Transition
from .methods import Tableau, get_method
from .relaxed.single import Stepper, hermite

ControlFn = Callable[[float, np.ndarray], Any]

#: Most fixed steps one flow may be asked to take (certification level, stochastic execution).
#: A ModeFlow advances a few thousand steps per second, so this is already about ten minutes of work:
#: a request beyond it is a typo (h = 1e-12, t_final = 1e9) rather than a computation to start.
MAX_STEPS = 2_000_000


def _norm(v: np.ndarray) -> float:
    """Euclidean norm of a vector (np.linalg.norm's generality costs more than the arithmetic
    on the small vectors of a step)."""
    return math.sqrt(float(np.dot(v, v)))


def _finite(v: np.ndarray) -> bool:
    # The sum of an array is finite only when every entry is (inf and nan propagate).
    return math.isfinite(v.sum())


# -- derivatives ------------------------------------------------------------------------------
def field_jacobian(mode: Mode, t: float, x: np.ndarray, u: Any = None) -> np.ndarray:
    """Df/dx at (t, x), shape (n, n): the mode's own ``jacobian`` when it has one, central
    finite differences otherwise."""
    if mode.jacobian is not None:
        J = np.asarray(mode.jacobian(t, x, u), dtype=float)
        if J.shape != (mode.dim, mode.dim):
            raise SimulationError(f"jacobian of a mode with dim {mode.dim} returned shape {J.shape}")
        return J
    return jacobian(lambda y: mode.field(t, y, u), x)


def lipschitz_estimate(mode: Mode, t: float, x: np.ndarray, u: Any = None) -> float:
    """sigma_max(Df(t, x)): the largest singular value of the field's Jacobian (1/s)."""
    J = field_jacobian(mode, t, x, u)
    if not _finite(J):
        return math.inf
    if not J.any():
        return 0.0
    return float(np.linalg.svd(J, compute_uv=False)[0])


def guard_gradient(transition: Transition, x: np.ndarray, t: float = 0.0, u: Any = None) -> np.ndarray:
    """Gradient in x of the transition's guard at x, shape (n,): its ``guard_gradient`` when
    given, central finite differences otherwise (t and u matter for ``guard_args="t,x,u"``)."""
    if transition.guard_gradient is not None:
        return np.asarray(transition.guard_gradient(x), dtype=float).reshape(-1)
    return gradient(lambda y: transition.guard_value(y, t, u), x)


def reset_lipschitz(transition: Transition, x: np.ndarray, target_dim: int) -> float:
    """sigma_max of the reset's Jacobian at x (how much the reset can stretch a ball), the
    Jacobian of shape (target_dim, n): ``reset_jacobian`` when given, central differences
    otherwise; 1 for the identity."""
    if transition.reset_jacobian is not None:
        J = np.asarray(transition.reset_jacobian(x), dtype=float)
    elif transition.reset is None:
        return 1.0
    else:
        J = jacobian(transition.reset, x).reshape(target_dim, len(x))
    if not _finite(J):
        return math.inf
    return float(np.linalg.svd(J, compute_uv=False)[0])


def signed_distance(transition: Transition, x: np.ndarray, t: float = 0.0, u: Any = None) -> float:
    """Distance from x to the guard ``g = 0`` through the guard linearised at x:
    ``g(x) / |grad g(x)|``, positive inside the domain, negative past the guard (exact for
    hyperplane guards). A zero gradient gives +-inf (no crossing can be predicted there).
    t and u matter only for guards declared with ``guard_args="t,x,u"``."""
    g = transition.guard_value(x, t, u)
    norm = _norm(guard_gradient(transition, x, t, u))
    if norm == 0.0 or not math.isfinite(norm):
        return math.inf if g >= 0 else -math.inf
    return g / norm


# -- the n-ball past a hyperplane -----------------------------------------------------------
def ball_fraction_past(distance: float | np.ndarray, radius: float | np.ndarray, dim: int) -> np.ndarray:
    """Fraction of the volume of a ``dim``-ball lying past a hyperplane.

    ``distance`` is the signed distance from the ball's centre to the plane (positive on the
    domain side), ``radius`` the ball's radius (same units). The cap beyond a plane at
    distance d >= 0 from the centre is, as a fraction of the ball,
    ``I_{1 - (d/r)^2}((dim + 1) / 2, 1 / 2) / 2`` (regularised incomplete beta function); by
    symmetry a centre past the plane (d < 0) leaves ``1 -`` that. A zero radius gives 0 on
    the domain side (d >= 0) and 1 past it. Returns an array of the broadcast shape.
    """
    if isinstance(dim, bool) or int(dim) != dim or dim < 1:
        raise SimulationError(f"ball dimension must be a positive integer, got {dim!r}")
    d = np.asarray(distance, dtype=float)
    # u = d / r, +-inf for a point ball; |u| >= 1 clips the beta argument to 0 and the cap to 0.
    if np.ndim(radius) == 0 and float(radius) > 0.0:
        u = d / float(radius)
    else:
        r = np.asarray(radius, dtype=float)
        if d.shape != r.shape:
            d, r = np.broadcast_arrays(d, r)
        u = np.divide(d, r, out=np.where(d >= 0.0, np.inf, -np.inf), where=r > 0.0)
    cap = 0.5 * betainc(0.5 * (dim + 1), 0.5, np.clip(1.0 - u * u, 0.0, 1.0))
    return np.where(u >= 0.0, cap, 1.0 - cap)


# -- accumulating local errors ----------------------------------------------------------------
def accumulate_bound(times: np.ndarray, local_errors: np.ndarray, lipschitz: float, b0: float = 0.0) -> np.ndarray:
    """Paper 004's global bound at the points: ``B_n = le_n + sum_{i<n} le_i e^{L (t_n - t_i)}``
    plus ``b0 e^{L (t_n - t_0)}`` for an initial uncertainty b0. Shapes (k,) in, (k,) out."""
    t = np.asarray(times, dtype=float)
    le = np.asarray(local_errors, dtype=float)
    out = np.empty_like(le)
    s = float(b0)
    for n in range(len(t)):
        out[n] = s + le[n]
        if n + 1 < len(t):
            # The recursion S_{n+1} = (S_n + le_n) e^{L h_n} is the sum in closed form without
            # the overflow of e^{L t_n} e^{-L t_i} for large L t.
            s = (s + le[n]) * math.exp(lipschitz * (t[n + 1] - t[n]))
    return out


class LocalErrorEstimator:
    """Local error of steps of a computing ``method``, estimated with an embedded ``pair``.

    ``estimate(field, t, x, h, k0, control, x_next)`` returns ``(x_hi, le)``: the pair's
    propagated solution from (t, x) over h and the estimate
    ``||x_next - x_hi|| + ||est|| + floor * h^(p+1)`` of ``||x^[n](t + h) - x_next||``.
    """

    def __init__(self, method: str | Tableau, pair: str | Tableau | None = None, floor: float = 0.0) -> None:
        self.method = get_method(method)
        if pair is None:
            pair = self.method if self.method.embedded else "dopri5"
        self.pair = get_method(pair)
        if not self.pair.embedded:
            raise SimulationError(
                f"error pair '{self.pair.name}' has no embedded error estimate; use 'bs32', 'dopri5' or 'dop853'"
            )
        floor = float(floor)
        if not math.isfinite(floor) or floor < 0.0:
            raise SimulationError(f"error floor must be finite and >= 0, got {floor}")
        self.floor = floor
        self.same = self.pair is self.method
        self._pair = Stepper(self.pair)
        self._pair_step = self._pair.step
        self._method_step = self._pair_step if self.same else Stepper(self.method).step
        self._power = self.method.order + 1

    def step(
        self, field: Callable, t: float, x: np.ndarray, h: float, k0: np.ndarray, control: ControlFn | None
    ) -> tuple[np.ndarray, float]:
        """One step of the computing method from (t, x) and the estimate of its local error."""
        x_hi, stages = self._pair_step(field, t, x, h, k0, control)
        le = _norm(self._pair.error_estimate(h, stages))
        if self.same:
            x_new = x_hi
        else:
            x_new, _ = self._method_step(field, t, x, h, k0, control)
            le += _norm(x_new - x_hi)
        return x_new, le + self.floor * h**self._power

    def pair_solution(
        self, field: Callable, t: float, x: np.ndarray, h: float, k0: np.ndarray, control: ControlFn | None
    ) -> np.ndarray:
        """The pair's propagated solution from (t, x) over h (a reference for interpolants)."""
        return self._pair_step(field, t, x, h, k0, control)[0]

    def estimate(
        self,
        field: Callable,
        t: float,
        x: np.ndarray,
        h: float,
        k0: np.ndarray,
        control: ControlFn | None,
        x_next: np.ndarray,
    ) -> float:
        """Local error estimate of a given step (t, x) -> (t + h, x_next)."""
        x_hi, stages = self._pair_step(field, t, x, h, k0, control)
        le = _norm(self._pair.error_estimate(h, stages))
        le += _norm(x_next - x_hi)
        return le + self.floor * h**self._power


# -- the bound along a computed execution -----------------------------------------------------
@dataclass(frozen=True)
class SegmentBound:
    """The bound along one mode visit of an execution.

    Attributes
    ----------
    mode: mode name.
    t: times (k,), s; x: computed states (k, n).
    local_error: estimated local error of the step leaving each point (k,); 0 at the last.
    sigma: sigma_max(Df) at each point (k,), 1/s.
    lipschitz: the constant L used (max of sigma, or the value given).
    bound: B(t_n) (k,), in state units (Euclidean norm).
    """

    mode: str
    t: np.ndarray
    x: np.ndarray
    local_error: np.ndarray
    sigma: np.ndarray
    lipschitz: float
    bound: np.ndarray

    def radius(self, times: float | np.ndarray) -> np.ndarray:
        """B at ``times`` by linear interpolation between the points."""
        return np.interp(np.asarray(times, dtype=float), self.t, self.bound)


@dataclass(frozen=True)
class ErrorBound:
    """Global error bounds along an execution, one ``SegmentBound`` per mode visit (each
    visit is its own initial value problem, so its bound starts from its own local errors)."""

    segments: tuple[SegmentBound, ...]
    method: str
    pair: str
    floor: float
    settings: dict[str, Any] = field(default_factory=dict)

    @property
    def max_bound(self) -> float:
        """Largest B over the execution."""
        return max((float(s.bound.max()) for s in self.segments if len(s.bound)), default=0.0)

    def radius_at(self, t: float) -> float:
        """B at time t in the visit containing it (the later visit at a shared boundary)."""
        for seg in reversed(self.segments):
            if seg.t[0] <= t <= seg.t[-1]:
                return float(seg.radius(t))
        raise SimulationError(
            f"time {t} is outside the bounded execution [{self.segments[0].t[0]}, {self.segments[-1].t[-1]}]"
        )

    def summary(self) -> dict[str, Any]:
        """JSON-ready summary: per visit the mode, time span, L and the largest bound."""
        return {
            "method": self.method,
            "pair": self.pair,
            "floor": self.floor,
            "max_bound": self.max_bound,
            "visits": [
                {
                    "mode": s.mode,
                    "t_start": float(s.t[0]),
                    "t_end": float(s.t[-1]),
                    "lipschitz": s.lipschitz,
                    "max_bound": float(s.bound.max()),
                    "final_bound": float(s.bound[-1]),
                }
                for s in self.segments
            ],
        }


def error_bound(
    execution: Execution,
    system: HybridSystem,
    *,
    pair: str | Tableau | None = None,
    control: ControlFn | None = None,
    floor: float = 0.0,
    lipschitz: float | str = "max",
) -> ErrorBound:
    """The global error bound of paper 004 Section III along every mode visit of ``execution``.

    Parameters
    ----------
    execution: a computed execution of ``system`` (any method, fixed or adaptive steps).
    system: the hybrid system it was computed for.
    pair: embedded pair for the local error estimates (``bs32`` or ``dopri5``); default the
        execution's own method when it is embedded, else ``dopri5``.
    control: the control the execution was computed with (the scene's ``model.control``).
    floor: declared local error floor coefficient (state units / s^(p+1)); see the module.
    lipschitz: ``"max"`` (paper 004: the largest sigma_max(Df) over the visit's points) or a
        number (1/s) to use instead.

    Returns
    -------
    ErrorBound with one SegmentBound per segment of the execution.
    """
    if not isinstance(execution, Execution):
        raise SimulationError(f"error_bound needs a legsim.Execution, got {type(execution).__name__}")
    if not isinstance(system, HybridSystem):
        raise SimulationError(f"error_bound needs a legsim.HybridSystem, got {type(system).__name__}")
    fixed_l: float | None = None
    if isinstance(lipschitz, str):
        if lipschitz != "max":
            raise SimulationError(f"lipschitz must be 'max' or a number >= 0, got {lipschitz!r}")
    else:
        fixed_l = float(lipschitz)
        if not math.isfinite(fixed_l) or fixed_l < 0.0:
            raise SimulationError(f"lipschitz must be 'max' or a finite number >= 0, got {lipschitz!r}")
    method = execution.settings.get("method", "rk4")
    estimator = LocalErrorEstimator(method, pair, floor)
    out: list[SegmentBound] = []
    for seg in execution.segments:
        mode = system.mode(seg.mode)
        fieldfn = mode.field
        k = len(seg.t)
        le = np.zeros(k)
        sigma = np.empty(k)
        for n in range(k):
            t, x = float(seg.t[n]), seg.x[n]
            u = None if control is None else control(t, x)
            sigma[n] = lipschitz_estimate(mode, t, x, u)
            if n + 1 < k:
                hn = float(seg.t[n + 1] - t)
                k0 = np.asarray(fieldfn(t, x, u), dtype=float)
                le[n] = estimator.estimate(fieldfn, t, x, hn, k0, control, seg.x[n + 1])
        L = fixed_l if fixed_l is not None else float(sigma.max())
        out.append(SegmentBound(seg.mode, seg.t.copy(), seg.x.copy(), le, sigma, L, accumulate_bound(seg.t, le, L)))
    return ErrorBound(
        tuple(out),
        estimator.method.name,
        estimator.pair.name,
        estimator.floor,
        {"lipschitz": lipschitz if fixed_l is None else fixed_l},
    )


# -- a mode's numerical flow, past its guards, with the bound ---------------------------------
@dataclass(frozen=True)
class FlowPoint:
    """One point of a ``ModeFlow``: time (s), state (n,), field there (n,), bound B (state
    units) and, per outgoing transition of the mode, the guard value and the signed distance
    to the linearised guard (positive inside)."""

    t: float
    x: np.ndarray
    f: np.ndarray
    radius: float
    guard: np.ndarray
    distance: np.ndarray


@dataclass(frozen=True)
class StepSamples:
    """A step of a ``ModeFlow`` seen at sample fractions ``s`` (K,) of its length, from 0 to 1:
    times t (K,), states x (K, n) on the cubic Hermite interpolant, radius (K,) (linear),
    guard values and signed distances (K, m). Between consecutive samples each guard's
    distance-to-radius ratio is monotone (the samples include its interior extrema), so the
    fraction of the ball past each guard is monotone there too."""

    s: np.ndarray
    t: np.ndarray
    x: np.ndarray
    radius: np.ndarray
    guard: np.ndarray
    distance: np.ndarray


class ModeFlow:
    """The fixed-step numerical solution of one mode from ``(t0, x0)`` with the bound of
    Section III around it, computed lazily point by point.

    The guards do not stop the flow: the state flows on past them (the domains of the
    stochastic approximation are all of R^n, and the error cone of Section V is followed
    until it has left the domain). Between points the trajectory is the cubic Hermite
    interpolant of the points and the fields there (legsim's dense output) rather than the
    paper's chord: a chord strays O(h^2) from the solution, far outside the O(h^p) bound of a
    higher-order method, so near a tangency the ball around a chord would miss the true
    solution. The interpolant's own error is estimated at each step's midpoint against a half
    step of the embedded pair and added to the step's local error, so the ball covers the whole
    interpolated trajectory, not only its points.

    The bound uses the running maximum of sigma_max(Df) as the Lipschitz constant (the
    paper's maximum over the points seen so far), so that points can be produced before the
    end of the flow is known; ``b0`` is an initial uncertainty radius, carried as
    ``b0 e^{L (t - t0)}``. ``progress(t)``, when given, is called every 256 points.

    ``status`` ends as ``end`` (t_end reached), ``non_finite`` (a field or step that is not
    finite), ``bound_overflow`` (B overflowed: the flow stops at its last finite ball),
    ``model_breakdown`` (a model function raised ``ModelBreakdown``, e.g. a runner's hip through
    the ground once it flows on past a touchdown) or ``max_points``; ``message`` says where.
    """

    SAMPLES_PER_ACTIVE_STEP = 8
    #: Fraction of a step between its ends and the probes that find extrema next to them; an
    #: extremum closer to an end than this is within ~probe^2 of the end's own value.
    EDGE_PROBE = 1e-6

    def __init__(
        self,
        system: HybridSystem,
        mode: str,
        x0: np.ndarray,
        t0: float,
        h: float,
        estimator: LocalErrorEstimator,
        *,
        control: ControlFn | None = None,
        b0: float = 0.0,
        t_end: float = math.inf,
        max_points: int = 10_000_000,
        progress: Callable[[float], None] | None = None,
    ) -> None:
        self.system = system
        self.mode_name = mode
        self.mode = system.mode(mode)
        self.transitions: tuple[Transition, ...] = system.outgoing(mode)
        self._timed_guards = any(tr.guard_args != "x" for tr in self.transitions)
        self.h = float(h)
        self.estimator = estimator
        self.control = control
        self.t_end = float(t_end)
        self.max_points = int(max_points)
        self.progress = progress
        self.points: list[FlowPoint] = []
        self.status = "running"
        self.message = ""
        self.t0 = float(t0)
        self._t = float(t0)
        self._x = np.array(x0, dtype=float)
        self._f: np.ndarray | None = None
        self._s = float(b0)
        self._L = 0.0
        self._done = False

    @property
    def dim(self) -> int:
        return self.mode.dim

    def field_at(self, t: float, x: np.ndarray) -> np.ndarray:
        """The mode's field at (t, x) with the control applied, shape (n,)."""
        u = None if self.control is None else self.control(t, x)
        return np.asarray(self.mode.field(t, x, u), dtype=float)

    def guards_at(self, x: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Guard values and linearised signed distances (m,) of the mode's transitions at (t, x)."""
        u = None
        if self.control is not None and self._timed_guards:
            u = self.control(t, x)
        g = np.array([tr.guard_value(x, t, u) for tr in self.transitions])
        d = np.array([signed_distance(tr, x, t, u) for tr in self.transitions])
        return g, d

    def on_step(self, n: int, s: float) -> tuple[float, np.ndarray, float, np.ndarray, np.ndarray]:
        """(t, x, B, guard values, signed distances) at fraction s of step n (points n and n + 1
        must exist): the Hermite interpolant, the bound interpolated linearly."""
        p0, p1 = self.points[n], self.points[n + 1]
        t = p0.t + s * (p1.t - p0.t)
        x = self.state(n, s)
        g, d = self.guards_at(x, t)
        return t, x, (1.0 - s) * p0.radius + s * p1.radius, g, d

    def _advance(self) -> bool:
        """Compute the next point; False when the flow has ended."""
        if self._done:
            return False
        try:
            return self._advance_point()
        except ModelBreakdown as exc:
            # Flowing on past the guards can take a model out of its range (a runner's hip
            # through the ground after a touchdown it did not take): the flow ends there.
            self._finish("model_breakdown", f"{exc} (flowing mode '{self.mode_name}' on from t={self._t:.6g})")
            return False

    def _advance_point(self) -> bool:
        t, x = self._t, self._x
        f0 = self.field_at(t, x) if self._f is None else self._f
        if not _finite(f0):
            self._finish("non_finite", f"field of mode '{self.mode_name}' is not finite at t={t:.17g}, x={x.tolist()}")
            return False
        u = None if self.control is None else self.control(t, x)
        self._L = max(self._L, lipschitz_estimate(self.mode, t, x, u))
        g, d = self.guards_at(x, t)
        remaining = self.t_end - t
        at_end = math.isfinite(self.t_end) and remaining <= 1e-12 * max(1.0, abs(self.t_end))
        last = at_end or len(self.points) + 1 >= self.max_points
        le = hn = 0.0
        if not last:
            hn, x_new, f_new, le, last = self._step(t, x, f0, remaining)
        if len(self.points) + 1 >= self.max_points and self.status == "running" and remaining > 0:
            self._finish(
                "max_points", f"flow of mode '{self.mode_name}' reached {self.max_points} points at t={t:.17g}"
            )
        # A failed step's error is not part of the bound at its start point (its ball stays finite).
        radius = self._s + (le if math.isfinite(le) else 0.0)
        if not math.isfinite(radius):
            # B grows like e^(L (t - t0)): past t - t0 ~ 700 / L it overflows, and a ball of
            # infinite radius says nothing (every guard would be half crossed, 0 * inf = nan).
            self._finish(
                "bound_overflow",
                f"the error bound of mode '{self.mode_name}' overflowed at t={t:.6g} (it grows like "
                f"exp(L (t - t0)) with L = {self._L:.3g} 1/s from t0 = {self.t0:.6g} s): "
                f"shorten t_final or lower h",
            )
            return False
        self.points.append(FlowPoint(t, x, f0, radius, g, d))
        if self.progress is not None and (len(self.points) & 255) == 0:
            self.progress(t)
        if last:
            if self.status == "running":
                self._finish("end", "")
            return True
        self._s = radius * math.exp(self._L * hn)
        self._t = t + hn if hn != remaining else self.t_end
        self._x = x_new
        self._f = f_new
        return True

    def _step(
        self, t: float, x: np.ndarray, f0: np.ndarray, remaining: float
    ) -> tuple[float, np.ndarray, np.ndarray, float, bool]:
        """One step from (t, x), f0 = f(t, x), at most ``remaining`` (s) long: (its length, the
        new state and field, its local error with the interpolant's, whether the flow ends at
        its start: the model broke down or the step is not finite, its error then infinite)."""
        hn = min(self.h, remaining)
        if remaining - hn <= 1e-9 * self.h:
            hn = remaining
        try:
            x_new, le = self.estimator.step(self.mode.field, t, x, hn, f0, self.control)
            f_new = self.field_at(t + hn, x_new) if _finite(x_new) else x_new
            if _finite(f_new):
                x_half = self.estimator.pair_solution(self.mode.field, t, x, 0.5 * hn, f0, self.control)
                midpoint = 0.5 * (x + x_new) + (0.125 * hn) * (f0 - f_new)
                le += _norm(midpoint - x_half)
        except ModelBreakdown as exc:
            # The step leaves the model's range, its start point does not: keep that point
            # (the cone may leave the domain there) and end the flow.
            self._finish("model_breakdown", f"{exc} (flowing mode '{self.mode_name}' on from t={t:.6g})")
            return hn, x, x, math.inf, True
        if not (_finite(x_new) and _finite(f_new) and math.isfinite(le)):
            self._finish(
                "non_finite", f"step from t={t:.17g} in mode '{self.mode_name}' is not finite (x={x.tolist()})"
            )
            return hn, x_new, f_new, math.inf, True
        return hn, x_new, f_new, le, False

    def _finish(self, status: str, message: str) -> None:
        self._done = True
        self.status = status
        self.message = message

    def point(self, n: int) -> FlowPoint | None:
        """Point n of the flow (computing up to it), or None past its end."""
        while len(self.points) <= n:
            if not self._advance():
                return None
        return self.points[n]

    def state(self, n: int, s: float) -> np.ndarray:
        """The interpolated state at fraction s of step n (points n and n + 1 must exist)."""
        p0, p1 = self.points[n], self.points[n + 1]
        return hermite(p0.x, p0.f, p1.x, p1.f, p1.t - p0.t, s)

    def step_samples(self, n: int) -> StepSamples | None:
        """Step n (point n to n + 1) at sample fractions resolving every guard the ball may
        reach during the step; just the two ends when it reaches none. None past the end (or
        when the model breaks down inside the step: status ``model_breakdown``)."""
        try:
            return self._step_samples(n)
        except ModelBreakdown as exc:
            if not self._done:
                self._finish("model_breakdown", f"{exc} (flowing mode '{self.mode_name}' on, inside step {n})")
            return None

    def _step_samples(self, n: int) -> StepSamples | None:
        p0 = self.point(n)
        p1 = self.point(n + 1)
        if p0 is None or p1 is None:
            return None
        dt = p1.t - p0.t
        r0, r1 = p0.radius, p1.radius
        chord = (p1.x - p0.x) / dt if dt > 0 else np.zeros_like(p0.x)
        # |Hermite - chord| <= (4/27) dt (|f0 - chord| + |f1 - chord|); 0.3 leaves room for the
        # curvature of a linearised guard over the step.
        margin = 0.3 * dt * (_norm(p0.f - chord) + _norm(p1.f - chord))
        rmax = max(r0, r1)
        lo = np.minimum(p0.distance, p1.distance)
        hi = np.maximum(p0.distance, p1.distance)
        inside = lo - rmax > margin
        past = hi + rmax < -margin
        if np.all(inside | past) or dt <= 0.0:  # just the two ends
            return StepSamples(np.array([0.0, 1.0]), np.array([p0.t, p1.t]), np.array([p0.x, p1.x]), np.array([r0, r1]),
                               np.array([p0.guard, p1.guard]), np.array([p0.distance, p1.distance]))  # fmt: skip
        k = self.SAMPLES_PER_ACTIVE_STEP
        fractions = list(np.linspace(0.0, 1.0, k + 1))
        cache: dict[float, tuple[np.ndarray, np.ndarray, np.ndarray]] = {
            0.0: (p0.x, p0.guard, p0.distance),
            1.0: (p1.x, p1.guard, p1.distance),
        }

        def at(s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            if s not in cache:
                x = hermite(p0.x, p0.f, p1.x, p1.f, dt, s)
                g, d = self.guards_at(x, p0.t + s * dt)
                cache[s] = (x, g, d)
            return cache[s]

        def ratio(s: float, j: int) -> float:
            r = (1.0 - s) * r0 + s * r1
            d = at(s)[2][j]
            return d / r if r > 0 else d

        extra = []
        for j in np.flatnonzero(~(inside | past)).tolist():
            extra += _extrema(functools.partial(ratio, j=j), fractions, self.EDGE_PROBE)
        s_all = np.unique(np.concatenate([np.array(fractions), np.array(extra)]))
        xs, gs, ds = zip(*(at(float(s)) for s in s_all), strict=True)
        return StepSamples(
            s_all,
            p0.t + s_all * dt,
            np.array(xs),
            (1.0 - s_all) * r0 + s_all * r1,
            np.array(gs).reshape(len(s_all), -1),
            np.array(ds).reshape(len(s_all), -1),
        )


def _extrema(u_at: Callable[[float], float], fractions: list[float], probe: float) -> list[float]:
    """Step fractions in [0, 1] of the local extrema of ``u_at`` (a guard's distance over the
    ball's radius) between its samples at ``fractions`` (0 to 1), each by a bounded search;
    none when a sample is not finite (a guard without a state gradient, e.g. a clock)."""
    k, u = len(fractions) - 1, [u_at(float(s)) for s in fractions]
    if not all(math.isfinite(v) for v in u):
        return []
    # A probe just inside each end brackets an extremum in the first or last sub-interval (the
    # next step starts past it).
    triples = [(u[i - 1], u[i], u[i + 1], fractions[i - 1], fractions[i + 1]) for i in range(1, k)]
    triples += [
        (u[0], u_at(probe), u[1], 0.0, fractions[1]),
        (u[k - 1], u_at(1.0 - probe), u[k], fractions[k - 1], 1.0),
    ]
    found = []
    for before, middle, after, lo_s, hi_s in triples:
        if (middle - before) * (after - middle) < 0.0:
            sign = 1.0 if middle <= before else -1.0  # a minimum of u, or a maximum
            res = minimize_scalar(lambda s, sign=sign: sign * u_at(float(s)), bounds=(lo_s, hi_s), method="bounded",
                                  options={"xatol": 1e-12})  # fmt: skip
            found.append(float(res.x))
    return found


def check_steps(span: float, h: float, what: str) -> int:
    """The number of fixed steps of size h (s) over ``span`` (s), or SimulationError naming
    ``what`` when it exceeds ``MAX_STEPS``."""
    steps = span / h
    if not steps <= MAX_STEPS:
        raise SimulationError(
            f"{what}: {span:g} s at h = {h:g} s is {steps:.3g} steps, more than the limit "
            f"{MAX_STEPS:.0e}: raise h or shorten t_final"
        )
    return math.ceil(steps)
