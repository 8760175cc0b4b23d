"""The orbit problem: a system (or a factory of systems over parameters), a section, the
integrator settings and the unknowns, checked once when the problem is made.

The unknowns are the coordinates of the section's mode that are neither fixed, cyclic nor the
section's own coordinate, then the free parameters; the equations (``legsim.orbits.newton``)
are periodicity on the non-cyclic coordinates other than the section's, s(x) = 0 for a section
given as a function, the constraints and the energy level. A problem with fewer equations than
unknowns is refused here, before any simulation.

A problem with a ``controller`` (a ``legsim.control.Controller`` with memory, or a
``legsim.control.ControlLaw``, such as a Raibert hopper's with its last stance duration)
searches the return map of the closed loop on the section state *and* the controller's memory:
every return starts with a fresh controller restored to the memory guess (a law's memory starts
the run's state) and reads the memory back at the return. The memory values join the unknowns
(after the free coordinates) and ``memory' - memory = 0`` the periodicity equations; the
multipliers are those of this augmented map.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..arguments import count
from ..control import ControlLaw, Controller
from ..errors import LegsimError, SimulationError
from ..execution import Execution, TransitionRecord
from ..hybrid import HybridSystem
from ..methods import Tableau, get_method
from ..relaxed.simulate import landing_part, step_size_rule
from .errors import OrbitError
from .sections import Section, bind_section

#: Most steps of size h over t_max that one return may take (``legsim.simulate`` makes about
#: 2e4 RK4 steps per second on the robots, so this is minutes per simulation): more is a typo
#: in h or t_max, not a computation to start.
MAX_STEPS_PER_RETURN = 10_000_000

#: Systems built for distinct parameter values that a problem keeps (Newton and finite
#: differences revisit a handful of values; continuation moves on and never comes back).
_CACHE_SIZE = 16

SystemLike = Any  # HybridSystem, (HybridSystem, control), a builders.Model, or a factory of these


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
    step_length: the distance covered (m), when the problem defines one.
    memory_start, memory_end: the controller's memory at the start and at the return (epochs and
        positions in the start's frame, ``ReturnMap._to_start_frame``), shape (m,)
        (empty without a controller).
    memory_noted: which memory entries the return changed (noted anew), shape (m,) bool; an
        entry it did not change is left in the start's frame.
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
    memory_start: np.ndarray = field(default_factory=lambda: np.empty(0))
    memory_end: np.ndarray = field(default_factory=lambda: np.empty(0))
    memory_noted: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=bool))

    @property
    def start(self) -> np.ndarray:
        """The augmented start (x_start, memory_start), shape (n + m,)."""
        return np.concatenate([self.x_start, self.memory_start])

    @property
    def end(self) -> np.ndarray:
        """The augmented return (x_end, memory_end), shape (n + m,)."""
        return np.concatenate([self.x_end, self.memory_end])


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
    controller: ``controller(model) -> legsim.control.Controller``, a fresh controller for the
        object the system (or the factory) gives, a ``builders.Model`` from a scene; its memory
        (``memory_names``) must be declared. It replaces any control, as in ``legsim run``.
    parameters: parameter values passed to the factory (initial guesses for the free ones).
    free: names of parameters solved for (unknowns besides the state).
    fixed: coordinates held at their initial values (e.g. the apex height), or controller memory
        values held at their guesses (where the controller conserves a combination of them). The
        coordinate of a coordinate section is always fixed.
    cyclic: coordinates along a symmetry (a horizontal position): fixed, left out of the
        periodicity equations, their increment over a return is the step length. Each name in
        ``free``, ``fixed`` and ``cyclic`` appears once, none both fixed and cyclic, not the
        coordinate of a coordinate section, and at least one multiplier must remain.
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
    rtol, atol: passed to ``simulate`` for error-controlled steps (embedded methods only: bs32,
        dopri5, dop853); h is then the first and largest step. Without them every step starts
        from h.
    landing: how ``simulate`` shortens a step that would leave the relaxed domain: ``"halve"``,
        ``"aim"`` or ``"dense"`` (methods with a continuous extension).
    max_halvings: most halvings of one step (``simulate``'s budget).
    progress: optional ``progress(t, t0, t_final)`` passed to every ``simulate`` (a progress
        bar for long returns).

    Attributes set from these: ``tableau``, ``integrator_settings`` (what every return runs
    with, tolerances as ``simulate`` completes them), ``is_factory``, ``bound`` (the bound section),
    ``names`` and ``dim`` (the section mode's coordinates), ``cyclic_idx``, ``unknown_idx``
    (coordinates solved for) and ``periodic_idx`` (coordinates asked to return to themselves);
    ``memory_names``, ``memory_units`` and ``memory_guess`` (a fresh controller's memory, shape
    (m,); m = 0 without a controller).
    """

    system: SystemLike
    section: Section
    h: float
    eps: float
    method: str | Tableau = "rk4"
    t_max: float = 10.0
    control: Callable[[float, np.ndarray], Any] | None = None
    controller: Callable[[Any], Controller] | None = None
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
    step_length: Callable[[Return], float] | None = None
    trivial_multipliers: int = 0
    rtol: float | None = None
    atol: float | None = None
    landing: str = "halve"
    max_halvings: int = 64
    progress: Callable[[float, float, float], None] | None = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        self._check_settings()
        self._resolve_system()
        self._check_name_lists()
        self._cache: dict[tuple, tuple[HybridSystem, Any, Any]] = {}
        system, _ = self.instantiate(self.parameters)
        self._check_controller()
        self._bind(system)
        self._check_equations(system)

    # -- checks, in the order a reader fixes them: settings, system, coordinates, equations --
    def _check_settings(self) -> None:
        for name in ("h", "eps", "t_max"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
                raise OrbitError(f"orbit problem: {name} must be a finite number > 0, got {value!r}", key=name)
        if self.rtol is None and self.atol is None and self.t_max / self.h > MAX_STEPS_PER_RETURN:
            raise OrbitError(
                f"orbit problem: t_max / h = {self.t_max:g} s / {self.h:g} s = {self.t_max / self.h:.3g} "
                f"steps per return, more than the limit {MAX_STEPS_PER_RETURN:.0e}: raise h or lower "
                f"t_max",
                key="t_max",
            )
        self.tableau = get_method(self.method)
        self._check_integrator()
        if not isinstance(self.section, Section):
            raise OrbitError(f"orbit problem: section must be a Section, got {type(self.section).__name__}")
        for name, low in (("returns", 1), ("max_transitions", 1), ("min_transitions", 0)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise OrbitError(f"orbit problem: {name} must be an integer >= {low}, got {value!r}", key=name)
        if self.section.kind == "transition" and (self.min_transitions != 1 or self.min_time != 0.0):
            raise OrbitError(
                "orbit problem: min_transitions and min_time count crossings of a level section; a "
                "Section.after returns at each such transition and takes neither",
                key="min_transitions" if self.min_transitions != 1 else "min_time",
            )
        if self.section.kind == "crossing" and self.min_transitions == 0 and self.min_time <= 0:
            raise OrbitError(
                "orbit problem: a crossing section with min_transitions = 0 needs min_time > 0, "
                "or the start itself would count as the return",
                key="min_transitions",
            )

    def _check_integrator(self) -> None:
        """Refuse, before any simulation, what ``simulate`` would refuse at the first return: a
        tolerance without an embedded pair, a landing the method cannot do, a halving budget
        below 1. The ``OrbitError``'s key names the setting."""
        checks = (
            (
                "rtol" if self.rtol is not None else "atol",
                lambda: step_size_rule(self.tableau, self.h, self.rtol, self.atol),
            ),
            ("landing", lambda: landing_part(self.landing, self.tableau)),
            ("max_halvings", lambda: count("max_halvings", self.max_halvings, 1)),
        )
        rules = []
        for key, check in checks:
            try:
                rules.append(check())
            except SimulationError as exc:
                raise OrbitError(f"orbit problem: {exc}", key=key) from None
        self._tolerances: tuple[float | None, float | None] = rules[0]  # type: ignore[assignment]  # (rtol, atol) as simulate will use them, (None, None) for fixed steps

    @property
    def integrator_settings(self) -> dict[str, Any]:
        """The settings every return is simulated with (the keys of ``legsim orbit --json``'s
        ``integrator``): method, h (s, the largest step under error control), eps (guard
        units), rtol and atol as ``simulate`` uses them (one given alone sets the other; both
        None for fixed steps), landing, max_halvings."""
        return {
            "method": self.tableau.name,
            "h": float(self.h),
            "eps": float(self.eps),
            "rtol": self._tolerances[0],
            "atol": self._tolerances[1],
            "landing": self.landing,
            "max_halvings": self.max_halvings,
        }

    @property
    def integrator_label(self) -> str:
        """``integrator_settings`` in one line for reports (``describe_integrator``)."""
        return describe_integrator(self.integrator_settings)

    def _resolve_system(self) -> None:
        self.parameters = {str(k): float(v) for k, v in dict(self.parameters).items()}
        self.free = tuple(self.free)
        self.fixed = tuple(self.fixed)
        self.cyclic = tuple(self.cyclic)
        # ``system`` stays as given (a Model, which a controller is made for, survives
        # ``dataclasses.replace``); the HybridSystem and control it holds are kept apart.
        self._fixed, self._fixed_control = _system_and_control(self.system, self.control)
        self.is_factory = not isinstance(self._fixed, HybridSystem)
        if self.is_factory and not callable(self._fixed):
            raise OrbitError(
                f"orbit problem: system must be a HybridSystem, a Model or a factory "
                f"system(parameters), got {type(self._fixed).__name__}"
            )
        missing = [p for p in self.free if p not in self.parameters]
        if missing:
            raise OrbitError(
                f"orbit problem: free parameter(s) {missing} need initial values in parameters "
                f"(given: {sorted(self.parameters)})",
                key="free",
            )
        if self.free and not self.is_factory:
            raise OrbitError(
                "orbit problem: free parameters need a system factory system(parameters) -> "
                "HybridSystem, not a fixed HybridSystem"
            )

    def _check_name_lists(self) -> None:
        """Each name at most once in ``free``, ``fixed`` and ``cyclic``, none both fixed and cyclic,
        and not the coordinate of a coordinate section as cyclic: that coordinate is held on the
        section, and a cyclic one is free to drift, so it cannot be both. Each would otherwise
        reach the solver as a duplicated unknown or a dropped equation, and fail there as a
        singular Jacobian that does not name the list at fault."""
        for label in ("free", "fixed", "cyclic"):
            group = getattr(self, label)
            repeated = sorted({name for name in group if group.count(name) > 1})
            if repeated:
                raise OrbitError(
                    f"orbit problem: {label} lists {repeated} more than once; each name may appear once", key=label
                )
        both = sorted(set(self.fixed) & set(self.cyclic))
        if both:
            raise OrbitError(
                f"orbit problem: {both} are both fixed and cyclic (a cyclic coordinate is already held at its "
                f"start); list each in one of fixed or cyclic",
                key="fixed",
            )
        if self.section.coordinate is not None and self.section.coordinate in self.cyclic:
            raise OrbitError(
                f"orbit problem: '{self.section.coordinate}' is the section's coordinate, held at its value on the "
                f"section, so it cannot be cyclic; cyclic may list the other coordinates",
                key="cyclic",
            )

    def _bind(self, system: HybridSystem) -> None:
        self.bound = bind_section(self.section, system)
        names = self.bound.names
        for label, group in (("fixed", self.fixed), ("cyclic", self.cyclic)):
            held_memory = self.memory_names if label == "fixed" else ()
            unknown = [c for c in group if c not in names and c not in held_memory]
            if unknown:
                raise OrbitError(
                    f"orbit problem: {label} coordinate(s) {unknown} are not coordinates of mode "
                    f"'{self.bound.mode}' {list(names)}",
                    key=label,
                )
        self.names = names
        self.dim = len(names)
        self._check_frames()
        self.cyclic_idx = [names.index(c) for c in self.cyclic]
        held = set(self.fixed) | set(self.cyclic)
        if self.section.coordinate is not None:
            held.add(self.section.coordinate)
        self.unknown_idx = [i for i, c in enumerate(names) if c not in held]
        self.periodic_idx = [
            i for i, c in enumerate(names) if i not in self.cyclic_idx and c != self.section.coordinate
        ]

    def _check_controller(self) -> None:
        """Make one controller and read its memory's names, units and values (the guess)."""
        self.memory_names: tuple[str, ...] = ()
        self.memory_units: tuple[str, ...] = ()
        self.memory_frames: tuple[str, ...] = ()
        self.memory_guess = np.empty(0)
        if self.controller is None:
            return
        made = self.make_controller(self.parameters)
        if made.memory_names is None:
            raise OrbitError(
                f"orbit problem: controller {type(made).__name__} does not declare its memory, so the "
                f"return map of the closed loop is not known to be a function of the section state: "
                f"give it memory_names, memory_units, memory() and restore(mode, memory) "
                f"(legsim.control.Controller), or memory_names = () if it keeps no state",
                key="controller",
            )
        self.memory_names = tuple(made.memory_names)
        self.memory_units = tuple(made.memory_units)
        self.memory_frames = self._frames_of(made)
        self.memory_guess = self._memory_of(made)

    def _frames_of(self, controller: Controller | ControlLaw) -> tuple[str, ...]:
        """What each memory value is measured from (``ControlLaw.memory_frames``): "" nothing, "t"
        the clock, or a coordinate; () from a controller means all "" (checked in ``_bind``)."""
        frames = tuple(str(f) for f in (getattr(controller, "memory_frames", ()) or ()))
        return frames or ("",) * len(self.memory_names)

    def _check_frames(self) -> None:
        """Each memory frame is "", "t" or a coordinate of the section's mode, one per value."""
        unknown = [f for f in self.memory_frames if f not in ("", "t") and f not in self.names]
        if len(self.memory_frames) != len(self.memory_names) or unknown:
            raise OrbitError(
                f"orbit problem: the controller's memory_frames {list(self.memory_frames)}: expected one of "
                f"'', 't' or a coordinate of mode '{self.bound.mode}' ({list(self.names)}) per memory value "
                f"{list(self.memory_names)}",
                key="controller",
            )

    def _memory_of(self, controller: Controller | ControlLaw) -> np.ndarray:
        """``controller.memory()`` (a law's initial memory) checked against its names: finite,
        shape (m,)."""
        if isinstance(controller, ControlLaw):
            memory = np.asarray(controller.initial_memory, dtype=float)
        else:
            memory = np.asarray(controller.memory(), dtype=float).reshape(-1)
        if memory.shape != (len(self.memory_names),) or len(self.memory_units) != len(self.memory_names):
            raise OrbitError(
                f"orbit problem: controller {type(controller).__name__} has memory_names "
                f"{list(self.memory_names)} and units {list(self.memory_units)} but memory() "
                f"returned {memory.size} values",
                key="controller",
            )
        if not np.all(np.isfinite(memory)):
            raise OrbitError(f"orbit problem: the controller's memory is not finite: {memory.tolist()}")
        return memory

    def _check_equations(self, system: HybridSystem) -> None:
        n_rows = len(self.periodic_idx) + self.extra_rows + self.n_memory
        n_unknowns = len(self.unknown_idx) + len(self.free) + len(self.unknown_memory_idx)
        # First: cyclic coordinates that leave no multipliers also leave few unknowns, and the
        # list to name is cyclic, not fixed or free.
        self._check_multipliers()
        if n_unknowns == 0:
            raise OrbitError(
                "orbit problem: nothing to solve for: every coordinate is fixed and no parameter is free", key="fixed"
            )
        if n_rows < n_unknowns:
            raise OrbitError(
                f"orbit problem: {n_unknowns} unknowns ({self.unknown_names}) but only {n_rows} "
                f"equations: fix coordinates or drop free parameters",
                key="free",
            )
        if self.energy is not None and system.energy is None:
            raise OrbitError(
                f"orbit problem: an energy level is asked for but {system.name} defines no energy", key="energy"
            )
        for item in self.constraints:
            if not (isinstance(item, tuple) and len(item) == 2 and callable(item[1])):
                raise OrbitError(f"orbit problem: constraints must be (name, c(x, parameters)) pairs, got {item!r}")

    def _check_multipliers(self) -> None:
        """``cyclic`` and ``trivial_multipliers`` leave at least one multiplier for the stability
        verdict: with none, a spectral radius of 0 would call any orbit stable."""
        # Multipliers live on the section without the cyclic coordinates, with the memory:
        # n - 1 - #cyclic + m of them.
        n_multipliers = self.dim - 1 - len(self.cyclic_idx) + self.n_memory
        if self.cyclic and n_multipliers < 1:
            raise OrbitError(
                f"orbit problem: cyclic = {list(self.cyclic)} leaves none of the section's multipliers to judge "
                f"stability by (a section of {self.dim} coordinates with c cyclic ones has {self.dim} - 1 - c"
                + (f" + {self.n_memory} (memory)" if self.n_memory else "")
                + f" multipliers): at most {self.dim - 2 + self.n_memory} coordinate(s) may be cyclic",
                key="cyclic",
            )
        trivial = self.trivial_multipliers
        if (
            isinstance(trivial, bool)
            or not isinstance(trivial, int)
            or trivial < 0
            or (trivial > 0 and trivial >= n_multipliers)
        ):
            raise OrbitError(
                f"orbit problem: trivial_multipliers = {trivial!r} must be an integer >= 0 that leaves "
                f"at least one of the section's {n_multipliers} multiplier(s) to judge stability by",
                key="trivial_multipliers",
            )

    # -- what the solver reads ----------------------------------------------------------------
    @property
    def n_memory(self) -> int:
        """m, the number of the controller's memory values (0 without a controller)."""
        return len(self.memory_names)

    @property
    def unknown_memory_idx(self) -> list[int]:
        """Indices in the memory of the values solved for (those not ``fixed``)."""
        return [i for i, name in enumerate(self.memory_names) if name not in self.fixed]

    @property
    def unknown_names(self) -> list[str]:
        """Names of the unknowns: free coordinates, the controller's memory, free parameters."""
        memory = [self.memory_names[i] for i in self.unknown_memory_idx]
        return [self.names[i] for i in self.unknown_idx] + memory + list(self.free)

    @property
    def augmented_unknown_idx(self) -> list[int]:
        """Indices of the unknown coordinates and memory values in the augmented state (x,
        memory)."""
        return list(self.unknown_idx) + [self.dim + i for i in self.unknown_memory_idx]

    @property
    def augmented_periodic_idx(self) -> list[int]:
        """Indices in (x, memory) asked to return to themselves: the periodic coordinates and
        every memory value."""
        return list(self.periodic_idx) + [self.dim + i for i in range(self.n_memory)]

    def make_controller(self, parameters: Mapping[str, float] | None = None) -> Controller | ControlLaw:
        """A fresh controller for the system at these parameter values (``controller`` must be
        set); OrbitError when it is neither a ``legsim.control.Controller`` nor a ``ControlLaw``."""
        assert self.controller is not None
        self.instantiate(parameters)
        made = self.controller(self.system if not self.is_factory else self._cached(parameters)[2])
        if not isinstance(made, (Controller, ControlLaw)):
            raise OrbitError(
                f"orbit problem: controller(model) made {type(made).__name__}, expected a legsim.control.Controller "
                f"or ControlLaw",
                key="controller",
            )
        return made

    def restored_controller(
        self, parameters: Mapping[str, float] | None, memory: np.ndarray | None
    ) -> Controller | ControlLaw:
        """A fresh controller restored to ``memory`` (default ``memory_guess``) at the section's
        mode: what one return runs with (a ``ControlLaw`` as it is: its memory starts the run's
        state)."""
        made = self.make_controller(parameters)
        if isinstance(made, ControlLaw):
            return made
        made.restore(self.bound.mode, self.memory_guess if memory is None else np.asarray(memory, dtype=float))
        return made

    @property
    def has_section_row(self) -> bool:
        """Whether s(x) = 0 is an equation: for a crossing section given as a function (a
        coordinate section holds its coordinate on the section instead)."""
        return self.section.kind == "crossing" and self.section.coordinate is None

    @property
    def extra_rows(self) -> int:
        """Equations that need no simulation: the section row, the constraints, the energy."""
        return int(self.has_section_row) + len(self.constraints) + int(self.energy is not None)

    def instantiate(self, parameters: Mapping[str, float] | None = None) -> tuple[HybridSystem, Any]:
        """(system, control) for these parameter values (cached); the fixed system and control
        when the problem has no factory."""
        if not self.is_factory:
            return self._fixed, self._fixed_control
        system, control, _ = self._cached(parameters)
        return system, control

    def _cached(self, parameters: Mapping[str, float] | None) -> tuple[HybridSystem, Any, Any]:
        """(system, control, what the factory returned) for these parameter values."""
        params = dict(self.parameters)
        if parameters:
            params.update({k: float(v) for k, v in parameters.items()})
        key = tuple(sorted(params.items()))
        hit = self._cache.get(key)
        if hit is not None:
            return hit
        built = self._build(params)
        if len(self._cache) > _CACHE_SIZE:
            self._cache.clear()
        self._cache[key] = built
        return built

    def _build(self, params: dict[str, float]) -> tuple[HybridSystem, Any, Any]:
        """Call the factory; its failures become ``simulation_failed`` errors (a parameter value
        the model refuses ends a continuation like a failed simulation does)."""
        try:
            built = self._fixed(params)
        except OrbitError:
            raise
        except LegsimError as exc:
            raise OrbitError(f"orbit problem: no system for parameters {params}: {exc}", "simulation_failed") from exc
        except Exception as exc:
            raise OrbitError(
                f"orbit problem: building the system with parameters {params} failed: {type(exc).__name__}: {exc}",
                "simulation_failed",
            ) from exc
        system, control = _system_and_control(built, self.control)
        if not isinstance(system, HybridSystem):
            raise OrbitError(
                f"orbit problem: the system factory returned {type(built).__name__}, expected a "
                f"HybridSystem, (HybridSystem, control) or a builders.Model"
            )
        return system, control, built

    def state_vector(self, guess: Mapping[str, float] | Sequence[float] | np.ndarray) -> np.ndarray:
        """A full state of the section's mode, shape (n,), from a vector or a {coordinate: value}
        table; a coordinate section's coordinate is set to the section's value."""
        x = self._guess_from_table(guess) if isinstance(guess, Mapping) else self._guess_from_vector(guess)
        if not np.all(np.isfinite(x)):
            raise OrbitError(f"initial guess must be finite, got {x.tolist()}")
        if self.section.coordinate is not None:
            x[self.bound.index] = self.section.value
        return x

    def _guess_from_table(self, guess: Mapping[str, float]) -> np.ndarray:
        unknown = sorted(set(guess) - set(self.names))
        if unknown:
            raise OrbitError(
                f"initial guess: unknown coordinate(s) {unknown}; coordinates of mode "
                f"'{self.bound.mode}': {list(self.names)}"
            )
        missing = [c for c in self.names if c not in guess and c != self.section.coordinate]
        if missing:
            raise OrbitError(f"initial guess: missing coordinate(s) {missing} of mode '{self.bound.mode}'")
        return np.array([float(guess.get(c, self.section.value)) for c in self.names])

    def _guess_from_vector(self, guess: Sequence[float] | np.ndarray) -> np.ndarray:
        x = np.asarray(guess, dtype=float).reshape(-1)
        if x.shape != (self.dim,):
            raise OrbitError(
                f"initial guess has shape {np.shape(guess)}, expected ({self.dim},) with "
                f"coordinates {list(self.names)} of mode '{self.bound.mode}'"
            )
        return x


def describe_integrator(settings: Mapping[str, Any]) -> str:
    """One line for reports from ``OrbitProblem.integrator_settings``: the method, its steps
    (h, or the tolerances and the largest step h), eps and the landing."""
    if settings["rtol"] is None:
        steps = f"h = {settings['h']:g} s"
    else:
        steps = f"rtol = {settings['rtol']:g}, atol = {settings['atol']:g}, largest step h = {settings['h']:g} s"
    return f"{settings['method']}, {steps}, eps = {settings['eps']:g}, landing '{settings['landing']}'"


def _system_and_control(obj: Any, control: Any) -> tuple[Any, Any]:
    """(system, control) of a ``(system, control)`` pair or a ``builders.Model``; ``obj`` with
    ``control`` for anything else (a HybridSystem, or a factory still to be called)."""
    if isinstance(obj, tuple) and len(obj) == 2:
        return obj[0], obj[1]
    if not isinstance(obj, HybridSystem) and isinstance(getattr(obj, "system", None), HybridSystem):
        return obj.system, getattr(obj, "control", None)
    return obj, control
