"""Periodic orbits of hybrid systems: Poincare sections, return maps, fixed points, Floquet
multipliers and continuation.

A gait is a periodic orbit of a hybrid system. We find one as a fixed point of the *return
map* P of a Poincare section S: start on S, simulate with the relaxed integrator until the
trajectory comes back to S, and ask that P(x) = x.

Sections
--------
``Section.crossing(mode, s, direction)`` is the level set s(x) = 0 of a function of the state of
one mode, crossed in a given direction (e.g. the apex ``zd = 0`` while zd decreases in
flight); ``Section.level(mode, name, value, direction)`` is the common case s = x[name] -
value; ``Section.after(transition)`` is the set of states just after a transition (e.g. the
state after heel strike), whose return is the next time that transition is taken.

How the return is found
-----------------------
The return map simulates a bounded horizon with ``legsim.simulate`` and locates the crossing
on the execution's dense output (the cubic Hermite interpolant of the step containing the sign
change, solved with Brent's method); for a transition section it reads the reset image from the
execution's transition record. We prefer this to adding the section as a guard of a wrapped
system: an extra guard would change the computation being analysed (steps would be halved to
land in the section's strip and the state held there), and starting on the section would fire
that guard at once. The horizon grows: 1.5 times the last return time (plus 20 steps), or
t_max / 8 at first, doubled until a return is found or t_max is reached. A return costs less
than about twice its own time, and a model failure long after it (a runner that falls a few
strides later) cannot hide it.

A crossing of a function section counts only after at least ``min_transitions`` transitions
(default 1) since the start, so that a start just off the section (as finite differences and
Newton trials make) does not "return" to the section it has just left. Crossings are looked for
inside continuous flow of the section's mode; a reset that jumps across s = 0 is not a crossing.

Period
------
The relaxed integrator holds the state at the guard point q for ``eps - tau`` plus the rest of
the landing step (relaxed.py), so the relaxed return time exceeds the hybrid system's period by
eps + O(h) per transition. ``period`` is the flow time (return time minus the time spent in
strips), which converges at the method's order; ``return_time`` is the relaxed one.

Jacobians
---------
Two ways, compared in the tests:

* ``jacobian="saltation"`` (default): along the relaxed execution, the derivative of each
  Runge-Kutta step (the variational equation integrated with the same tableau on the same
  steps, with the field's Jacobian from ``Mode.jacobian`` or forward differences) and, at each
  transition with guard point q, the saltation matrix
  ``Xi = DR + (f+ - DR f-) grad_g^T / (grad_g . f-)`` from the reset Jacobian DR(q), the guard
  gradient (``Transition.reset_jacobian``/``guard_gradient`` or central differences) and the
  fields either side. The return itself is not taken at a fixed time but where the
  trajectory meets the section, so the product ends with a projection along the flow: for a
  crossing section ``I - f grad_s^T / (grad_s . f)``; for a section after a transition the
  returning transition contributes ``DR (I - f- grad_g^T / (grad_g . f-))`` (the derivative of
  the reset image R(q)) instead of its saltation matrix. One simulation in all.
* ``jacobian="fd"``: central differences of the return map, 2 simulations per coordinate.
  Step ``delta_j = fd_step * max(1, |x_j|)``. The central difference error is about
  ``eta / delta + delta**2 |P'''| / 6`` with eta the return map's own noise as a function of x
  (rounding, and the O(h^p) jumps as the step that lands in a strip changes with x). For fixed
  steps eta is tiny: the compass gait's FD error against the saltation Jacobian is 8.5e-8,
  3.8e-9 and 3.4e-8 at steps 1e-5, 1e-6 and 1e-7, i.e. eta ~ 3e-15 and |P'''| ~ 5e3, an
  optimum near (3 eta / |P'''|)^(1/3) ~ 1e-6, which is the default. With error-controlled
  steps (rtol/atol) the step sequence itself changes with x, eta ~ the tolerance, and the
  default becomes tolerance^(1/3). ``docs/orbits.md`` has the measurements.

Derivatives with respect to free parameters are always central differences of the return map
(the system is rebuilt for each value). Where the simulation on one side of a difference fails
(a model that refuses states on one side, such as a runner whose flight foot would start below
the ground just off a symmetric gait), the one-sided difference on the other side is used.

Multipliers
-----------
The return map extended off the section by the flow satisfies DP f(x*) = 0 (a start moved
along the flow returns to the same point), so the n x n Jacobian DP has the trivial eigenvalue
0 along f. In an orthonormal basis B of the complement f^perp, ``M = B^T DP B`` is the Jacobian
of the return map restricted to a section, whatever the section's shape, and its n - 1
eigenvalues are the Floquet multipliers. Cyclic coordinates (positions along a translation
symmetry, such as a runner's x) are removed first: P(x + a e_c) = P(x) + a e_c, so they only add
trivial multipliers 1. Multipliers known to be 1 because of a conserved quantity (the energy of a
passive runner) are reported but can be excluded from the stability verdict with
``trivial_multipliers``.

Failures are never answers: the solver returns an ``OrbitResult`` whose ``status`` says why it
stopped (``no_return``, ``simulation_failed``, ``singular_jacobian``, ``diverged``, ``stalled``,
``max_iterations``) with a message; ``result.raise_for_status()`` turns it into an
``OrbitError``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any, Callable, Mapping, Sequence

import numpy as np
from scipy.optimize import brentq

from .errors import LegsimError
from .execution import Execution, Segment, TransitionRecord
from .hybrid import HybridSystem, Transition
from .methods import Tableau, get_method
from .relaxed import simulate

__all__ = [
    "OrbitError", "Section", "OrbitProblem", "Return", "ReturnMap", "OrbitResult", "Family", "FamilyPoint",
    "StabilityChange", "OrbitSettings", "problem_from_scene", "default_fd_step", "find_orbit", "return_map",
    "jacobian_fd", "jacobian_saltation", "saltation_matrix", "MAX_STEPS_PER_RETURN", "MAX_FD_STEP",
    "reset_on_guard_jacobian",
    "floquet_multipliers", "continue_family", "STATUSES",
]

#: Ends of an orbit search.
STATUSES = ("converged", "no_return", "simulation_failed", "singular_jacobian", "diverged", "stalled",
            "max_iterations")

_CBRT_EPS = np.finfo(float).eps ** (1.0 / 3.0)  # optimal relative step of a central difference

#: Most steps of size h over t_max that one return may take (``legsim.simulate`` makes about
#: 2e4 RK4 steps per second on the robots, so this is minutes per simulation): more is a typo
#: in h or t_max, not a computation to start.
MAX_STEPS_PER_RETURN = 10_000_000
#: Largest relative finite-difference step: beyond it a difference is no derivative at all
#: (the default is 1e-6, see ``default_fd_step``).
MAX_FD_STEP = 0.1


class OrbitError(LegsimError, ValueError):
    """An orbit computation failed or was set up wrongly; the message says why (no return within
    the time limit, a failed simulation, a singular Jacobian, divergence, bad problem).
    ``key`` names the problem setting at fault, when there is one (e.g. ``"cyclic"``), so that a
    scene's error can name its ``[orbit]`` key."""

    def __init__(self, message: str, status: str = "invalid", key: str | None = None) -> None:
        super().__init__(message)
        self.status = status
        self.key = key


# --------------------------------------------------------------------------------------------
# Sections
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Section:
    """A Poincare section. Build one with ``Section.crossing``, ``Section.level`` or
    ``Section.after``.

    Attributes
    ----------
    mode: the mode the section lies in (for ``after``, filled in from the transition's target).
    function: ``s(x) -> float`` for a crossing section; the section is s = 0.
    direction: -1 when s decreases through 0 (from > 0 to <= 0), +1 when it increases, 0 both.
    gradient: optional ``grad s(x)`` of shape (n,); central differences otherwise.
    transition: name of the transition for an ``after`` section.
    coordinate, value: for ``coordinate`` sections, the coordinate's name and level.
    label: a readable name.
    """

    mode: str | None
    function: Callable[[np.ndarray], float] | None = None
    direction: int = -1
    gradient: Callable[[np.ndarray], np.ndarray] | None = None
    transition: str | None = None
    coordinate: str | None = None
    value: float = 0.0
    label: str = ""

    @classmethod
    def crossing(cls, mode: str, function: Callable[[np.ndarray], float], direction: int = -1,
                 gradient: Callable[[np.ndarray], np.ndarray] | None = None, label: str = "") -> "Section":
        """The level set ``function(x) = 0`` in ``mode``, crossed in ``direction`` (-1: s goes
        from > 0 to <= 0; +1: from < 0 to >= 0; 0: either)."""
        if not callable(function):
            raise OrbitError("Section.crossing: function must be callable s(x) -> float")
        return cls(mode, function, _check_direction(direction), gradient, None, None, 0.0,
                   label or f"s(x) = 0 in {mode}")

    @classmethod
    def level(cls, mode: str, coordinate: str, value: float = 0.0, direction: int = -1) -> "Section":
        """``x[coordinate] = value`` in ``mode``, crossed in ``direction`` (e.g. the apex:
        ``Section.level("flight", "zd", 0.0, -1)``)."""
        if not isinstance(coordinate, str):
            raise OrbitError(f"Section.level: coordinate must be a name, got {coordinate!r}")
        value = float(value)
        if not math.isfinite(value):
            raise OrbitError(f"Section.level: value must be finite, got {value}")
        direction = _check_direction(direction)
        arrow = {-1: "decreasing", 1: "increasing", 0: "either way"}[direction]
        return cls(mode, None, direction, None, None, coordinate, value,
                   f"{coordinate} = {value:g} ({arrow}) in {mode}")

    @classmethod
    def after(cls, transition: str) -> "Section":
        """The states just after ``transition`` (its reset images), in its target mode."""
        if not isinstance(transition, str) or not transition:
            raise OrbitError(f"Section.after: transition must be a transition name, got {transition!r}")
        return cls(None, None, 0, None, transition, None, 0.0, f"after {transition}")

    @property
    def kind(self) -> str:
        """``"transition"`` or ``"crossing"``."""
        return "transition" if self.transition is not None else "crossing"


