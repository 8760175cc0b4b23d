"""How a system or robot declares itself to scenes, and how scenes find it.

A *builder* names its parameters and the effects it can switch on (each with its own
parameters), and builds a ``Model`` (a ``HybridSystem`` plus what the tools around it need:
default initial state, energy, geometry for pictures) from only the effects a scene asks for.

Builders are found through the ``legsim.builders`` entry-point group, so the core never imports
``robots/`` (nor any third-party package): a package that wants its robot runnable from scenes
declares ``[project.entry-points."legsim.builders"] myrobot = "mypkg.myrobot:BUILDER"``.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable, Iterator, Mapping
from contextvars import ContextVar
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

from .errors import ModelError, SceneError
from .hybrid import HybridSystem
from .registry import load_registered, registered

#: A scene's ground as a builder receives it: a ``legsim.terrain.Terrain`` (made by the scene
#: layer, which reads its files), passed through untouched by the core.
Terrain = Any

ENTRY_POINT_GROUP = "legsim.builders"

#: Most items of a list parameter: the bundled robots and controllers take a dozen at most.
MAX_LIST_ITEMS = 4096

#: The folder of the scene whose model or controller is being made (``reading_inside``).
_INPUT_FOLDER: ContextVar[Path | None] = ContextVar("legsim_input_folder", default=None)


def input_folder() -> Path | None:
    """The folder every file a builder reads must lie in while a scene is being built (the
    scene's own: a URDF's meshes are held to the rule its ``[output]`` paths are held to); None
    when a builder is called from Python, outside a scene."""
    return _INPUT_FOLDER.get()


@contextlib.contextmanager
def reading_inside(folder: Path) -> Iterator[None]:
    """Within the block, ``input_folder()`` is ``folder``."""
    token = _INPUT_FOLDER.set(folder)
    try:
        yield
    finally:
        _INPUT_FOLDER.reset(token)


@dataclass(frozen=True)
class Param:
    """A scene parameter: its default, meaning and allowed values.

    ``low``/``high`` bound numbers (inclusive unless ``low_open``/``high_open``);
    ``choices`` restricts strings. The type is the default's type (int is accepted where a
    float is expected, bool never is). ``path``: the string is a file path, which a scene
    resolves against its own folder (and checks that the file exists).
    """

    default: Any
    doc: str = ""
    unit: str = ""
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    choices: tuple[Any, ...] | None = None
    path: bool = False

    def allowed(self) -> str:
        """Human description of the allowed values (for error messages and docs)."""
        kind = type(self.default).__name__
        parts = [kind]
        if self.choices is not None:
            parts.append(f"one of {list(self.choices)}")
        if self.low is not None or self.high is not None:
            lo = "-inf" if self.low is None else f"{self.low:g}"
            hi = "inf" if self.high is None else f"{self.high:g}"
            lb = "(" if (self.low is None or self.low_open) else "["
            rb = ")" if (self.high is None or self.high_open) else "]"
            parts.append(f"in {lb}{lo}, {hi}{rb}")
        return " ".join(parts)

    def allowed_with_unit(self) -> str:
        """``allowed()`` followed by the unit, where the parameter has one ("float in (0, inf) s")."""
        return f"{self.allowed()} {self.unit}".strip()

    def check(self, value: Any, where: str) -> Any:
        """Return ``value`` converted to this parameter's type, or raise SceneError naming ``where``."""
        expected = type(self.default)
        if expected is bool:
            if not isinstance(value, bool):
                raise SceneError(f"{where}: expected a boolean (true/false), got {value!r}")
            return value
        if expected in (int, float):
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise SceneError(f"{where}: expected a number ({self.allowed_with_unit()}), got {value!r}")
            if expected is int and not isinstance(value, int):
                raise SceneError(f"{where}: expected an integer ({self.allowed_with_unit()}), got {value!r}")
            value = expected(value)
            if not math.isfinite(value):
                raise SceneError(f"{where}: must be finite, got {value!r}")
            below = self.low is not None and (value < self.low or (self.low_open and value == self.low))
            above = self.high is not None and (value > self.high or (self.high_open and value == self.high))
            if below or above:
                raise SceneError(f"{where}: {value!r} is out of range, allowed: {self.allowed_with_unit()}")
            return value
        if expected is str:
            if not isinstance(value, str):
                raise SceneError(f"{where}: expected a string, got {value!r}")
            if self.choices is not None and value not in self.choices:
                raise SceneError(f"{where}: {value!r} is not allowed, choose one of {list(self.choices)}")
            return value
        if expected in (list, tuple):
            if not isinstance(value, (list, tuple)):
                raise SceneError(f"{where}: expected a list, got {value!r}")
            return check_items(list(value), self.default, where)
        return value


