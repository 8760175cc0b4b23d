"""Controllers as parts of a run: an object that knows the mode, may keep state across
transitions, and is either evaluated at every stage of a step or held over it.

A plain ``control(t, x) -> u`` still works wherever a control is taken. A ``Controller``:

* ``__call__(mode, t, x) -> u``: the input in mode ``mode`` at (t, x);
* ``reset(mode, t, x)``: called when the run enters a mode (at the start and after every
  transition), so a controller can update internal state at transitions (a Raibert hopper
  plans its next foot placement at liftoff);
* ``hold``: False evaluates it at every stage of a Runge-Kutta step (a time-varying input keeps
  the method's order); True holds u(t_k) over the step from t_k, a zero-order hold as the papers'
  digital controllers (paper 000 Fig. 1).

A controller whose state influences the future declares it as its *memory*, so that ``legsim
orbit`` can search the closed loop (``legsim.orbits``: the return map acts on the section state
and the memory together):

* ``memory_names`` and ``memory_units``: one name and unit per value (``("T_s",)``, ``("s",)``);
  ``None`` (the default) leaves the memory undeclared, and the orbit search refuses the
  controller; a stateless controller declares ``()``;
* ``memory() -> np.ndarray``: the values now, shape (len(memory_names),);
* ``restore(mode, memory)``: set them before a run that starts in ``mode``. Everything else the
  controller keeps must be set by the run itself before it is used (a touchdown time is written
  when the stance is entered), and the memory may change only in ``reset``, at mode entries.

Scenes name controllers by a registry (the ``legsim.controllers`` entry-point group, like
robots): a ``ControllerSpec`` names its parameters and makes a ``Controller`` for a model.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from importlib import metadata
from typing import Any

import numpy as np

from .builders import Model, Param, resolve_parameters
from .errors import LegsimError, ModelError, SceneError
from .registry import load_registered, registered

ENTRY_POINT_GROUP = "legsim.controllers"


class Controller:
    """Base class of controllers (see the module docstring). Subclasses define ``__call__``
    and, when they keep state, ``reset``."""

    hold: bool = False
    #: Names and units of the values ``memory()`` returns (module docstring); None: undeclared.
    memory_names: tuple[str, ...] | None = None
    memory_units: tuple[str, ...] = ()
    #: What each memory value is measured from ("", "t" or a coordinate: ``ControlLaw``); () all "".
    memory_frames: tuple[str, ...] = ()

    def reset(self, mode: str, t: float, x: np.ndarray) -> None:
        """Entering ``mode`` at (t, x): update internal state (nothing by default)."""

    def memory(self) -> np.ndarray:
        """The values of ``memory_names`` now, shape (len(memory_names),) (none by default)."""
        return np.empty(0)

    def restore(self, mode: str, memory: np.ndarray) -> None:
        """Set the memory to ``memory`` (shape as ``memory()``) before a run starting in ``mode``."""

    def __call__(self, mode: str, t: float, x: np.ndarray) -> Any:
        raise NotImplementedError

    @property
    def input_source(self) -> Controller:
        """The controller whose input this one returns: itself, or for a wrapper that only
        observes (``legsim.orbits``' memory log) the wrapped one."""
        return self


@dataclass(frozen=True)
class ControlLaw:
    """A controller written once, as functions over arrays that the Python loop and the compiled
    kernel both call (``legsim.model``'s conventions):

    * ``control(t, x, m, p, u)``: the input into u (``inputs`` entries) at the plant's state x in
      the current mode, from the memory m and the mode's parameters p;
    * ``enter(t, x, m, p, m_new)``: entering a mode (at the start and after every transition),
      the new memory into m_new from the old one (a hopper measures its stance time); None: the
      memory never changes.

    The memory is part of the run's hybrid state: the state of every mode is the plant's followed
    by the memory's ``memory_names`` (units ``memory_units``), which executions, recordings, orbit
    searches and sweeps see; ``initial_memory`` is where a run starts it unless its initial
    state gives it. ``params(mode)`` gives the controller's parameter array in each mode (gains,
    which legs are in stance there; float64). ``hold``: sample the input once per step (a
    zero-order hold, a digital controller) instead of at every stage. ``memory_frames``: what
    each memory entry is measured from, "" (nothing: a gain, a duration, a flag; the default),
    "t" (an epoch on the run's clock, such as a touchdown time) or a plant coordinate's name (a
    position along it, such as the body's x at a touchdown); an orbit search expresses such
    entries in each return's own clock and place (``legsim.orbits.returns``).
    """

    name: str
    control: Callable[..., None]
    inputs: int
    params: Callable[[str], Any]
    enter: Callable[..., None] | None = None
    memory_names: tuple[str, ...] = ()
    memory_units: tuple[str, ...] = ()
    initial_memory: tuple[float, ...] = ()
    hold: bool = False
    memory_frames: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        where = f"controller {self.name}"
        if not callable(self.control) or (self.enter is not None and not callable(self.enter)):
            raise ModelError(f"{where}: control and enter must be functions")
        if not callable(self.params):
            raise ModelError(f"{where}: params must be a function params(mode) -> parameter array")
        names = tuple(str(n) for n in self.memory_names)
        units = tuple(str(u) for u in self.memory_units) or ("",) * len(names)
        initial = tuple(float(v) for v in self.initial_memory) or (0.0,) * len(names)
        if len(units) != len(names) or len(initial) != len(names) or len(set(names)) != len(names):
            raise ModelError(
                f"{where}: memory_names {names}, memory_units {units} and initial_memory {initial} must have "
                f"one unique name, a unit and a value per memory entry"
            )
        if names and self.enter is None:
            raise ModelError(f"{where}: a controller with memory {names} needs an enter function to change it")
        object.__setattr__(self, "memory_names", names)
        object.__setattr__(self, "memory_units", units)
        object.__setattr__(self, "initial_memory", initial)
        frames = tuple(str(f) for f in self.memory_frames) or ("",) * len(names)
        if len(frames) != len(names):
            raise ModelError(f"{where}: memory_frames {frames} must have one entry per memory entry {names}")
        object.__setattr__(self, "memory_frames", frames)

    def params_for(self, mode: str, system: Any = None) -> np.ndarray:
        """The parameter array in mode ``mode`` (float64)."""
        try:
            return np.ascontiguousarray(self.params(mode), dtype=np.float64).reshape(-1)
        except (TypeError, ValueError) as exc:
            raise ModelError(f"controller {self.name}: params('{mode}') is not an array of numbers: {exc}") from exc

    def input_at(self, mode: str, t: float, x: np.ndarray, memory: Any = None) -> np.ndarray:
        """The input u (``inputs`` entries) in ``mode`` at the plant's state x, from ``memory``
        (default the initial memory): the same function the runs call."""
        m = np.asarray(self.initial_memory if memory is None else memory, dtype=float).reshape(-1)
        u = np.zeros(self.inputs)
        self.control(float(t), np.ascontiguousarray(x, dtype=float), m, self.params_for(mode), u)
        return u

    @property
    def compiled(self) -> bool:
        """Whether its functions are compiled (numba), so the kernel can call them."""
        return hasattr(self.control, "py_func") and (self.enter is None or hasattr(self.enter, "py_func"))


class LawController(Controller):
    """A ``ControlLaw`` run as a ``Controller`` (its memory kept here, changed by ``enter`` at
    every mode entry), for tools that drive a plant by Python controllers (the event-driven
    baseline, ``legsim.baselines``): the same functions, hence the same input."""

    def __init__(self, law: ControlLaw) -> None:
        self.law = law
        self.hold = law.hold
        self.memory_names = law.memory_names
        self.memory_units = law.memory_units
        self.memory_frames = law.memory_frames
        self._memory = np.asarray(law.initial_memory, dtype=float).copy()

    def reset(self, mode: str, t: float, x: np.ndarray) -> None:
        if self.law.enter is not None:
            new = np.empty_like(self._memory)
            self.law.enter(float(t), np.ascontiguousarray(x, dtype=float), self._memory, self.law.params_for(mode), new)
            self._memory = new

    def memory(self) -> np.ndarray:
        return self._memory.copy()

    def restore(self, mode: str, memory: np.ndarray) -> None:
        self._memory = np.asarray(memory, dtype=float).reshape(-1).copy()

    def __call__(self, mode: str, t: float, x: np.ndarray) -> np.ndarray:
        return self.law.input_at(mode, t, x, self._memory)


class Bound:
    """A ``Controller`` as the integrator calls a control, ``u(t, x)``, bound to the mode the run
    is in, with the held value of a zero-order hold."""

    def __init__(self, controller: Controller) -> None:
        self.controller = controller
        self.hold = bool(controller.hold)
        self.mode = ""
        self._held: Any = None

    def enter(self, mode: str, t: float, x: np.ndarray) -> None:
        """The run enters ``mode`` at (t, x): reset the controller, and hold its value there."""
        self.reset_in(mode, t, x)
        self.step_from(t, x)

    def reset_in(self, mode: str, t: float, x: np.ndarray) -> None:
        """The controller's ``reset`` on entering ``mode`` at (t, x), which becomes the mode it
        is asked in; its failure is a ModelError naming it, the mode and t."""
        self.mode = mode
        try:
            self.controller.reset(mode, t, x)
        except LegsimError:
            raise
        except Exception as exc:  # a plug-in's own bug: name it and where, not a traceback
            raise ModelError(self._failed("reset", mode, t, exc)) from exc

    def step_from(self, t: float, x: np.ndarray) -> None:
        """A step starts at (t, x): a held controller is sampled there."""
        if self.hold:
            self._held = self._evaluate(t, x)

    def __call__(self, t: float, x: np.ndarray) -> Any:
        return self._held if self.hold else self._evaluate(t, x)

    def _evaluate(self, t: float, x: np.ndarray) -> Any:
        return self.input_in(self.mode, t, x)

    def input_in(self, mode: str, t: float, x: np.ndarray) -> Any:
        """The controller's input in ``mode`` at (t, x); its failure is a ModelError naming it,
        the mode and t."""
        try:
            return self.controller(mode, t, x)
        except LegsimError:
            raise
        except Exception as exc:
            raise ModelError(self._failed("its input", mode, t, exc)) from exc

    def _failed(self, what: str, mode: str, t: float, exc: Exception) -> str:
        return (
            f"controller {type(self.controller).__name__}: {what} in mode '{mode}' at t={t:.17g} failed: "
            f"{type(exc).__name__}: {exc}"
        )


def bind(control: Controller | Callable[[float, np.ndarray], Any] | None) -> Any:
    """What the integrator calls: a ``Bound`` controller, or the plain control itself."""
    return Bound(control) if isinstance(control, Controller) else control


@dataclass(frozen=True)
class ControllerSpec:
    """A named controller scenes can ask for: ``make(model, parameters) -> Controller`` receives
    the scene's model and every parameter (defaults filled in, checked)."""

    name: str
    description: str
    parameters: Mapping[str, Param]
    make: Callable[[Model, dict[str, Any]], Controller | ControlLaw]

    def build(
        self,
        model: Model,
        parameters: Mapping[str, Any] | None = None,
        where: str = "",
        files: Callable[[Mapping[str, Param], dict[str, Any]], None] | None = None,
    ) -> Controller | ControlLaw:
        """Check ``parameters`` (``files`` resolves their file parameters in place, as a scene
        does) and make the controller for ``model``. A ``make`` that raises anything but a
        legsim error is a ``SceneError`` naming the controller and the failure."""
        prefix = f"{where}: " if where else ""
        try:
            params = resolve_parameters(
                self.parameters, {} if parameters is None else parameters, f"{prefix}controller.parameters"
            )
            if files is not None:
                files(self.parameters, params)
            controller = self.make(model, params)
        except LegsimError as exc:
            named = self._naming(exc)
            if named is exc:
                raise
            raise named from None
        except Exception as exc:  # a plug-in's own failure on parameters it accepted
            raise SceneError(
                f"{prefix}controller '{self.name}' could not be made from its parameters {params!r:.300}: "
                f"{type(exc).__name__}: {exc}"
            ) from exc
        if not isinstance(controller, (Controller, ControlLaw)):
            raise SceneError(
                f"{prefix}controller '{self.name}' made {type(controller).__name__}, expected a "
                f"legsim.control.Controller"
            )
        return controller

    def _naming(self, exc: LegsimError) -> LegsimError:
        """``exc`` with the controller's name added, unless its message already names it (a
        field such as ``controller.parameters.kp`` does not say which controller reads it)."""
        named = f"controller '{self.name}'"
        if named in str(exc) or type(exc) not in (SceneError, ModelError):
            return exc
        return type(exc)(f"{exc} ({named})")


def available() -> dict[str, metadata.EntryPoint]:
    """The registered controllers by name (not yet imported)."""
    return registered(ENTRY_POINT_GROUP)


def get_controller(name: str) -> ControllerSpec:
    """Load the controller called ``name``; SceneError lists the known names when it is unknown."""
    return load_registered(available(), name, "controller", ControllerSpec)