def _check_direction(direction: Any) -> int:
    if direction in ("decreasing", "down"):
        return -1
    if direction in ("increasing", "up"):
        return 1
    if direction in ("either", "both"):
        return 0
    if isinstance(direction, bool) or direction not in (-1, 0, 1):
        raise OrbitError(f"section direction must be -1, 0, +1 (or 'decreasing', 'increasing', 'either'), "
                         f"got {direction!r}")
    return int(direction)


@dataclass(frozen=True)
class _BoundSection:
    """A section resolved against a system: mode, s(x), grad s(x) or the transition."""

    section: Section
    mode: str
    names: tuple[str, ...]
    index: int | None  # coordinate index of a coordinate section

    def s(self, x: np.ndarray) -> float:
        if self.index is not None:
            return float(x[self.index]) - self.section.value
        return float(self.section.function(x))  # type: ignore[misc]

    def grad(self, x: np.ndarray) -> np.ndarray:
        n = len(x)
        if self.index is not None:
            g = np.zeros(n)
            g[self.index] = 1.0
            return g
        if self.section.gradient is not None:
            g = np.asarray(self.section.gradient(x), dtype=float).reshape(-1)
            if g.shape != (n,):
                raise OrbitError(f"section {self.section.label}: gradient has shape {g.shape}, expected ({n},)")
            return g
        return _gradient_fd(self.s, x)


def _bind_section(section: Section, system: HybridSystem) -> _BoundSection:
    if not isinstance(section, Section):
        raise OrbitError(f"section must be a legsim.orbits.Section, got {type(section).__name__}")
    if section.transition is not None:
        matches = [tr for tr in system.transitions if tr.name == section.transition]
        if not matches:
            known = sorted({tr.name for tr in system.transitions})
            raise OrbitError(f"section after '{section.transition}': no transition of that name in "
                             f"{system.name}; transitions: {known}")
        targets = sorted({tr.target for tr in matches})
        if len(targets) > 1:
            raise OrbitError(f"section after '{section.transition}': transitions of that name lead to "
                             f"several modes {targets}; name them apart")
        mode = targets[0]
        return _BoundSection(replace(section, mode=mode), mode, tuple(system.state_names(mode)), None)
    try:
        names = tuple(system.state_names(section.mode))  # type: ignore[arg-type]
    except LegsimError:
        raise OrbitError(f"section {section.label}: unknown mode {section.mode!r}; "
                         f"modes: {sorted(system.modes)}") from None
    index = None
    if section.coordinate is not None:
        if section.coordinate not in names:
            raise OrbitError(f"section {section.label}: mode '{section.mode}' has no coordinate "
                             f"'{section.coordinate}'; coordinates: {list(names)}")
        index = names.index(section.coordinate)
    return _BoundSection(section, section.mode, names, index)  # type: ignore[arg-type]


# --------------------------------------------------------------------------------------------
# Problem
# --------------------------------------------------------------------------------------------
SystemLike = Any  # HybridSystem, (HybridSystem, control) or a builders.Model