def _kind(value: Any) -> str:
    """What a scene value is, as a message names it."""
    if isinstance(value, bool):
        return "booleans"
    if isinstance(value, (int, float)):
        return "numbers"
    if isinstance(value, str):
        return "strings"
    if isinstance(value, (list, tuple)):
        return "lists"
    if isinstance(value, Mapping):
        return "tables"
    return type(value).__name__


def check_items(items: list[Any], default: Any, where: str) -> list[Any]:
    """A list parameter's items, checked whatever the builder does with them: at most
    ``MAX_LIST_ITEMS``, all of one kind (that of the default's items when it has some), and every
    number in them, nested tables and lists included, finite. SceneError naming the item."""
    if len(items) > MAX_LIST_ITEMS:
        raise SceneError(f"{where}: {len(items)} items, more than the {MAX_LIST_ITEMS} a parameter may hold")
    kinds = sorted({_kind(item) for item in items})
    wanted = sorted({_kind(item) for item in default}) if isinstance(default, (list, tuple)) and default else kinds
    if len(kinds) > 1 or (kinds and len(wanted) == 1 and kinds != wanted):
        expected = f"a list of {wanted[0]}" if len(wanted) == 1 and default else "a list of one kind"
        raise SceneError(f"{where}: expected {expected}, got {', '.join(kinds)}: {items!r:.200}")
    pending: list[tuple[str, Any]] = [(f"{where}[{k}]", item) for k, item in enumerate(items)]
    while pending:
        name, value = pending.pop()
        if isinstance(value, float) and not math.isfinite(value):
            raise SceneError(f"{name}: must be finite, got {value!r}")
        if isinstance(value, (list, tuple)):
            pending.extend((f"{name}[{k}]", item) for k, item in enumerate(value))
        elif isinstance(value, Mapping):
            pending.extend((f"{name}.{key}", item) for key, item in value.items())
    return items


@dataclass(frozen=True)
class Effect:
    """An effect a scene may switch on (gravity, a stop, a leg, damping, a controller...).

    In a scene, ``name = true`` switches it on with default parameters, ``name = false`` off,
    and ``name = { key = value, ... }`` on with those parameters.
    """

    doc: str
    default_on: bool = False
    parameters: Mapping[str, Param] = field(default_factory=dict)


#: Key of ``Model.info`` under which a builder passes the ``zeno`` effect's window (s) to the
#: runs of its scenes (``simulate(zeno_window=...)``; an ``integrator.zeno_window`` overrides it).
ZENO_WINDOW = "zeno_window"

#: The ``zeno`` effect of the builders whose transitions name continuations: it sets the window
#: of the accumulation rule (``legsim.relaxed.zeno``). Continuation itself is on by default.
ZENO_EFFECT = Effect(
    "the window of the Zeno accumulation rule: shrinking flights shorter than `window` count as "
    "accumulating, and contacts continue in their constrained mode (continuation is on by "
    "default with window h + eps; `integrator.continuation = false` switches it off)",
    parameters={
        "window": Param(
            2e-3, "shortest flight resolved (s); by default h + eps of the run", "s", low=0.0, low_open=True
        )
    },
)


