"""Scene files: a TOML description of one simulation, validated completely before anything runs.

A scene names a robot (a builder registered in the ``legsim.builders`` entry-point group), its
parameters, the effects it wants switched on, the initial mode and state by coordinate name,
the integrator settings and the outputs::

    [scene]
    description = "one line shown by `legsim scenes`"

    [robot]
    name = "bouncing_ball"
    [robot.parameters]
    g = 9.81

    [effects]
    floor = { restitution = 0.5 }

    [initial]
    mode = "flight"
    state = { z = 1.0, zd = 0.0 }

    [integrator]
    method = "rk4"
    h = 1e-3
    eps = 1e-3
    t_final = 2.7

    [output]
    rrd = "out/ball.rrd"

An optional ``[fall]`` section says when a run has failed (``legsim.scene.falls``: such a run
ends with status ``fell``); an optional ``[terrain]`` section gives the ground under a robot
that takes one (``legsim.terrain``: flat, slope, steps, profile, sine).

Tool sections (``[orbit]``, ``[certify]``, ...) must be tables; the tool that reads one
validates its content. Every error is a ``SceneError`` whose message starts with the file and
names the field (as a dotted path) and what is allowed.

A scene is named either by a path or by a bare name, which is looked up as ``<name>.toml`` in
the directories of ``LEGSIM_SCENE_PATH`` (``os.pathsep`` separated), then in the bundled
scenes (``legsim.scenarios``, the repository's ``scenarios/`` folder).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..builders import (
    ZENO_WINDOW,
    Builder,
    Model,
    available,
    get_builder,
    reading_inside,
    resolve_effects,
    resolve_parameters,
)
from ..control import ControlLaw, Controller
from ..errors import LegsimError, ModelError, SceneError
from ..execution import Execution
from ..graph import reachable_modes
from ..output.summary import run_summary
from ..relaxed.resolution import state_scale, thinnest_strip
from ..terrain import Terrain
from .controller import scene_controller
from .falls import fall_watches
from .fields import check_keys, describe, field_error, table_at
from .files import apply_overrides, bundled_dir, checked_depth, read_toml, resolve_scene_path, scene_relative_files
from .integrator import check_step_rule, validated_integrator
from .terrain import parse_terrain, profile_file

CORE_SECTIONS = ("scene", "robot", "effects", "initial", "integrator", "output", "controller", "fall", "terrain")
TOOL_SECTIONS = ("orbit", "certify", "stochastic", "zeno", "stress", "bench", "accuracy")
ALLOWED_SECTIONS = CORE_SECTIONS + TOOL_SECTIONS

SCENE_KEYS = {"description": "a one-line string"}
ROBOT_KEYS = {"name": "a builder name (required)", "parameters": "a table of the builder's parameters"}
INITIAL_KEYS = {"mode": "a mode name", "state": "a table of coordinate name = number"}
OUTPUT_KEYS = ("rrd", "html", "plot")

#: Key of ``Model.info`` under which a builder may put ``check(mode, x, eps) -> str | None``: the
#: reason an initial state is impossible for the model although it is inside the relaxed domain
#: (None when it is fine). ``load_scene`` calls it and reports the reason at ``initial.state``.
INITIAL_CHECK = "initial_check"
#: Key of ``Model.info`` under which a builder may put ``watches(control, eps) -> [Watch, ...]``:
#: the conditions its runs are checked for (``legsim.relaxed.Watch``; a link below the ground, the
#: time an actuator spends at its effort limit), given what the run is controlled by and its eps.
WATCHES = "watches"

# Integrator settings as Params, so their messages say what is allowed exactly as the
# builders' do. t_final, h and eps have no default: their right values depend on the model
# (eps is in guard units), so a scene must state them.


@dataclass
class Scene:
    """A validated scene, ready to simulate.

    Attributes
    ----------
    path: the scene file.
    name: the scene's name (the file's stem).
    description: one line.
    robot: the builder's name; ``builder`` the builder itself.
    parameters, effects: the resolved robot parameters and the effects switched on (with their
        parameters), as passed to the builder.
    model: the built ``legsim.builders.Model``.
    initial_mode: mode name; ``initial_state``: float64 array (n,) in that mode's coordinates.
    integrator: method, h (s), eps (guard units), t_final (s), t0 (s), max_transitions,
        max_halvings, max_steps (bound on (t_final - t0) / h, checked at loading), landing
        ("halve", "aim" or "dense"), rtol and atol (None unless error-controlled).
    output: rrd, html, plot paths (str, relative to the scene's folder) or None; ``output_paths``
        resolves them.
    sections: the tool sections present (``orbit``, ``certify``, ...), as tables.
    data: the scene's TOML content after overrides.
    overrides: the ``key.path=value`` overrides applied.
    """

    path: Path
    name: str
    description: str
    robot: str
    builder: Builder
    parameters: dict[str, Any]
    effects: dict[str, dict[str, Any]]
    model: Model
    initial_mode: str
    initial_state: np.ndarray
    integrator: dict[str, Any]
    output: dict[str, str | None]
    sections: dict[str, dict[str, Any]]
    data: dict[str, Any] = field(repr=False)
    overrides: list[str] = field(default_factory=list)
    controller: Any = None
    #: Makes the ``[controller]`` section's controller anew (from its registry entry, as
    #: ``controller`` was made: attached to the model where the controller attaches itself).
    make_controller: Callable[[], Any] | None = field(default=None, repr=False, compare=False)
    #: The ``[fall]`` section's conditions (``legsim.scene.falls``), stop watches.
    falls: tuple[Any, ...] = ()
    #: The ``[terrain]`` section's ground (``legsim.terrain``), None without one.
    terrain: Terrain | None = None

    def watches(self, control: Any, eps: float | None = None) -> tuple[Any, ...]:
        """The conditions a run under ``control`` with strip width ``eps`` (default the scene's)
        is checked for: the ``[fall]`` section's and the model's own (``Model.info["watches"]``)."""
        own = self.model.info.get(WATCHES) if isinstance(self.model.info, Mapping) else None
        eps = self.integrator["eps"] if eps is None else eps
        return self.falls + (tuple(own(control, eps)) if callable(own) else ())

    @property
    def control(self) -> Any:
        """What a run is controlled by: a newly made ``[controller]`` (a controller keeps state
        across transitions, so every run starts from the one the section describes, never from
        where an earlier run left it), else the model's own control (None without either). A
        ``ControlLaw`` keeps nothing in itself (its memory is the run's state): every run shares
        the scene's one, and with it the tables an earlier run built (``legsim.relaxed.tables``)."""
        if isinstance(self.controller, ControlLaw):
            return self.controller
        return self.make_controller() if self.make_controller is not None else self.model.control

    @property
    def state_names(self) -> tuple[str, ...]:
        """Coordinate names of the initial mode."""
        return tuple(self.model.system.state_names(self.initial_mode))

    @property
    def reference(self) -> Any:
        """The model's reference for *this* scene's initial mode and state (which ``[initial]``
        or ``--set`` may have changed), or None when the model has none. References that can be
        restarted define ``with_initial(mode, x)``; others describe the model's default start."""
        ref = self.model.reference
        if ref is not None and hasattr(ref, "with_initial"):
            return ref.with_initial(self.initial_mode, self.initial_state.copy())
        return ref

    def input_files(self) -> list[Path]:
        """The files the scene reads: the scene file, its robot's file parameters (a URDF) and
        its terrain's CSV profile, resolved (an output may be none of them)."""
        files = [self.path]
        files += [Path(value) for name, param in self.builder.parameters.items()
                  if param.path and isinstance(value := self.parameters.get(name), str) and value]  # fmt: skip
        csv = (self.data.get("terrain") or {}).get("file")  # a validated table: a file name or absent
        found = profile_file(self.path, csv) if csv else None
        files += [found] if found is not None else []
        return files

    def output_paths(self, out_dir: str | os.PathLike[str] | None = None) -> dict[str, Path]:
        """kind -> file of each ``[output]`` of this scene, resolved against ``out_dir`` or else the
        scene's own folder (a bundled scene's: the current folder, never the installed package's).
        SceneError naming the file and field when a symbolic link on the way leads out of that
        folder (a downloaded scene may bring one)."""
        folder = self.path.parent
        bundled = os.path.realpath(folder) == os.path.realpath(bundled_dir())
        base = Path(out_dir) if out_dir is not None else Path.cwd() if bundled else folder
        real_base = os.path.realpath(base)
        out: dict[str, Path] = {}
        for kind, relative in self.output.items():
            if not relative:
                continue
            target = base / relative
            real = os.path.realpath(target)
            if os.path.commonpath([real_base, real]) != real_base:
                raise field_error(
                    self.path,
                    f"output.{kind}",
                    f"{relative!r} leads out of {base} to {real} through a "
                    f"symbolic link; give --{kind} FILE to write there",
                )
            out[kind] = target
        return out

    def simulate(self, progress: Callable[[float, float, float], None] | None = None) -> Execution:
        """Run the relaxed integrator with the scene's settings.

        ``progress(t, t0, t_final)`` is called a few times a second on long runs. The model's
        own counters (``Model.counters()``, e.g. damping-term evaluations) counted during this
        run are added to ``execution.counters`` under their own names (prefixed ``model_``
        where a name collides with an integrator counter).
        """
        from ..relaxed import simulate

        # The run's own model counters: other runs of the system wait for their turn.
        with self.model.system.turn():
            s = self.integrator
            before = _model_counters(self.model)
            control = self.control
            execution = simulate(
                self.model.system,
                self.initial_state.copy(),
                self.initial_mode,
                s["t_final"],
                s["h"],
                s["eps"],
                s["method"],
                control,
                t0=s["t0"],
                max_transitions=s["max_transitions"],
                max_halvings=s["max_halvings"],
                progress=progress,
                rtol=s["rtol"],
                atol=s["atol"],
                landing=s["landing"],
                max_steps=s["max_steps"],
                continuation=s["continuation"],
                zeno_window=s["zeno_window"] or self.model.info.get(ZENO_WINDOW),
                watches=self.watches(control),
            )
            after = _model_counters(self.model)
            for key, value in after.items():
                # Report this run's count: the builder may have evaluated terms while being checked.
                delta = value - before.get(key, 0) if isinstance(value, (int, float)) else value
                name = key if key not in execution.counters else f"model_{key}"
                execution.counters[name] = delta
            return execution

    def check_accuracy(self, progress: Callable[[float, float, float], None] | None = None) -> tuple[Execution, Any]:
        """The scene's run and the estimate of its error (``legsim.accuracy``): the run repeated
        with eps / 10 and h / 2 (tolerances / 10 under error control). Returns (the execution,
        its ``ErrorEstimate``)."""
        from ..accuracy import compare, refined
        from .orbit import accuracy_section

        section = accuracy_section(self)
        run = self.simulate(progress)
        fine = dataclasses.replace(self, integrator=refined(self.integrator)).simulate(progress)
        return run, compare(run, fine, self.model.system, section)

    def energy(self, mode: str, x: np.ndarray) -> float | None:
        """The system's energy (J) at (mode, x), or None when it defines none."""
        fn = self.model.system.energy
        if fn is None:
            return None
        try:
            value = float(fn(mode, np.asarray(x, dtype=float)))
        except Exception as exc:
            raise ModelError(
                f"{self.model.system.name}: energy in mode '{mode}' failed: {type(exc).__name__}: {exc}"
            ) from exc
        return value

    def summary(self, execution: Execution) -> dict[str, Any]:
        """The run summary of ``legsim run --json`` (without ``outputs``): see
        ``legsim.output.summary.run_summary``."""
        return run_summary(execution, self)


def _model_counters(model: Model) -> dict[str, Any]:
    if model.counters is None:
        return {}
    counts = model.counters()
    if not isinstance(counts, Mapping):
        raise ModelError(f"{model.system.name}: Model.counters() must return a dict, got {type(counts).__name__}")
    return dict(counts)


def load_scene(path_or_name: str | os.PathLike[str], overrides: Sequence[str] = ()) -> Scene:
    """Read, override and validate a scene; build its model.

    Parameters
    ----------
    path_or_name: a scene file, or the name of a scene in ``LEGSIM_SCENE_PATH`` or ``scenarios/``.
    overrides: ``key.path=value`` strings applied to the file's content before validation.

    Raises
    ------
    SceneError
        naming the file, the field (dotted path) and what is allowed, for anything wrong:
        missing file, TOML syntax (with its line), unknown sections, keys, robots, parameters,
        effects, modes or coordinates, wrong types, out-of-range values.
    """
    if isinstance(overrides, str):
        overrides = [overrides]
    path = resolve_scene_path(path_or_name)
    data = read_toml(path)
    applied = apply_overrides(data, overrides)
    return _validate(path, checked_depth(path, data), applied)


def _validate(path: Path, data: dict[str, Any], overrides: list[str]) -> Scene:
    _check_sections(path, data)
    description = _description(path, data.get("scene", {}))
    robot_t = table_at(path, data, "robot")
    robot = _robot_name(path, robot_t)
    parameters = table_at(path, robot_t, "parameters", "robot.parameters")
    effects_t = table_at(path, data, "effects")
    # Integrator settings and outputs are checked before the model is built, so that a typo in
    # them is reported without paying for (possibly slow) model construction.
    integrator = validated_integrator(path, table_at(path, data, "integrator"))
    output = _output(path, table_at(path, data, "output"))
    terrain = parse_terrain(path, data["terrain"]) if "terrain" in data else None
    sections = {key: data[key] for key in TOOL_SECTIONS if key in data}

    try:
        builder = get_builder(robot)
    except SceneError as exc:
        raise field_error(path, "robot.name", str(exc)) from None
    where = str(path)
    # Builder.make would do these two steps too; they are done here so that the scene keeps the
    # resolved values (for recordings and tools) and the builder runs once.
    resolved_params = resolve_parameters(builder.parameters, parameters, f"{where}: robot.parameters")
    scene_relative_files(path, builder.parameters, resolved_params, "robot.parameters")
    chosen = resolve_effects(builder.effects, effects_t, f"{where}: effects")
    model = _built(path, robot, builder, resolved_params, chosen, terrain)
    check_step_rule(path, model.info, integrator)

    controller_table = table_at(path, data, "controller")
    controller = scene_controller(path, controller_table, model)
    initial_mode, initial_state = _initial(
        path, model, table_at(path, data, "initial"), integrator["eps"], integrator["t0"], controller
    )
    falls = fall_watches(path, table_at(path, data, "fall"), model, initial_mode, terrain)
    make_controller = None if controller is None else functools.partial(scene_controller, path, controller_table, model)
    return Scene(
        path=path,
        name=path.stem,
        description=description,
        robot=robot,
        builder=builder,
        parameters=resolved_params,
        effects=chosen,
        model=model,
        initial_mode=initial_mode,
        initial_state=initial_state,
        integrator=integrator,
        output=output,
        sections=sections,
        data=data,
        overrides=overrides,
        controller=controller,
        make_controller=make_controller,
        falls=falls,
        terrain=terrain,
    )


def _check_sections(path: Path, data: dict[str, Any]) -> None:
    """Every top-level key a known section, and each a table."""
    unknown = sorted(set(data) - set(ALLOWED_SECTIONS))
    if unknown:
        raise SceneError(
            f"{path}: unknown section(s) {unknown}; allowed: {list(CORE_SECTIONS)} and tool "
            f"sections {list(TOOL_SECTIONS)}"
        )
    for key in ALLOWED_SECTIONS:
        table_at(path, data, key)


def _description(path: Path, scene_t: dict[str, Any]) -> str:
    """The ``[scene]`` table's description ("" when absent)."""
    check_keys(path, scene_t, SCENE_KEYS, "scene")
    description = scene_t.get("description", "")
    if not isinstance(description, str):
        raise field_error(path, "scene.description", f"expected a string, got {describe(description)}")
    return description


def _robot_name(path: Path, robot_t: dict[str, Any]) -> str:
    """The ``[robot]`` table's ``name`` (a string; the robots available named when it is not)."""
    check_keys(path, robot_t, ROBOT_KEYS, "robot")
    if "name" not in robot_t:
        raise field_error(path, "robot.name", f"missing; available robots: {sorted(available())}")
    robot = robot_t["name"]
    if not isinstance(robot, str):
        raise field_error(
            path, "robot.name", f"expected a string, got {describe(robot)}; available robots: {sorted(available())}"
        )
    return robot


def _built(path: Path, robot: str, builder: Any, parameters: dict[str, Any], effects: dict[str, Any],
           terrain: Any) -> Model:  # fmt: skip
    """The builder's model from resolved parameters and effects, read inside the scene's folder;
    a builder's failure names the file and the robot, its cause chained."""
    where = str(path)
    try:
        with reading_inside(path.parent):
            model = builder.run(parameters, effects, terrain, where)
    except SceneError as exc:
        if str(exc).startswith(where):
            raise
        raise SceneError(f"{where}: robot '{robot}': {exc}") from exc
    except Exception as exc:  # a builder's own failure: name the file and robot, keep the cause chained
        detail = str(exc) if isinstance(exc, LegsimError) else f"{type(exc).__name__}: {exc}"
        raise ModelError(f"{where}: robot '{robot}' could not be built: {detail}") from exc
    if not isinstance(model, Model):
        raise ModelError(f"{where}: builder '{robot}' returned {type(model).__name__}, expected legsim.builders.Model")
    return model


def _output(path: Path, table: dict[str, Any]) -> dict[str, str | None]:
    """The ``[output]`` paths, each relative and inside the scene's folder (see ``output_paths``)."""
    check_keys(path, table, OUTPUT_KEYS, "output")
    out: dict[str, str | None] = {}
    for key in OUTPUT_KEYS:
        value = table.get(key)
        if value is not None:
            _check_output_path(path, f"output.{key}", value)
        out[key] = value
    return out


def _check_output_path(path: Path, where: str, value: Any) -> None:
    """A scene may come from someone else: its output paths may only name files in its own
    folder (or ``--out-dir``), never an absolute path or one that climbs out with ``..``."""
    if not isinstance(value, str) or not value.strip():
        raise field_error(path, where, f"expected a file path (string), got {describe(value)}")
    if "\x00" in value:
        raise field_error(path, where, f"{value!r} contains a NUL character")
    if os.path.isabs(value) or os.path.splitdrive(value)[0]:
        raise field_error(
            path,
            where,
            f"{value!r} is an absolute path; a scene's outputs are relative to its "
            f"folder (or --out-dir); give --{where.split('.')[-1]} FILE to write elsewhere",
        )
    normal = os.path.normpath(value)
    if normal == os.curdir or normal == os.pardir or normal.startswith(os.pardir + os.sep):
        raise field_error(
            path,
            where,
            f"{value!r} leaves the scene's folder; a scene's outputs stay inside its "
            f"folder (or --out-dir); give --{where.split('.')[-1]} FILE to write elsewhere",
        )


def _known_modes(model: Model) -> list[str]:
    try:
        return sorted(set(model.system.modes) | set(reachable_modes(model.system, model.initial_mode)))
    except LegsimError:
        return sorted(model.system.modes)


def _initial_input(control: Any, mode: str, t0: float, x0: np.ndarray) -> Any:
    """The input at the initial state, before the run enters its mode: a ``ControlLaw``'s from its
    initial memory, a ``Controller``'s asked in ``mode``, a plain control's, or None."""
    if isinstance(control, ControlLaw):
        return control.input_at(mode, t0, x0)
    if isinstance(control, Controller):
        return control(mode, t0, x0)
    return None if control is None else control(t0, x0)


def _initial(
    path: Path, model: Model, table: dict[str, Any], eps: float, t0: float, controller: Any = None
) -> tuple[str, np.ndarray]:
    """The ``[initial]`` mode and state, checked: the state's coordinates numbers (the robot's
    defaults for those not given), the model's functions evaluated on it, inside the mode's
    relaxed domain, and passing the model's own initial-state check."""
    check_keys(path, table, INITIAL_KEYS, "initial")
    mode, names = _initial_mode(path, model, table)
    x0 = _initial_values(path, model, table.get("state", {}), mode, names)
    _check_resolved(path, x0, names, eps)
    system = model.system
    try:
        u0 = _initial_input(controller if controller is not None else model.control, mode, t0, x0)
    except Exception as exc:
        raise ModelError(
            f"{path}: the control of robot model '{system.name}' failed on the initial state "
            f"{x0.tolist()}: {type(exc).__name__}: {exc}"
        ) from exc
    try:
        system.check_state(mode, x0, t=t0, u=u0, label="initial state")
    except ModelError as exc:
        raise field_error(path, "initial", str(exc)) from exc
    state = dict(zip(names, x0.tolist(), strict=True))
    gvals = system.guard_values(mode, x0)
    if gvals.size and gvals.min() < -eps:
        worst = int(np.argmin(gvals))
        raise field_error(
            path,
            "initial.state",
            f"{state} lies past the guard of transition {system.outgoing(mode)[worst].name} by "
            f"{-gvals[worst]:.3g} > eps = {eps:g} (guard units); start inside the domain of mode '{mode}'",
        )
    _model_initial_check(path, model, mode, x0, eps, state)
    return mode, x0


#: A coordinate of the initial state beyond this size (SI units) is taken for the mistake when
#: eps is too thin to resolve next to it, rather than eps.
UNPHYSICAL_STATE = 1e6


def _check_resolved(path: Path, x0: np.ndarray, names: tuple[str, ...], eps: float) -> None:
    """The strip must be wider than float64 resolves next to the initial state (``simulate``
    refuses it too, without the scene's names): the error names ``integrator.eps``, or the
    coordinate beyond ``UNPHYSICAL_STATE`` that makes float64 too coarse there."""
    thinnest = thinnest_strip(x0)
    if eps >= thinnest:
        return
    largest = int(np.argmax(np.abs(x0)))
    spacing = float(np.spacing(state_scale(x0)))
    if abs(x0[largest]) > UNPHYSICAL_STATE:
        raise field_error(
            path,
            f"initial.state.{names[largest]}",
            f"{x0[largest]:g} is so large that float64 values next to it are {spacing:.3g} apart: no step "
            f"could land in a strip of eps = {eps:g}; give the state in a physical range",
        )
    raise field_error(
        path,
        "integrator.eps",
        f"{eps:g} is thinner than float64 resolves next to the initial state (|x| up to {abs(x0[largest]):.3g}, "
        f"values {spacing:.3g} apart there): no step could land in a strip; give eps >= {thinnest:.3g} in guard "
        f"units",
    )


def _initial_mode(path: Path, model: Model, table: dict[str, Any]) -> tuple[str, tuple[str, ...]]:
    """The initial mode's name (the robot's default when not given) and its coordinates."""
    mode = table.get("mode", model.initial_mode)
    if not isinstance(mode, str):
        raise field_error(
            path, "initial.mode", f"expected a mode name (string), got {describe(mode)}; modes: {_known_modes(model)}"
        )
    try:
        return mode, tuple(model.system.state_names(mode))
    except ModelError:
        raise field_error(path, "initial.mode", f"unknown mode {mode!r}; modes: {_known_modes(model)}") from None


def _initial_values(path: Path, model: Model, given: Any, mode: str, names: tuple[str, ...]) -> np.ndarray:
    """The initial state (shape (len(names),)): each coordinate's given value or the robot's
    default, a finite number."""
    if not isinstance(given, dict):
        raise field_error(path, "initial.state", f"expected a table of coordinate = number, got {describe(given)}")
    unknown = sorted(set(given) - set(names))
    if unknown:
        raise field_error(
            path, "initial.state", f"unknown coordinate(s) {unknown} of mode '{mode}'; coordinates: {list(names)}"
        )
    defaults = dict(model.initial_state)
    values = []
    for name in names:
        if name in given:
            value = given[name]
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise field_error(path, f"initial.state.{name}", f"expected a number, got {describe(value)}")
        elif name in defaults:
            value = defaults[name]
        else:
            raise field_error(
                path,
                f"initial.state.{name}",
                f"missing, and the robot has no default for it in mode '{mode}'; give {list(names)}",
            )
        value = float(value)
        if not math.isfinite(value):
            raise field_error(path, f"initial.state.{name}", f"must be finite, got {value!r}")
        values.append(value)
    return np.array(values, dtype=float)


def _model_initial_check(path: Path, model: Model, mode: str, x0: np.ndarray, eps: float,
                         state: dict[str, float]) -> None:  # fmt: skip
    """The model's own check of an initial state (``INITIAL_CHECK`` in its info), if it has one."""
    # Guards written as "and" conditions (max(z, zd): below the floor AND falling) admit states
    # that no execution reaches, e.g. a ball 5 m under the floor at rest; the model may name them.
    check = model.info.get(INITIAL_CHECK) if isinstance(model.info, Mapping) else None
    if not callable(check):
        return
    try:
        problem = check(mode, x0.copy(), eps)
    except Exception as exc:
        raise ModelError(
            f"{path}: the initial-state check of robot model '{model.system.name}' failed on "
            f"{x0.tolist()}: {type(exc).__name__}: {exc}"
        ) from exc
    if problem:
        raise field_error(path, "initial.state", f"{state}: {problem}")