@dataclass
class OrbitProblem:
    """Everything that defines the return map and the periodic-orbit equations.

    Parameters
    ----------
    system: a ``HybridSystem``, or a factory ``system(parameters: dict) -> HybridSystem |
        (HybridSystem, control) | legsim.builders.Model`` when parameters are free or continued.
    section: the Poincare section.
    h, eps, method: the relaxed integrator's step (s), strip width (guard units) and method.
    t_max: time limit of one return (s); no return within it is a ``no_return`` failure.
    control: ``control(t, x) -> u`` for a fixed system (a factory returns its own).
    parameters: parameter values passed to the factory (initial guesses for the free ones).
    free: names of parameters solved for (unknowns besides the state).
    fixed: coordinates held at their initial values (e.g. the apex height). The coordinate of a
        coordinate section is always fixed.
    cyclic: coordinates along a symmetry (a horizontal position): fixed, left out of the
        periodicity equations, their increment over a return is the step length.
    constraints: extra equations ``(name, c(x, parameters) -> float)`` asked to be 0.
    energy: when given, the constraint ``system.energy(mode, x) = energy`` (J).
    returns: the orbit's period in returns (2 for a period-two gait).
    min_transitions, min_time: a crossing section's return counts only after this many
        transitions and this much time (s) since the previous return.
    max_transitions: transition budget of one return (guards against chattering).
    step_length: optional ``step_length(ret: Return) -> float`` (m) for walkers; by default the
        increment of the first cyclic coordinate, if any.
    trivial_multipliers: how many multipliers are 1 because of conserved quantities; they are
        left out of the stability verdict (the ones closest to 1).
    rtol, atol: passed to ``simulate`` for error-controlled steps (embedded methods only).
    progress: optional ``progress(t, t0, t_final)`` passed to every ``simulate`` (a progress
        bar for long returns).
    """

    system: SystemLike
    section: Section
    h: float
    eps: float
    method: str | Tableau = "rk4"
    t_max: float = 10.0
    control: Callable[[float, np.ndarray], Any] | None = None
    parameters: Mapping[str, float] = field(default_factory=dict)
    free: Sequence[str] = ()
    fixed: Sequence[str] = ()
    cyclic: Sequence[str] = ()
    constraints: Sequence[tuple[str, Callable[[np.ndarray, Mapping[str, float]], float]]] = ()
    energy: float | None = None
    returns: int = 1
    min_transitions: int = 1
    min_time: float = 0.0
    max_transitions: int = 10_000
    step_length: Callable[["Return"], float] | None = None
    trivial_multipliers: int = 0
    rtol: float | None = None
    atol: float | None = None
    progress: Callable[[float, float, float], None] | None = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        for name in ("h", "eps", "t_max"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
                raise OrbitError(f"orbit problem: {name} must be a finite number > 0, got {value!r}", key=name)
        if self.rtol is None and self.atol is None and self.t_max / self.h > MAX_STEPS_PER_RETURN:
            raise OrbitError(f"orbit problem: t_max / h = {self.t_max:g} s / {self.h:g} s = {self.t_max / self.h:.3g} "
                             f"steps per return, more than the limit {MAX_STEPS_PER_RETURN:.0e}: raise h or lower "
                             f"t_max", key="t_max")
        self.tableau = get_method(self.method)
        if not isinstance(self.section, Section):
            raise OrbitError(f"orbit problem: section must be a Section, got {type(self.section).__name__}")
        for name in ("returns", "max_transitions"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise OrbitError(f"orbit problem: {name} must be an integer >= 1, got {value!r}", key=name)
        if isinstance(self.min_transitions, bool) or not isinstance(self.min_transitions, int) \
                or self.min_transitions < 0:
            raise OrbitError(f"orbit problem: min_transitions must be an integer >= 0, got {self.min_transitions!r}",
                             key="min_transitions")
        if self.section.kind == "crossing" and self.min_transitions == 0 and self.min_time <= 0:
            raise OrbitError("orbit problem: a crossing section with min_transitions = 0 needs min_time > 0, "
                             "or the start itself would count as the return", key="min_transitions")
        self.parameters = {str(k): float(v) for k, v in dict(self.parameters).items()}
        self.free = tuple(self.free)
        self.fixed = tuple(self.fixed)
        self.cyclic = tuple(self.cyclic)
        if isinstance(self.system, tuple) and len(self.system) == 2:
            self.system, self.control = self.system
        elif not isinstance(self.system, HybridSystem) and isinstance(getattr(self.system, "system", None),
                                                                     HybridSystem):
            self.system, self.control = self.system.system, getattr(self.system, "control", None)
        self.is_factory = not isinstance(self.system, HybridSystem)
        if self.is_factory and not callable(self.system):
            raise OrbitError(f"orbit problem: system must be a HybridSystem, a Model or a factory "
                             f"system(parameters), got {type(self.system).__name__}")
        missing = [p for p in self.free if p not in self.parameters]
        if missing:
            raise OrbitError(f"orbit problem: free parameter(s) {missing} need initial values in parameters "
                             f"(given: {sorted(self.parameters)})", key="free")
        if self.free and not self.is_factory:
            raise OrbitError("orbit problem: free parameters need a system factory system(parameters) -> "
                             "HybridSystem, not a fixed HybridSystem")
        self._cache: dict[tuple, tuple[HybridSystem, Any]] = {}
        system, _ = self.instantiate(self.parameters)
        self.bound = _bind_section(self.section, system)
        names = self.bound.names
        for label, group in (("fixed", self.fixed), ("cyclic", self.cyclic)):
            unknown = [c for c in group if c not in names]
            if unknown:
                raise OrbitError(f"orbit problem: {label} coordinate(s) {unknown} are not coordinates of mode "
                                 f"'{self.bound.mode}' {list(names)}", key=label)
        self.names = names
        self.dim = len(names)
        self.cyclic_idx = [names.index(c) for c in self.cyclic]
        fixed = set(self.fixed) | set(self.cyclic)
        if self.section.coordinate is not None:
            fixed.add(self.section.coordinate)
        self.unknown_idx = [i for i, c in enumerate(names) if c not in fixed]
        self.periodic_idx = [i for i, c in enumerate(names) if i not in self.cyclic_idx
                             and c != self.section.coordinate]
        n_rows = len(self.periodic_idx) + (1 if self.section.kind == "crossing" and self.section.coordinate is None
                                           else 0) + len(self.constraints) + (self.energy is not None)
        n_unknowns = len(self.unknown_idx) + len(self.free)
        if n_unknowns == 0:
            raise OrbitError("orbit problem: nothing to solve for: every coordinate is fixed and no parameter is free",
                             key="fixed")
        if n_rows < n_unknowns:
            raise OrbitError(f"orbit problem: {n_unknowns} unknowns ({self.unknown_names}) but only {n_rows} "
                             f"equations: fix coordinates or drop free parameters", key="free")
        if self.energy is not None and system.energy is None:
            raise OrbitError(f"orbit problem: an energy level is asked for but {system.name} defines no energy",
                             key="energy")
        # Multipliers live on the section without the cyclic coordinates: n - 1 - #cyclic of them.
        n_multipliers = self.dim - 1 - len(self.cyclic_idx)
        trivial = self.trivial_multipliers
        if isinstance(trivial, bool) or not isinstance(trivial, int) or trivial < 0 \
                or (trivial > 0 and trivial >= n_multipliers):
            raise OrbitError(f"orbit problem: trivial_multipliers = {trivial!r} must be an integer >= 0 that leaves "
                             f"at least one of the section's {n_multipliers} multiplier(s) to judge stability by",
                             key="trivial_multipliers")
        for item in self.constraints:
            if not (isinstance(item, tuple) and len(item) == 2 and callable(item[1])):
                raise OrbitError(f"orbit problem: constraints must be (name, c(x, parameters)) pairs, got {item!r}")

    @property
    def unknown_names(self) -> list[str]:
        """Names of the unknowns: free coordinates, then free parameters."""
        return [self.names[i] for i in self.unknown_idx] + list(self.free)

    def instantiate(self, parameters: Mapping[str, float] | None = None) -> tuple[HybridSystem, Any]:
        """(system, control) for these parameter values (cached)."""
        if not self.is_factory:
            return self.system, self.control
        params = dict(self.parameters)
        if parameters:
            params.update({k: float(v) for k, v in parameters.items()})
        key = tuple(sorted(params.items()))
        hit = self._cache.get(key)
        if hit is not None:
            return hit
        try:
            built = self.system(params)
        except OrbitError:
            raise
        except LegsimError as exc:
            raise OrbitError(f"orbit problem: no system for parameters {params}: {exc}", "simulation_failed") from exc
        except Exception as exc:
            raise OrbitError(f"orbit problem: building the system with parameters {params} failed: "
                             f"{type(exc).__name__}: {exc}", "simulation_failed") from exc
        control = self.control
        if isinstance(built, tuple):
            built, control = built
        elif not isinstance(built, HybridSystem) and hasattr(built, "system"):
            control = getattr(built, "control", None)
            built = built.system
        if not isinstance(built, HybridSystem):
            raise OrbitError(f"orbit problem: the system factory returned {type(built).__name__}, expected a "
                             f"HybridSystem, (HybridSystem, control) or a builders.Model")
        if len(self._cache) > 16:
            self._cache.clear()
        self._cache[key] = (built, control)
        return built, control

    def state_vector(self, guess: Mapping[str, float] | Sequence[float] | np.ndarray) -> np.ndarray:
        """A full state of the section's mode from a vector or a {coordinate: value} table."""
        if isinstance(guess, Mapping):
            unknown = sorted(set(guess) - set(self.names))
            if unknown:
                raise OrbitError(f"initial guess: unknown coordinate(s) {unknown}; coordinates of mode "
                                 f"'{self.bound.mode}': {list(self.names)}")
            missing = [c for c in self.names if c not in guess and c != self.section.coordinate]
            if missing:
                raise OrbitError(f"initial guess: missing coordinate(s) {missing} of mode '{self.bound.mode}'")
            x = np.array([float(guess.get(c, self.section.value)) for c in self.names])
        else:
            x = np.asarray(guess, dtype=float).reshape(-1)
            if x.shape != (self.dim,):
                raise OrbitError(f"initial guess has shape {np.shape(guess)}, expected ({self.dim},) with "
                                 f"coordinates {list(self.names)} of mode '{self.bound.mode}'")
        if not np.all(np.isfinite(x)):
            raise OrbitError(f"initial guess must be finite, got {x.tolist()}")
        if self.section.coordinate is not None:
            x[self.bound.index] = self.section.value
        return x


# --------------------------------------------------------------------------------------------
# Return map
# --------------------------------------------------------------------------------------------
@dataclass
class Return:
    """One evaluation of the return map.

    Attributes
    ----------
    x_start, x_end: the start and the returned state (section mode), shape (n,).
    mode: the section's mode.
    time: relaxed return time (s), strips included; flow_time: the same without the time spent
        in strips (the hybrid system's period to the integrator's order).
    transitions: the transition records of the return, in order.
    execution: the simulation the return was read from (it may run past the return).
    t_return: absolute time of the return in the execution (s).
    segment: index of the segment holding the return (crossing sections) or of the last
        segment before the returning transition.
    parameters: the parameter values used.
    """

    x_start: np.ndarray
    x_end: np.ndarray
    mode: str
    time: float
    flow_time: float
    transitions: list[TransitionRecord]
    execution: Execution
    t_return: float
    segment: int
    parameters: dict[str, float]
    step_length: float | None = None


class ReturnMap:
    """The return map of a problem's section, with an adaptive simulation horizon.

    ``rmap(x, parameters=None) -> Return``; raises ``OrbitError`` (status ``no_return`` or
    ``simulation_failed``) when there is no return.
    """

    def __init__(self, problem: OrbitProblem) -> None:
        self.problem = problem
        self.evaluations = 0
        self._hint: float | None = None

    def __call__(self, x: np.ndarray, parameters: Mapping[str, float] | None = None) -> Return:
        p = self.problem
        x = np.asarray(x, dtype=float).copy()
        params = dict(p.parameters)
        if parameters:
            params.update({k: float(v) for k, v in parameters.items()})
        system, control = p.instantiate(params)
        # Growing horizons: the last return time and a half, or t_max / 8, doubled up to t_max.
        # A return is found at a cost below about twice its own time, and a model failure long
        # after the return (a runner falling later) cannot hide it.
        first = 1.5 * self._hint + 20 * p.h if self._hint is not None else p.t_max / 8
        horizons = []
        horizon = first
        while horizon < p.t_max:
            horizons.append(horizon)
            horizon *= 2
        horizons.append(p.t_max)
        last_error: OrbitError | None = None
        for horizon in horizons:
            self.evaluations += 1
            try:
                ex = simulate(system, x, p.bound.mode, horizon, p.h, p.eps, p.tableau, control,
                              max_transitions=p.max_transitions, rtol=p.rtol, atol=p.atol, progress=p.progress)
            except LegsimError as exc:
                raise OrbitError(f"return map: the simulation from {self._show(x)} over {horizon:g} s failed before "
                                 f"returning to the section {p.section.label}: {exc}", "simulation_failed") from exc
            found = self._locate(ex, x, params)
            if found is not None:
                self._hint = found.time
                return found
            if ex.status != "finished":
                raise OrbitError(f"return map: the simulation from {self._show(x)} stopped with status "
                                 f"'{ex.status}' before returning to the section {p.section.label}: {ex.message}",
                                 "simulation_failed")
            seen = [tr.name for tr in ex.transitions]
            last_error = OrbitError(
                f"no return to the section {p.section.label} within t_max = {horizon:g} s from "
                f"{self._show(x)} (transitions taken: {_abbreviate(seen)}; final mode '{ex.final_mode}', "
                f"state {np.round(ex.final_state, 6).tolist()})", "no_return")
        assert last_error is not None
        raise last_error

    def _show(self, x: np.ndarray) -> str:
        return "{" + ", ".join(f"{n}={v:.6g}" for n, v in zip(self.problem.names, x)) + "}"

    def _locate(self, ex: Execution, x0: np.ndarray, params: dict[str, float]) -> Return | None:
        p = self.problem
        if p.section.kind == "transition":
            count = 0
            for k, rec in enumerate(ex.transitions):
                if rec.name == p.section.transition:
                    count += 1
                    if count == p.returns:
                        return self._make_return(ex, x0, rec.state_after.copy(), rec.exit_time, k,
                                                 ex.transitions[:k + 1], params)
            return None
        # Crossing section: scan segments of the section's mode in time order. Segment k
        # follows transitions[k-1], so k transitions precede it.
        bound = p.bound
        direction = p.section.direction
        count = 0
        last_k, last_t = 0, ex.t0
        for k, seg in enumerate(ex.segments):
            if seg.mode != bound.mode or len(seg.t) < 2:
                continue
            if k - last_k < p.min_transitions:
                continue
            hit = _first_crossing(seg, bound.s, direction, last_t + p.min_time)
            while hit is not None:
                t_hit, x_hit = hit
                count += 1
                if count == p.returns:
                    return self._make_return(ex, x0, x_hit, t_hit, k, ex.transitions[:k], params)
                last_k, last_t = k, t_hit
                if p.min_transitions > 0:
                    break
                hit = _first_crossing(seg, bound.s, direction, last_t + p.min_time)
        return None

    def _make_return(self, ex, x0, x_end, t_ret, k, records, params) -> Return:
        p = self.problem
        in_strips = sum(s.exit_time - s.time for s in ex.strips if s.exit_time <= t_ret + 1e-12 * max(1.0, t_ret))
        ret = Return(x_start=x0.copy(), x_end=np.asarray(x_end, dtype=float), mode=p.bound.mode,
                     time=t_ret - ex.t0, flow_time=t_ret - ex.t0 - in_strips, transitions=list(records),
                     execution=ex, t_return=t_ret, segment=k, parameters=dict(params))
        if p.step_length is not None:
            ret.step_length = float(p.step_length(ret))
        elif p.cyclic_idx:
            c = p.cyclic_idx[0]
            ret.step_length = float(ret.x_end[c] - ret.x_start[c])
        return ret


def _first_crossing(seg: Segment, s: Callable[[np.ndarray], float], direction: int,
                    not_before: float) -> tuple[float, np.ndarray] | None:
    """First crossing of s = 0 in ``direction`` on a segment's dense output after ``not_before``."""
    start = int(np.searchsorted(seg.t, not_before, side="right")) - 1
    start = max(start, 0)
    values = [s(seg.x[start])]
    for i in range(start, len(seg.t) - 1):
        s0 = values[-1]
        s1 = s(seg.x[i + 1])
        values.append(s1)
        down = s0 > 0.0 >= s1
        up = s0 < 0.0 <= s1
        if not ((direction <= 0 and down) or (direction >= 0 and up)):
            continue
        t0, t1 = seg.t[i], seg.t[i + 1]
        if s1 == 0.0:
            tc = t1
        else:
            def along(t: float) -> float:
                return s(seg.interpolate(np.array([t]))[0])

            # The interpolant's ends are the stored points, so the bracket holds.
            tc = brentq(along, t0, t1, xtol=1e-15 * max(1.0, abs(t1)), rtol=4 * np.finfo(float).eps)
        if tc <= not_before:
            continue
        return tc, seg.interpolate(np.array([tc]))[0]
    return None


def _abbreviate(names: list[str], limit: int = 8) -> str:
    if not names:
        return "none"
    if len(names) <= limit:
        return ", ".join(names)
    return ", ".join(names[:limit]) + f", ... ({len(names)} in all)"


def return_map(problem: OrbitProblem, x: Sequence[float] | np.ndarray,
               parameters: Mapping[str, float] | None = None) -> Return:
    """One evaluation of ``problem``'s return map from the state ``x`` (section's mode)."""
    return ReturnMap(problem)(problem.state_vector(x), parameters)


# --------------------------------------------------------------------------------------------
# Jacobians
# --------------------------------------------------------------------------------------------
def _gradient_fd(fn: Callable[[np.ndarray], float], x: np.ndarray) -> np.ndarray:
    g = np.empty(len(x))
    for j in range(len(x)):
        d = _CBRT_EPS * max(1.0, abs(x[j]))
        xp, xm = x.copy(), x.copy()
        xp[j] += d
        xm[j] -= d
        g[j] = (float(fn(xp)) - float(fn(xm))) / (2 * d)
    return g


def _jacobian_fd(fn: Callable[[np.ndarray], np.ndarray], x: np.ndarray) -> np.ndarray:
    cols = []
    for j in range(len(x)):
        d = _CBRT_EPS * max(1.0, abs(x[j]))
        xp, xm = x.copy(), x.copy()
        xp[j] += d
        xm[j] -= d
        cols.append((np.asarray(fn(xp), dtype=float) - np.asarray(fn(xm), dtype=float)) / (2 * d))
    return np.column_stack(cols)


_SQRT_EPS = math.sqrt(np.finfo(float).eps)


def _field_jacobian(mode_obj, control, t: float, x: np.ndarray, fx: np.ndarray) -> np.ndarray:
    """df/dx at (t, x), given fx = f(t, x). ``Mode.jacobian`` when the mode has one (and there
    is no control: with one, the closed-loop field x -> f(t, x, u(t, x)) is differentiated, since
    Mode.jacobian holds u fixed); otherwise forward differences from fx with steps
    sqrt(machine eps) * max(1, |x_j|), relative accuracy ~1e-8, n evaluations per Jacobian
    (half the cost of central differences, which dominate the saltation Jacobian's cost)."""
    if mode_obj.jacobian is not None and control is None:
        return np.asarray(mode_obj.jacobian(t, x, None), dtype=float)
    n = len(x)
    J = np.empty((n, n))
    for j in range(n):
        d = _SQRT_EPS * max(1.0, abs(x[j]))
        y = x.copy()
        y[j] += d
        d = y[j] - x[j]  # the step actually taken, after rounding
        J[:, j] = (_field(mode_obj, control, t, y) - fx) / d
    return J


def _field(mode_obj, control, t: float, x: np.ndarray) -> np.ndarray:
    return np.asarray(mode_obj.field(t, x, None if control is None else control(t, x)), dtype=float)


def _step_derivative(mode_obj, control, tableau: Tableau, t: float, x: np.ndarray, h: float) -> np.ndarray:
    """Derivative of one explicit Runge-Kutta step x -> x + h sum b_j k_j with respect to x:
    dk_j = J(X_j) (I + h sum_l A_jl dk_l), the variational equation stepped by the same method."""
    n = len(x)
    A, c, b = tableau.A, tableau.c, tableau.b
    ks: list[np.ndarray] = []
    dks: list[np.ndarray] = []
    eye = np.eye(n)
    for j in range(tableau.stages):
        Xj = x.copy()
        dXj = eye.copy()
        for l in range(j):
            if A[j, l] != 0.0:
                Xj = Xj + h * A[j, l] * ks[l]
                dXj = dXj + h * A[j, l] * dks[l]
        tj = t + c[j] * h
        ks.append(_field(mode_obj, control, tj, Xj))
        dks.append(_field_jacobian(mode_obj, control, tj, Xj, ks[-1]) @ dXj)
    S = eye.copy()
    for j in range(tableau.stages):
        if b[j] != 0.0:
            S = S + h * b[j] * dks[j]
    return S


def _segment_sensitivity(system: HybridSystem, control, tableau: Tableau, seg: Segment,
                         t_stop: float | None = None) -> np.ndarray:
    """d x(end) / d x(start) along one stored segment, stepping the variational equation on the
    segment's own steps (each from its stored start point); ``t_stop`` cuts the last step."""
    mode_obj = system.mode(seg.mode)
    n = seg.x.shape[1]
    Phi = np.eye(n)
    for i in range(len(seg.t) - 1):
        t0 = seg.t[i]
        if t_stop is not None and t0 >= t_stop:
            break
        t1 = seg.t[i + 1] if t_stop is None else min(seg.t[i + 1], t_stop)
        if t1 <= t0:
            continue
        Phi = _step_derivative(mode_obj, control, tableau, t0, seg.x[i], t1 - t0) @ Phi
    return Phi


def _transition_pieces(system: HybridSystem, transition: Transition, q: np.ndarray, x_plus: np.ndarray,
                       t_minus: float, t_plus: float, control) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                                        np.ndarray, float]:
    """(DR, grad g, f-, f+, grad g . f-) of a transition at its guard point q."""
    src = system.mode(transition.source)
    tgt = system.mode(transition.target)
    q = np.asarray(q, dtype=float)
    x_plus = np.asarray(x_plus, dtype=float)
    if transition.reset_jacobian is not None:
        DR = np.asarray(transition.reset_jacobian(q), dtype=float).reshape(tgt.dim, src.dim)
    elif transition.reset is None:
        DR = np.eye(src.dim)
    else:
        DR = _jacobian_fd(lambda y: transition.reset(y), q).reshape(tgt.dim, src.dim)  # type: ignore[misc]
    if transition.guard_gradient is not None:
        grad = np.asarray(transition.guard_gradient(q), dtype=float).reshape(src.dim)
    else:
        grad = _gradient_fd(transition.guard, q)
    f_minus = _field(src, control, t_minus, q)
    f_plus = _field(tgt, control, t_plus, x_plus)
    rate = float(grad @ f_minus)
    scale = float(np.linalg.norm(grad) * np.linalg.norm(f_minus))
    if scale == 0.0 or abs(rate) <= 1e-10 * scale:
        raise OrbitError(f"transition {transition.name}: the flow is tangent to the guard at q = "
                         f"{np.round(q, 8).tolist()} (grad g . f = {rate:.3g}): grazing, no saltation matrix",
                         "singular_jacobian")
    return DR, grad, f_minus, f_plus, rate


def saltation_matrix(system: HybridSystem, transition: Transition, q: np.ndarray, x_plus: np.ndarray,
                     t_minus: float = 0.0, t_plus: float = 0.0, control=None) -> np.ndarray:
    """The saltation matrix ``Xi = DR + (f+ - DR f-) grad_g^T / (grad_g . f-)`` of a transition
    at its guard point q, shape (n_target, n_source): it maps a perturbation just before the
    nominal transition time to the perturbation just after it (both at the same time).

    DR is ``transition.reset_jacobian(q)`` (central differences of the reset when absent, the
    identity for an identity reset), grad_g ``transition.guard_gradient(q)`` (central
    differences when absent), f- the source field at (t_minus, q) and f+ the target field at
    (t_plus, x_plus). Raises OrbitError when the flow is tangent to the guard (grazing).
    """
    DR, grad, f_minus, f_plus, rate = _transition_pieces(system, transition, q, x_plus, t_minus, t_plus, control)
    return DR + np.outer(f_plus - DR @ f_minus, grad) / rate


def reset_on_guard_jacobian(system: HybridSystem, transition: Transition, q: np.ndarray, x_plus: np.ndarray,
                            t_minus: float = 0.0, t_plus: float = 0.0, control=None) -> np.ndarray:
    """Derivative of the reset image R(q) itself (not of the state at a fixed time) with respect
    to a perturbation just before the transition: ``DR (I - f- grad_g^T / (grad_g . f-))``, the
    reset Jacobian after projecting onto the guard along the flow. This ends the Jacobian of the
    return map of a section ``after`` this transition (the saltation matrix would add f+ dt)."""
    DR, grad, f_minus, _, rate = _transition_pieces(system, transition, q, x_plus, t_minus, t_plus, control)
    return DR @ (np.eye(len(grad)) - np.outer(f_minus, grad) / rate)


def jacobian_saltation(problem: OrbitProblem, ret: Return) -> np.ndarray:
    """The n x n Jacobian of the return map at ``ret.x_start``, through the variational equation
    on the relaxed execution and the saltation matrix of each transition (module docstring)."""
    system, control = problem.instantiate(ret.parameters)
    ex = ret.execution
    tableau = problem.tableau
    n = problem.dim
    Phi = np.eye(n)
    last = ret.segment
    for k in range(last + 1):
        seg = ex.segments[k]
        stop = ret.t_return if (k == last and problem.section.kind == "crossing") else None
        Phi = _segment_sensitivity(system, control, tableau, seg, stop) @ Phi
        if k == last and problem.section.kind == "crossing":
            break
        rec = ex.transitions[k]
        tr = system.outgoing(rec.source)[rec.index]
        # Synchronous saltation inside the period; the returning transition of an "after"
        # section maps onto the reset image itself.
        jump = reset_on_guard_jacobian if k == last else saltation_matrix
        Phi = jump(system, tr, rec.state_before, rec.state_after, rec.time, rec.exit_time, control) @ Phi
    if problem.section.kind == "crossing":
        mode_obj = system.mode(problem.bound.mode)
        f = _field(mode_obj, control, ret.t_return, ret.x_end)
        grad = problem.bound.grad(ret.x_end)
        rate = float(grad @ f)
        if abs(rate) <= 1e-10 * float(np.linalg.norm(grad) * np.linalg.norm(f) + 1e-300):
            raise OrbitError(f"the flow is tangent to the section {problem.section.label} at the return "
                             f"(grad s . f = {rate:.3g})", "singular_jacobian")
        Phi = (np.eye(n) - np.outer(f, grad) / rate) @ Phi
    return Phi


def _difference(fn: Callable[[float], np.ndarray], d: float, base: Callable[[], np.ndarray], label: str) -> np.ndarray:
    """Central difference (fn(d) - fn(-d)) / 2d; when the simulation on one side fails (a model
    that refuses states on one side, e.g. a runner whose flight foot would start below the
    ground), the one-sided difference on the other side, accurate to O(d) instead of O(d^2)."""
    plus = minus = None
    errors = []
    try:
        plus = fn(d)
    except OrbitError as exc:
        errors.append(exc)
    try:
        minus = fn(-d)
    except OrbitError as exc:
        errors.append(exc)
    if plus is not None and minus is not None:
        return (plus - minus) / (2 * d)
    if plus is None and minus is None:
        raise OrbitError(f"finite difference in {label}: the simulations on both sides failed: {errors[0]}",
                         errors[0].status)
    if plus is not None:
        return (plus - base()) / d
    return (base() - minus) / d


def _check_fd_step(step: Any) -> float:
    if isinstance(step, bool) or not isinstance(step, (int, float)) or not 0.0 < step <= MAX_FD_STEP:
        raise OrbitError(f"fd_step must be a relative step in (0, {MAX_FD_STEP:g}], got {step!r}", key="fd_step")
    return float(step)


def default_fd_step(problem: OrbitProblem) -> float:
    """Relative finite-difference step of the return map: 1e-6 for fixed steps, the cube root
    of the tolerance with error-controlled steps (module docstring)."""
    tols = [t for t in (problem.rtol, problem.atol) if t is not None]
    return max(1e-6, max(tols) ** (1.0 / 3.0)) if tols else 1e-6


def jacobian_fd(problem: OrbitProblem, x: np.ndarray, parameters: Mapping[str, float] | None = None,
                step: float | None = None, columns: Sequence[int] | None = None,
                rmap: ReturnMap | None = None) -> np.ndarray:
    """The n x n Jacobian of the return map at x by central differences (columns of cyclic
    coordinates are e_c by symmetry; one-sided where one side's simulation fails). ``step``:
    relative step, default ``default_fd_step`` (module docstring); ``columns``: only these columns (the others
    are left 0)."""
    rmap = rmap or ReturnMap(problem)
    step = default_fd_step(problem) if step is None else _check_fd_step(step)
    n = problem.dim
    J = np.zeros((n, n))
    cols = range(n) if columns is None else columns
    cache: list[np.ndarray] = []

    def base() -> np.ndarray:
        if not cache:
            cache.append(rmap(x, parameters).x_end)
        return cache[0]

    for j in cols:
        if j in problem.cyclic_idx:
            J[j, j] = 1.0
            continue
        d = step * max(1.0, abs(x[j]))

        def shifted(delta: float, j=j) -> np.ndarray:
            y = x.copy()
            y[j] += delta
            return rmap(y, parameters).x_end

        J[:, j] = _difference(shifted, d, base, f"coordinate {problem.names[j]}")
    return J


def floquet_multipliers(DP: np.ndarray, f: np.ndarray, cyclic: Sequence[int] = ()) -> tuple[np.ndarray, np.ndarray]:
    """Floquet multipliers from the full return-map Jacobian ``DP`` (n x n) and the field ``f``
    at the fixed point: removes cyclic coordinates, restricts to f^perp (DP f = 0 there) and
    returns (multipliers sorted by decreasing modulus, the restricted matrix M)."""
    keep = [i for i in range(DP.shape[0]) if i not in set(cyclic)]
    D = DP[np.ix_(keep, keep)]
    fk = np.asarray(f, dtype=float)[keep]
    norm = np.linalg.norm(fk)
    if norm == 0.0:
        raise OrbitError("the field vanishes at the fixed point: it is an equilibrium, not a periodic orbit",
                         "singular_jacobian")
    # Orthonormal basis of f^perp: the last columns of a complete QR of f.
    Q, _ = np.linalg.qr(fk.reshape(-1, 1), mode="complete")
    B = Q[:, 1:]
    M = B.T @ D @ B
    mu = np.linalg.eigvals(M) if M.size else np.empty(0, dtype=complex)
    order = np.argsort(-np.abs(mu), kind="stable")
    return mu[order].astype(complex), M


# --------------------------------------------------------------------------------------------
# Fixed points
# --------------------------------------------------------------------------------------------
@dataclass
class OrbitResult:
    """The outcome of an orbit search.

    Attributes
    ----------
    status: one of ``STATUSES``; converged: status == "converged"; message: why it stopped.
    mode, state_names: the section's mode and coordinates.
    fixed_point: the last iterate, shape (n,) (the orbit's state on the section when converged).
    parameters: all parameter values, free ones solved.
    period: flow time of one return (s), strips excluded; return_time: relaxed return time (s).
    step_length: the distance covered in one period (m), when defined.
    multipliers: Floquet multipliers (complex, by decreasing modulus), shape (n - 1 - #cyclic,).
    stable: True when every multiplier but the trivial ones has modulus < 1.
    jacobian: the full return-map Jacobian at the fixed point (n, n); section_jacobian: its
        restriction M to the section.
    residual: max-norm of the orbit equations at fixed_point; iterations: Newton iterations.
    history: residual max-norm after each iteration.
    transitions: names of the transitions of one period.
    evaluations: simulations run.
    """

    status: str
    message: str
    mode: str
    state_names: tuple[str, ...]
    fixed_point: np.ndarray
    parameters: dict[str, float]
    residual: float
    iterations: int
    history: list[float]
    period: float | None = None
    return_time: float | None = None
    step_length: float | None = None
    multipliers: np.ndarray | None = None
    trivial_multipliers: int = 0
    jacobian: np.ndarray | None = None
    section_jacobian: np.ndarray | None = None
    transitions: list[str] = field(default_factory=list)
    evaluations: int = 0
    jacobian_method: str = "saltation"
    section: str = ""
    free: tuple[str, ...] = ()

    @property
    def converged(self) -> bool:
        return self.status == "converged"

    @property
    def spectral_radius(self) -> float | None:
        """Largest modulus of the non-trivial multipliers."""
        mu = self.nontrivial_multipliers
        if mu is None:
            return None
        return float(np.max(np.abs(mu))) if mu.size else 0.0

    @property
    def nontrivial_multipliers(self) -> np.ndarray | None:
        """The multipliers without the ``trivial_multipliers`` closest to 1."""
        if self.multipliers is None:
            return None
        mu = self.multipliers
        if self.trivial_multipliers <= 0:
            return mu
        drop = set(np.argsort(np.abs(mu - 1.0))[: self.trivial_multipliers].tolist())
        return np.array([m for i, m in enumerate(mu) if i not in drop], dtype=complex)

    @property
    def stable(self) -> bool | None:
        rho = self.spectral_radius
        return None if rho is None else rho < 1.0

    def raise_for_status(self) -> "OrbitResult":
        """Raise ``OrbitError`` with the message unless the search converged."""
        if not self.converged:
            raise OrbitError(f"orbit search {self.status}: {self.message}", self.status)
        return self

    def to_json(self) -> dict[str, Any]:
        """JSON-ready dict (the keys of ``legsim orbit --json``); non-finite numbers become None."""
        def num(v):
            if v is None:
                return None
            v = float(v)
            return v if math.isfinite(v) else None

        return {
            "status": self.status,
            "message": self.message,
            "section": self.section,
            "mode": self.mode,
            "state_names": list(self.state_names),
            "fixed_point": [num(v) for v in self.fixed_point],
            "parameters": {k: num(v) for k, v in self.parameters.items()},
            "free": list(self.free),
            "period": num(self.period),
            "return_time": num(self.return_time),
            "step_length": num(self.step_length),
            "multipliers": None if self.multipliers is None else
            [[num(m.real), num(m.imag)] for m in self.multipliers],
            "spectral_radius": num(self.spectral_radius),
            "stable": self.stable,
            "trivial_multipliers": self.trivial_multipliers,
            "residual": num(self.residual),
            "iterations": self.iterations,
            "history": [num(v) for v in self.history],
            "transitions": list(self.transitions),
            "evaluations": self.evaluations,
            "jacobian": self.jacobian_method,
        }


class _Equations:
    """The orbit equations F(z) = 0 in the unknowns z = (free coordinates, free parameters)."""

    def __init__(self, problem: OrbitProblem, x_template: np.ndarray, rmap: ReturnMap) -> None:
        self.p = problem
        self.template = x_template.copy()
        self.rmap = rmap
        self.n_x = len(problem.unknown_idx)

    def unpack(self, z: np.ndarray) -> tuple[np.ndarray, dict[str, float]]:
        x = self.template.copy()
        x[self.p.unknown_idx] = z[: self.n_x]
        params = dict(self.p.parameters)
        params.update({name: float(v) for name, v in zip(self.p.free, z[self.n_x:])})
        return x, params

    def pack(self, x: np.ndarray, params: Mapping[str, float]) -> np.ndarray:
        return np.concatenate([x[self.p.unknown_idx], [params[name] for name in self.p.free]])

    def extra(self, x: np.ndarray, params: Mapping[str, float]) -> np.ndarray:
        """Rows that do not need a simulation: section function, constraints, energy."""
        p = self.p
        rows = []
        if p.section.kind == "crossing" and p.section.coordinate is None:
            rows.append(p.bound.s(x))
        for name, fn in p.constraints:
            try:
                rows.append(float(fn(x, params)))
            except Exception as exc:
                raise OrbitError(f"constraint '{name}' failed at x = {x.tolist()}: {type(exc).__name__}: {exc}") \
                    from exc
        if p.energy is not None:
            system, _ = p.instantiate(params)
            rows.append(float(system.energy(p.bound.mode, x)) - p.energy)  # type: ignore[misc]
        return np.array(rows, dtype=float)

    def residual(self, ret: Return) -> np.ndarray:
        idx = self.p.periodic_idx
        return np.concatenate([ret.x_end[idx] - ret.x_start[idx], self.extra(ret.x_start, ret.parameters)])

    def evaluate(self, z: np.ndarray) -> tuple[Return, np.ndarray]:
        x, params = self.unpack(z)
        ret = self.rmap(x, params)
        return ret, self.residual(ret)

    def jacobian(self, z: np.ndarray, ret: Return, method: str, fd_step: float | None) -> tuple[np.ndarray, np.ndarray]:
        """(dF/dz, full DP at x)."""
        p = self.p
        x, params = self.unpack(z)
        if method == "saltation":
            DP = jacobian_saltation(p, ret)
        else:
            DP = jacobian_fd(p, x, params, fd_step, columns=p.unknown_idx, rmap=self.rmap)
        idx = p.periodic_idx
        cols = []
        for j in p.unknown_idx:
            col_periodic = DP[idx, j] - (np.array(idx) == j).astype(float)
            col_extra = self._extra_column(x, params, coord=j)
            cols.append(np.concatenate([col_periodic, col_extra]))
        step = default_fd_step(p) if fd_step is None else fd_step
        for name in p.free:
            d = step * max(1.0, abs(params[name]))

            def shifted(delta: float, name=name) -> np.ndarray:
                q = dict(params)
                q[name] += delta
                return self.residual(self.rmap(x, q))

            cols.append(_difference(shifted, d, lambda: self.residual(ret), f"parameter {name}"))
        return np.column_stack(cols), DP

    def _extra_column(self, x: np.ndarray, params: Mapping[str, float], coord: int) -> np.ndarray:
        if not self.extra_rows:
            return np.empty(0)
        d = _CBRT_EPS * max(1.0, abs(x[coord]))
        xp, xm = x.copy(), x.copy()
        xp[coord] += d
        xm[coord] -= d
        return (self.extra(xp, params) - self.extra(xm, params)) / (2 * d)

    @property
    def extra_rows(self) -> int:
        p = self.p
        return int(p.section.kind == "crossing" and p.section.coordinate is None) + len(p.constraints) + \
            int(p.energy is not None)


def find_orbit(problem: OrbitProblem, guess: Mapping[str, float] | Sequence[float] | np.ndarray, *,
               tol: float = 1e-9, max_iterations: int = 30, jacobian: str = "saltation",
               fd_step: float | None = None, singular_tol: float = 1e-9,
               max_backtracks: int = 8) -> OrbitResult:
    """Find a periodic orbit: a fixed point of the return map (P^returns) with Gauss-Newton.

    Parameters
    ----------
    problem: the section, integrator settings, unknowns, fixed coordinates, free parameters.
    guess: initial state of the section's mode (vector or {coordinate: value}); fixed and
        cyclic coordinates keep these values.
    tol: convergence when the max-norm of the equations (state units; J for an energy row)
        is <= tol.
    max_iterations: Newton iterations allowed.
    jacobian: ``"saltation"`` or ``"fd"`` (module docstring).
    fd_step: relative finite-difference step in (0, 0.1] (default ``default_fd_step(problem)``).
    singular_tol: the Jacobian counts as singular when its smallest singular value is below
        singular_tol times its largest.
    max_backtracks: step halvings tried when a full Newton step does not reduce the residual.

    Returns
    -------
    OrbitResult
        converged or not; never raises for an ordinary failure (see ``STATUSES``).
    """
    if jacobian not in ("saltation", "fd"):
        raise OrbitError(f"jacobian must be 'saltation' or 'fd', got {jacobian!r}")
    if not (isinstance(tol, (int, float)) and tol > 0):
        raise OrbitError(f"tol must be a number > 0, got {tol!r}")
    if isinstance(max_iterations, bool) or not isinstance(max_iterations, int) or max_iterations < 0:
        raise OrbitError(f"max_iterations must be an integer >= 0, got {max_iterations!r}")
    if fd_step is not None:
        fd_step = _check_fd_step(fd_step)
    x0 = problem.state_vector(guess)
    rmap = ReturnMap(problem)
    eq = _Equations(problem, x0, rmap)
    z = eq.pack(x0, problem.parameters)
    history: list[float] = []

    def fail(status: str, message: str, z_now: np.ndarray, res: float, it: int, ret: Return | None = None):
        x_now, params_now = eq.unpack(z_now)
        result = _result(problem, status, message, x_now, params_now, res, it, history, rmap, jacobian, ret)
        return result

    try:
        ret, F = eq.evaluate(z)
    except OrbitError as exc:
        return fail(exc.status, f"at the initial guess: {exc}", z, math.inf, 0)
    res = float(np.max(np.abs(F))) if F.size else 0.0
    history.append(res)
    z_scale = 1.0 + float(np.max(np.abs(z)))
    for it in range(max_iterations + 1):
        if res <= tol:
            try:
                DP = jacobian_saltation(problem, ret) if jacobian == "saltation" else \
                    jacobian_fd(problem, ret.x_start, ret.parameters, fd_step, rmap=rmap)
            except OrbitError as exc:
                return fail(exc.status, f"converged (residual {res:.3g}) but the Jacobian failed: {exc}", z, res,
                            it, ret)
            return _result(problem, "converged", f"residual {res:.3g} <= tol {tol:g} after {it} iteration(s)",
                           ret.x_start, ret.parameters, res, it, history, rmap, jacobian, ret, DP)
        if it == max_iterations:
            break
        try:
            J, _ = eq.jacobian(z, ret, jacobian, fd_step)
        except OrbitError as exc:
            return fail(exc.status, f"iteration {it + 1}: {exc}", z, res, it, ret)
        U, sv, Vt = np.linalg.svd(J, full_matrices=False)
        if sv.size == 0 or not np.all(np.isfinite(sv)):
            return fail("singular_jacobian", f"iteration {it + 1}: the Jacobian is not finite", z, res, it, ret)
        if sv[-1] <= singular_tol * sv[0]:
            null = Vt[-1]
            names = problem.unknown_names
            lead = ", ".join(f"{names[i]} ({null[i]:+.2f})" for i in np.argsort(-np.abs(null))[:3]
                             if abs(null[i]) > 0.1)
            head = (f"iteration {it + 1}: the Jacobian of the orbit equations is singular (singular values "
                    f"{sv[0]:.3g} .. {sv[-1]:.3g}, residual {res:.3g})")
            if res <= max(1e3 * tol, 1e-6):
                # Next to an orbit: a whole family of them passes through it.
                detail = (f"the orbit is not isolated along {lead}; a conserved quantity or symmetry leaves a "
                          f"family of orbits: fix one of these coordinates or add a constraint (e.g. energy)")
            else:
                # Far from any orbit the iterate may simply have wandered where the map degenerates.
                detail = (f"the iterate {rmap._show(eq.unpack(z)[0])} is still far from an orbit and the return "
                          f"map degenerates there along {lead}: try another initial guess (or, if a conserved "
                          f"quantity leaves a family of orbits, fix one of these coordinates or add a constraint)")
            return fail("singular_jacobian", f"{head}: {detail}", z, res, it, ret)
        dz = -(Vt.T @ ((U.T @ F) / sv))
        lam = 1.0
        accepted = False
        for _ in range(max_backtracks + 1):
            trial = z + lam * dz
            try:
                ret_t, F_t = eq.evaluate(trial)
                res_t = float(np.max(np.abs(F_t)))
            except OrbitError:
                res_t = math.inf
            if res_t < res:
                accepted = True
                break
            lam *= 0.5
        if not accepted:
            step_norm = float(np.max(np.abs(dz)))
            if step_norm <= 1e-12 * z_scale:
                return fail("stalled",
                            f"the residual stalls at {res:.3g} > tol {tol:g} after {it} iteration(s): the Newton step "
                            f"({step_norm:.2g}) is below rounding, so the return map's own noise (rounding, and the "
                            f"integrator's steps at h = {problem.h:g}, eps = {problem.eps:g}) limits the residual: raise "
                            f"tol", z, res, it, ret)
            return fail("diverged",
                        f"iteration {it + 1}: no Newton step (lengths 1 .. 1/{2 ** max_backtracks}) reduces the "
                        f"residual {res:.3g}; there may be no periodic orbit near the last iterate {rmap._show(eq.unpack(z)[0])}"
                        + (f" with parameters {eq.unpack(z)[1]}" if problem.free else ""), z, res, it, ret)
        z, ret, F, res = trial, ret_t, F_t, res_t
        history.append(res)
        if float(np.max(np.abs(z))) > 1e8 * z_scale:
            return fail("diverged", f"iteration {it + 1}: the iterates run away (|z| = {np.max(np.abs(z)):.3g})",
                        z, res, it + 1, ret)
    return fail("max_iterations", f"no convergence in {max_iterations} iterations: residual {res:.3g} > tol {tol:g} "
                f"(history {[float(f'{v:.3g}') for v in history]})", z, res, max_iterations, ret)


def _result(problem: OrbitProblem, status: str, message: str, x: np.ndarray, params: Mapping[str, float],
            res: float, iterations: int, history: list[float], rmap: ReturnMap, jacobian: str,
            ret: Return | None = None, DP: np.ndarray | None = None) -> OrbitResult:
    result = OrbitResult(status=status, message=message, mode=problem.bound.mode, state_names=problem.names,
                         fixed_point=np.asarray(x, dtype=float).copy(), parameters=dict(params), residual=res,
                         iterations=iterations, history=list(history), trivial_multipliers=problem.trivial_multipliers,
                         evaluations=rmap.evaluations, jacobian_method=jacobian, section=problem.section.label,
                         free=tuple(problem.free))
    if ret is not None:
        result.period = ret.flow_time
        result.return_time = ret.time
        result.step_length = ret.step_length
        result.transitions = [tr.name for tr in ret.transitions]
    if DP is not None and ret is not None:
        system, control = problem.instantiate(ret.parameters)
        f = _field(system.mode(problem.bound.mode), control, 0.0, ret.x_start)
        try:
            mu, M = floquet_multipliers(DP, f, problem.cyclic_idx)
        except OrbitError as exc:
            result.status, result.message = exc.status, f"{message}; but {exc}"
            return result
        result.jacobian = DP
        result.section_jacobian = M
        result.multipliers = mu
    return result


# --------------------------------------------------------------------------------------------
# Continuation
# --------------------------------------------------------------------------------------------
@dataclass
class FamilyPoint:
    """One orbit of a family: the parameter value and the search's result."""

    value: float
    result: OrbitResult


@dataclass
class StabilityChange:
    """Stability changes between two consecutive orbits of a family.

    ``at`` is the parameter value where the largest non-trivial multiplier modulus crosses 1
    (linear interpolation); ``kind`` says how the multiplier leaves the unit circle:
    ``"period doubling"`` (through -1), ``"fold"`` (through +1), ``"torus"`` (a complex pair).
    """

    between: tuple[float, float]
    at: float
    becomes: str  # "stable" or "unstable"
    kind: str
    multiplier: complex

    def describe(self, parameter: str) -> str:
        return (f"{parameter} ~ {self.at:.6g} (between {self.between[0]:.6g} and {self.between[1]:.6g}): becomes "
                f"{self.becomes}, {self.kind} (multiplier {self.multiplier.real:+.4f}{self.multiplier.imag:+.4f}j)")


@dataclass
class Family:
    """A family of orbits over a parameter (``continue_family``)."""

    parameter: str
    points: list[FamilyPoint]
    stability_changes: list[StabilityChange]
    complete: bool
    message: str

    def to_json(self) -> dict[str, Any]:
        return {
            "parameter": self.parameter,
            "complete": self.complete,
            "message": self.message,
            "points": [{"value": p.value, **p.result.to_json()} for p in self.points],
            "stability_changes": [{"between": list(c.between), "at": c.at, "becomes": c.becomes, "kind": c.kind,
                                   "multiplier": [c.multiplier.real, c.multiplier.imag]}
                                  for c in self.stability_changes],
        }


def continue_family(problem: OrbitProblem, parameter: str, start: float, stop: float, steps: int,
                    guess: Mapping[str, float] | Sequence[float] | np.ndarray, *, max_refinements: int = 4,
                    locate: int = 0, progress: Callable[[FamilyPoint], None] | None = None,
                    **solver: Any) -> Family:
    """Follow a family of orbits as ``parameter`` goes from ``start`` to ``stop`` in ``steps``
    equal steps, with a secant predictor (linear extrapolation of the last two orbits' unknowns
    in the parameter; the previous orbit for the second point) and the Newton corrector
    ``find_orbit(**solver)``. A failed correction halves the parameter step, up to
    ``max_refinements`` times, before the family is declared to end there.

    Stability changes are reported between consecutive orbits where the largest non-trivial
    multiplier modulus crosses 1, at the parameter where it crosses 1 by linear interpolation;
    ``locate`` > 0 first narrows each such interval by that many bisections (one orbit search
    each, warm-started by interpolation), so the change is placed within 2**-locate of a step.
    """
    if not problem.is_factory:
        raise OrbitError("continuation needs a system factory system(parameters) -> HybridSystem")
    if parameter in problem.free:
        raise OrbitError(f"the continuation parameter '{parameter}' cannot also be a free parameter")
    if isinstance(steps, bool) or not isinstance(steps, int) or steps < 1:
        raise OrbitError(f"steps must be an integer >= 1, got {steps!r}")
    for label, v in (("start", start), ("stop", stop)):
        if not isinstance(v, (int, float)) or not math.isfinite(v):
            raise OrbitError(f"continuation {label} must be a finite number, got {v!r}")
    if start == stop:
        raise OrbitError("continuation needs start != stop")
    base = dict(problem.parameters)
    x_guess = problem.state_vector(guess)
    grid = [float(v) for v in np.linspace(start, stop, steps + 1)]
    min_step = abs(grid[1] - grid[0]) / 2 ** max_refinements
    points: list[FamilyPoint] = []
    history: list[tuple[float, np.ndarray, dict[str, float]]] = []
    complete = True
    message = f"{steps + 1} orbit(s) from {parameter} = {start:g} to {stop:g}"
    i, value = 0, grid[0]
    while i < len(grid):
        params = dict(base)
        params[parameter] = value
        if len(history) >= 2:
            (v1, x1, p1), (v2, x2, p2) = history[-2], history[-1]
            w = (value - v2) / (v2 - v1)
            x_pred = x2 + w * (x2 - x1)
            for name in problem.free:
                params[name] = p2[name] + w * (p2[name] - p1[name])
        elif history:
            x_pred = history[-1][1].copy()
            for name in problem.free:
                params[name] = history[-1][2][name]
        else:
            x_pred = x_guess
        result = find_orbit(replace(problem, parameters=params), x_pred, **solver)
        if result.converged:
            point = FamilyPoint(value, result)
            points.append(point)
            history.append((value, result.fixed_point.copy(), dict(result.parameters)))
            if progress is not None:
                progress(point)
            if value == grid[i]:
                i += 1
            if i < len(grid):
                value = grid[i]
            continue
        if history:
            # Halve the step towards the failed value, down to 2**-max_refinements grid steps.
            last = history[-1][0]
            half = last + 0.5 * (value - last)
            if abs(half - last) >= min_step * (1 - 1e-9):
                value = half
                continue
        complete = False
        message = (f"the family ends near {parameter} = {value:g} (last orbit at {history[-1][0]:g}): "
                   f"{result.status}: {result.message}" if history else
                   f"no orbit at the start {parameter} = {value:g}: {result.status}: {result.message}")
        break
    changes = _stability_changes(points)
    if locate > 0 and changes:
        changes = [_locate_change(problem, parameter, points, c, locate, solver) for c in changes]
    return Family(parameter, points, changes, complete, message)


def _locate_change(problem: OrbitProblem, parameter: str, points: list[FamilyPoint], change: StabilityChange,
                   bisections: int, solver: Mapping[str, Any]) -> StabilityChange:
    """Narrow a stability change's interval by bisection on the parameter."""
    by_value = {p.value: p for p in points}
    lo, hi = by_value[change.between[0]], by_value[change.between[1]]
    for _ in range(bisections):
        mid_value = 0.5 * (lo.value + hi.value)
        w = 0.5
        params = dict(problem.parameters)
        params[parameter] = mid_value
        for name in problem.free:
            params[name] = (1 - w) * lo.result.parameters[name] + w * hi.result.parameters[name]
        x_mid = (1 - w) * lo.result.fixed_point + w * hi.result.fixed_point
        result = find_orbit(replace(problem, parameters=params), x_mid, **solver)
        if not result.converged or result.stable is None:
            break
        mid = FamilyPoint(mid_value, result)
        if (mid.result.stable) == (lo.result.stable):
            lo = mid
        else:
            hi = mid
    located = _stability_changes([lo, hi])
    return located[0] if located else change


def _stability_changes(points: list[FamilyPoint]) -> list[StabilityChange]:
    changes = []
    for a, b in zip(points, points[1:]):
        ra, rb = a.result.spectral_radius, b.result.spectral_radius
        if ra is None or rb is None or (ra < 1.0) == (rb < 1.0):
            continue
        at = a.value + (1.0 - ra) * (b.value - a.value) / (rb - ra)
        unstable = a.result if ra >= 1.0 else b.result
        mu = unstable.nontrivial_multipliers
        m = complex(mu[np.argmax(np.abs(mu))])  # type: ignore[index]
        if abs(m.imag) > 1e-9 * max(1.0, abs(m)):
            kind = "torus (complex pair leaves the unit circle)"
        elif m.real < 0:
            kind = "period doubling (multiplier through -1)"
        else:
            kind = "fold or branch point (multiplier through +1)"
        changes.append(StabilityChange((a.value, b.value), at, "unstable" if rb >= 1.0 else "stable", kind, m))
    return changes


# --------------------------------------------------------------------------------------------
# Scenes: the [orbit] section
# --------------------------------------------------------------------------------------------
#: Keys of a scene's ``[orbit]`` section and what they hold.
ORBIT_KEYS = {
    "section": "{ after = TRANSITION } or { mode = MODE, coordinate = NAME, value = 0.0, direction = "
               "'decreasing' | 'increasing' | 'either' }",
    "fixed": "coordinates held at their initial values (list of names)",
    "cyclic": "coordinates along a symmetry, left out of periodicity; their increment is the step length",
    "free": "parameters solved for: robot parameter names or EFFECT.PARAM",
    "energy": "energy level of the orbit (J), when the system defines an energy",
    "guess": "initial guess by coordinate (default: the scene's [initial] state)",
    "tol": "convergence tolerance on the orbit equations (state units), default 1e-9",
    "max_iterations": "Newton iterations, default 30",
    "jacobian": "'saltation' (default) or 'fd'",
    "fd_step": "relative finite-difference step in (0, 0.1], default 1e-6 (see legsim.orbits)",
    "singular_tol": "relative singular value below which the Jacobian is singular, default 1e-9",
    "t_max": "time limit of one return (s), default the scene's integrator.t_final",
    "returns": "returns per period (2 for a period-two orbit), default 1",
    "min_transitions": "transitions before a crossing section counts, default 1",
    "min_time": "time (s) before a crossing section counts, default 0",
    "max_transitions": "transition budget of one return, default 10000",
    "trivial_multipliers": "multipliers equal to 1 by a conserved quantity, left out of the stability verdict",
}


@dataclass
class OrbitSettings:
    """An orbit problem read from a scene, with the solver settings and the initial guess."""

    problem: OrbitProblem
    guess: np.ndarray
    solver: dict[str, Any]
    scene: Any


def _scene_fail(scene, key: str, message: str) -> LegsimError:
    from .errors import SceneError

    return SceneError(f"{scene.path}: orbit.{key}: {message}")


def _parameter_setter(scene, name: str, label: str = "orbit.free"):
    """(spec, value) of a real-valued robot parameter ``name`` or effect parameter
    ``EFFECT.PARAM``; errors name ``label`` (the [orbit] key, or the continued parameter)."""
    from .errors import SceneError

    def fail(message: str) -> LegsimError:
        return SceneError(f"{scene.path}: {label}: {message}")

    builder = scene.builder
    if "." in name:
        effect, param = name.split(".", 1)
        if effect not in builder.effects:
            raise fail(f"unknown effect '{effect}' in '{name}'; effects: {sorted(builder.effects)}")
        if effect not in scene.effects:
            raise fail(f"effect '{effect}' is switched off in this scene")
        schema = builder.effects[effect].parameters
        if param not in schema:
            raise fail(f"effect '{effect}' has no parameter '{param}'; parameters: {sorted(schema)}")
        spec = schema[param]
        value = scene.effects[effect][param]
    else:
        if name not in builder.parameters:
            raise fail(f"robot '{scene.robot}' has no parameter '{name}'; parameters: {sorted(builder.parameters)}")
        spec = builder.parameters[name]
        value = scene.parameters[name]
    if type(spec.default) is not float:
        raise fail(f"parameter '{name}' is {type(spec.default).__name__}-valued; only real parameters can be "
                   f"solved for or continued")
    return spec, float(value)


def problem_from_scene(scene: Any, *, extra_parameters: Sequence[str] = ()) -> OrbitSettings:
    """Read a scene's ``[orbit]`` section (keys: ``ORBIT_KEYS``) into an ``OrbitProblem``.

    The system is rebuilt by the scene's builder for each value of the free (and
    ``extra_parameters``, e.g. a continuation parameter) parameters; h, eps and method come
    from ``[integrator]``, the initial guess from ``[initial]`` (overridden by ``orbit.guess``),
    whose mode must be the section's. Errors are ``SceneError`` naming the file and key.
    """
    from .builders import resolve_parameters

    table = scene.sections.get("orbit")
    if table is None:
        raise _scene_fail(scene, "section", "the scene has no [orbit] section; add one, e.g. [orbit] "
                                            "section = { after = \"touchdown\" }")
    unknown = sorted(set(table) - set(ORBIT_KEYS))
    if unknown:
        raise _scene_fail(scene, unknown[0], f"unknown key(s) {unknown}; allowed: {sorted(ORBIT_KEYS)}")
    sec = table.get("section")
    if not isinstance(sec, dict):
        raise _scene_fail(scene, "section", f"missing or not a table; expected {ORBIT_KEYS['section']}")
    try:
        if "after" in sec:
            if set(sec) != {"after"}:
                raise _scene_fail(scene, "section", f"'after' takes no other keys, got {sorted(sec)}")
            section = Section.after(sec["after"])
        else:
            allowed = {"mode", "coordinate", "value", "direction"}
            bad = sorted(set(sec) - allowed)
            if bad or "coordinate" not in sec:
                raise _scene_fail(scene, "section", f"expected {ORBIT_KEYS['section']}, got keys {sorted(sec)}")
            value = sec.get("value", 0.0)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise _scene_fail(scene, "section.value", f"expected a number, got {value!r}")
            section = Section.level(sec.get("mode", scene.initial_mode), sec["coordinate"], value,
                                    sec.get("direction", "decreasing"))
    except OrbitError as exc:
        raise _scene_fail(scene, "section", str(exc)) from None

    def names(key: str) -> tuple[str, ...]:
        value = table.get(key, [])
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise _scene_fail(scene, key, f"expected a list of names, got {value!r}")
        return tuple(value)

    def number(key: str, default, kind=float, low=None):
        value = table.get(key, default)
        if value is None:
            return None
        if isinstance(value, bool) or not isinstance(value, (int, float)) or (kind is int and not isinstance(value, int)):
            raise _scene_fail(scene, key, f"expected {'an integer' if kind is int else 'a number'}, got {value!r}")
        if not math.isfinite(value) or (low is not None and value < low):
            raise _scene_fail(scene, key, f"must be finite{'' if low is None else f' and >= {low}'}, got {value!r}")
        return kind(value)

    free = names("free")
    params: dict[str, float] = {}
    specs = {}
    for name in tuple(free) + tuple(extra_parameters):
        spec, value = _parameter_setter(scene, name, "orbit.free" if name in free else "continued parameter")
        specs[name] = spec
        params[name] = value
    base_params = dict(scene.parameters)
    base_effects = {k: dict(v) for k, v in scene.effects.items()}
    builder = scene.builder
    where = f"{scene.path}: orbit"

    def factory(values: Mapping[str, float]):
        p = dict(base_params)
        e = {k: dict(v) for k, v in base_effects.items()}
        for name, value in values.items():
            if "." in name:
                effect, param = name.split(".", 1)
                e[effect][param] = specs[name].check(float(value), f"{where}: effects.{name}")
            else:
                p[name] = specs[name].check(float(value), f"{where}: robot.parameters.{name}")
        p = resolve_parameters(builder.parameters, p, f"{where}: robot.parameters")
        return builder.build(p, e)

    jacobian = table.get("jacobian", "saltation")
    if jacobian not in ("saltation", "fd"):
        raise _scene_fail(scene, "jacobian", f"expected 'saltation' or 'fd', got {jacobian!r}")
    energy = number("energy", None)
    integ = scene.integrator
    try:
        problem = OrbitProblem(
            system=factory if params else scene.model, section=section, h=integ["h"], eps=integ["eps"],
            method=integ["method"], t_max=number("t_max", integ["t_final"], low=0.0),
            parameters=params, free=free, fixed=names("fixed"), cyclic=names("cyclic"), energy=energy,
            returns=number("returns", 1, int, 1), min_transitions=number("min_transitions", 1, int, 0),
            min_time=number("min_time", 0.0, low=0.0), max_transitions=number("max_transitions", 10_000, int, 1),
            trivial_multipliers=number("trivial_multipliers", 0, int, 0))
    except OrbitError as exc:
        if exc.key in ("h", "eps"):  # they come from [integrator]
            from .errors import SceneError
            raise SceneError(f"{scene.path}: integrator.{exc.key}: {exc}") from None
        raise _scene_fail(scene, exc.key or "section", str(exc)) from None
    if problem.bound.mode != scene.initial_mode:
        raise _scene_fail(scene, "section", f"the section lies in mode '{problem.bound.mode}' but the scene starts "
                                            f"in '{scene.initial_mode}': set [initial] mode = \"{problem.bound.mode}\"")
    x0 = np.asarray(scene.initial_state, dtype=float).copy()
    guess = table.get("guess", {})
    if not isinstance(guess, dict):
        raise _scene_fail(scene, "guess", f"expected a table of coordinate = number, got {guess!r}")
    for key, value in guess.items():
        if key not in problem.names:
            raise _scene_fail(scene, "guess", f"unknown coordinate '{key}'; coordinates: {list(problem.names)}")
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise _scene_fail(scene, f"guess.{key}", f"expected a finite number, got {value!r}")
        x0[problem.names.index(key)] = float(value)
    solver = {"tol": number("tol", 1e-9, low=0.0), "max_iterations": number("max_iterations", 30, int, 0),
              "jacobian": jacobian, "fd_step": number("fd_step", None, low=0.0),
              "singular_tol": number("singular_tol", 1e-9, low=0.0)}
    if solver["tol"] == 0:
        raise _scene_fail(scene, "tol", "must be > 0")
    if solver["fd_step"] is not None and not 0.0 < solver["fd_step"] <= MAX_FD_STEP:
        raise _scene_fail(scene, "fd_step", f"must be a relative step in (0, {MAX_FD_STEP:g}], got {solver['fd_step']!r}")
    return OrbitSettings(problem, problem.state_vector(x0), solver, scene)