@dataclass
class Model:
    """What a builder returns: the hybrid system and what tools around it need.

    Attributes
    ----------
    system: the hybrid system, with only the modes, guards and terms of the effects named.
    initial_mode: default initial mode.
    initial_state: default initial state by coordinate name (of ``initial_mode``).
    control: optional control passed to ``simulate``: a ``control(t, x) -> u``, a ``Controller``
        or a ``legsim.control.ControlLaw``.
    geometry: optional ``geometry(mode, x) -> {part: array (k, 2)}``: polylines in the
        sagittal (x, z) plane in metres, for recordings and animations.
    scenery: static polylines (ground, stops) in the same form.
    reference: optional analytic or high-accuracy reference of the scene's execution.
    counters: optional ``() -> dict`` of model-side counts (e.g. damping-term evaluations).
    info: free-form facts about the model (parameters used, units of each guard).
    """

    system: HybridSystem
    initial_mode: str
    initial_state: dict[str, float]
    control: Any = None  # a control(t, x) -> u, a Controller or a legsim.control.ControlLaw
    geometry: Callable[[str, np.ndarray], dict[str, np.ndarray]] | None = None
    scenery: dict[str, np.ndarray] = field(default_factory=dict)
    reference: Any = None
    counters: Callable[[], dict[str, int]] | None = None
    info: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Builder:
    """A named system or robot that scenes can ask for.

    ``build(parameters, effects)`` receives every parameter (defaults filled in, validated)
    and only the effects that are switched on, each with its validated parameters; a builder
    with ``terrain = True`` takes a scene's ``[terrain]`` too: ``build(parameters, effects,
    terrain)``, terrain a ``legsim.terrain.Terrain`` or None.
    """

    name: str
    description: str
    parameters: Mapping[str, Param]
    effects: Mapping[str, Effect]
    build: Callable[..., Model]
    terrain: bool = False

    def make(
        self,
        parameters: Mapping[str, Any] | None = None,
        effects: Mapping[str, Any] | None = None,
        where: str = "",
        terrain: Terrain | None = None,
    ) -> Model:
        """Validate ``parameters`` and ``effects`` (as a scene would give them) and build (on
        ``terrain``, for a builder that takes one)."""
        prefix = f"{where}: " if where else ""
        params = resolve_parameters(
            self.parameters, {} if parameters is None else parameters, f"{prefix}robot.parameters"
        )
        chosen = resolve_effects(self.effects, {} if effects is None else effects, f"{prefix}effects")
        model = self.run(params, chosen, terrain, where)
        if not isinstance(model, Model):
            raise ModelError(f"builder '{self.name}' returned {type(model).__name__}, expected legsim.builders.Model")
        return model

    def run(
        self, params: dict[str, Any], effects: dict[str, dict[str, Any]], terrain: Terrain | None, where: str = ""
    ) -> Model:
        """``build`` with resolved parameters and effects, and the terrain when the builder takes
        one; SceneError naming ``terrain`` for a terrain given to a robot whose ground is its own."""
        if self.terrain:
            return self.build(params, effects, terrain)
        if terrain is not None:
            prefix = f"{where}: " if where else ""
            raise SceneError(
                f"{prefix}terrain: robot '{self.name}' has its ground built in and takes no [terrain] "
                f"(the robots from a URDF, 'urdf', do)"
            )
        return self.build(params, effects)


def resolve_parameters(schema: Mapping[str, Param], given: Mapping[str, Any], where: str) -> dict[str, Any]:
    """Defaults overridden by ``given``, each checked; unknown names are rejected."""
    if not isinstance(given, Mapping):
        raise SceneError(f"{where}: expected a table of parameters, got {given!r}")
    unknown = sorted(set(given) - set(schema))
    if unknown:
        raise SceneError(f"{where}: unknown parameter(s) {unknown}; allowed: {sorted(schema)}")
    out = {name: p.default for name, p in schema.items()}
    for name, value in given.items():
        out[name] = schema[name].check(value, f"{where}.{name}")
    return out


def resolve_effects(schema: Mapping[str, Effect], given: Mapping[str, Any], where: str) -> dict[str, dict[str, Any]]:
    """The effects switched on, each with its parameters resolved."""
    if not isinstance(given, Mapping):
        raise SceneError(f"{where}: expected a table of effects, got {given!r}")
    unknown = sorted(set(given) - set(schema))
    if unknown:
        raise SceneError(f"{where}: unknown effect(s) {unknown}; allowed: {sorted(schema)}")
    chosen: dict[str, dict[str, Any]] = {}
    for name, effect in schema.items():
        value = given.get(name, effect.default_on)
        if isinstance(value, bool):
            if value:
                chosen[name] = resolve_parameters(effect.parameters, {}, f"{where}.{name}")
        elif isinstance(value, Mapping):
            chosen[name] = resolve_parameters(effect.parameters, value, f"{where}.{name}")
        else:
            raise SceneError(f"{where}.{name}: expected true, false or a table of parameters, got {value!r}")
    return chosen


def available() -> dict[str, metadata.EntryPoint]:
    """The registered builders by name (not yet imported)."""
    return registered(ENTRY_POINT_GROUP)


def get_builder(name: str) -> Builder:
    """Load the robot called ``name``; SceneError lists the known names when it is unknown."""
    return load_registered(available(), name, "robot", Builder)
