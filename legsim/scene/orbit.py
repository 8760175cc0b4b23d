"""A scene's ``[orbit]`` section, read into an ``OrbitProblem``, the solver settings and the
initial guess that ``legsim.orbits.find_orbit`` and ``continue_family`` take.

::

    [orbit]
    section = { after = "heel_strike" }     # or { mode = ..., coordinate = ..., value = ..., direction = ... }
                                            # or { after = "touchdown_front", mode = "hind+front" }
    cyclic = ["foot_x"]
    free = ["psi"]                          # robot parameters, or EFFECT.PARAM
    tol = 1e-10

The keys and what they hold are ``ORBIT_KEYS``. The integrator settings (``INTEGRATOR_KEYS``:
method, h, eps, rtol, atol, landing, max_halvings) come from ``[integrator]``, so that a return
is computed as ``legsim run`` computes a run; the initial guess comes from ``[initial]`` (whose
mode must be the section's).
A scene with a ``[controller]`` is searched in closed loop: each return runs a controller made
anew from the section, restored to the memory guess (``legsim.orbits.problem``); the memory
values join the unknowns and can be guessed by name in ``orbit.guess``. A controller that does
not declare its memory is refused, naming the ``controller`` field.
Every error is a ``SceneError`` naming the file and the ``orbit.KEY`` at fault.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..accuracy import OrbitSection
from ..builders import Param, resolve_parameters
from ..errors import LegsimError, SceneError
from ..graph import reachable_modes
from ..orbits import MAX_FD_STEP, OrbitError, OrbitProblem, Section
from ..orbits.sections import bind_section
from .controller import scene_controller
from .fields import check_keys, describe, field_error, table_at
from .files import parse_override
from .integrator import check_step_rule, validated_integrator

#: Keys of a scene's ``[orbit]`` section and what they hold.
ORBIT_KEYS = {
    "section": "{ after = TRANSITION } (with mode = MODE where transitions of that name lead to several modes) "
    "or { mode = MODE, coordinate = NAME, value = 0.0, direction = "
    "'decreasing' | 'increasing' | 'either' }",
    "fixed": "coordinates held at their initial values, or controller memory values held at their guesses "
    "(list of names, each once, none also cyclic)",
    "cyclic": "coordinates along a symmetry, left out of periodicity; their increment is the step length "
    "(each once, not the section's coordinate, leaving at least one multiplier)",
    "free": "parameters solved for: robot parameter names or EFFECT.PARAM (each once)",
    "energy": "energy level of the orbit (J), when the system defines an energy",
    "guess": "initial guess by coordinate or controller memory name (default: the scene's [initial] "
    "state and a fresh controller's memory)",
    "tol": "convergence tolerance on the orbit equations (state units), default 1e-9",
    "max_iterations": "Newton iterations, default 30",
    "jacobian": "'saltation' (default) or 'fd'; a scene with a [controller] always uses 'fd'",
    "fd_step": "relative finite-difference step in (0, 0.1], default 1e-6 (see legsim.orbits)",
    "singular_tol": "relative singular value below which the Jacobian is singular, in (0, 1), default 1e-9",
    "t_max": "time limit of one return (s), default the scene's integrator.t_final",
    "returns": "returns per period (2 for a period-two orbit), default 1",
    "min_transitions": "transitions before a crossing section counts, default 1 (not with { after = ... })",
    "min_time": "time (s) before a crossing section counts, default 0 (not with { after = ... })",
    "max_transitions": "transition budget of one return, default 10000",
    "trivial_multipliers": "multipliers equal to 1 by a conserved quantity, left out of the stability verdict",
    "integrator": "the search's own integrator settings where they differ from the run's: a table of "
    "method, h, eps, rtol, atol, landing, max_halvings, over [integrator]",
}

#: Keys of a scene's ``[accuracy]`` section: where ``--check-accuracy`` compares a run and its
#: refinement along the orbit (``legsim.accuracy.along_orbit``).
ACCURACY_KEYS = {
    "along": "'entries' (the run's entries into its initial mode; the default), 'orbit' (the crossings of "
    "the [orbit] section, counted as its return map counts them) or a section table as orbit.section's",
    "min_transitions": "for a section table: transitions before a crossing counts, default 1",
    "min_time": "for a section table: time (s) before a crossing counts, default 0",
}

#: The ``[integrator]`` settings every return of the orbit search runs with, as in ``legsim run``
#: (t0 and t_final are not: a return starts at 0 and its horizon is ``orbit.t_max``).
INTEGRATOR_KEYS = ("method", "h", "eps", "rtol", "atol", "landing", "max_halvings")

#: Keys of a crossing section's table (``{ after = ... }`` takes no other).
LEVEL_SECTION_KEYS = ("mode", "coordinate", "value", "direction")


@dataclass
class OrbitSettings:
    """An orbit problem read from a scene, with the solver settings (keyword arguments of
    ``find_orbit``) and the initial guess, shape (n,)."""

    problem: OrbitProblem
    guess: np.ndarray
    solver: dict[str, Any]
    scene: Any


def problem_from_scene(scene: Any, *, extra_parameters: Sequence[str] = ()) -> OrbitSettings:
    """Read a scene's ``[orbit]`` section (keys: ``ORBIT_KEYS``) into an ``OrbitProblem``.

    The system is rebuilt by the scene's builder for each value of the free (and
    ``extra_parameters``, e.g. a continuation parameter) parameters; the integrator settings
    (``INTEGRATOR_KEYS``) come from ``[integrator]``, the initial guess from ``[initial]``
    (overridden by ``orbit.guess``), whose mode must be the section's. Errors are ``SceneError``
    naming the file and key.
    """
    table = _orbit_table(scene)
    section = _section(scene, table)
    free = _names(scene, table, "free")
    params, factory = _parameter_factory(scene, free, extra_parameters)
    jacobian = table.get("jacobian", "saltation")
    if jacobian not in ("saltation", "fd"):
        raise _fail(scene, "jacobian", f"expected 'saltation' or 'fd', got {describe(jacobian)}")
    if section.kind == "transition":
        _refuse_counts(
            scene,
            table,
            "counts crossings of a level section; an { after = ... } section returns at each such transition, "
            "so it takes neither min_transitions nor min_time",
        )
    problem = _problem(scene, table, section, free, params, factory)
    if problem.bound.mode != scene.initial_mode:
        raise _fail(
            scene,
            "section",
            f"the section lies in mode '{problem.bound.mode}' but the scene starts "
            f"in '{scene.initial_mode}': set [initial] mode = \"{problem.bound.mode}\"",
        )
    x0, memory = _guess(scene, table, problem)
    solver = _solver(scene, table, jacobian)
    if problem.controller is not None:
        solver["memory"] = memory
    return OrbitSettings(problem, problem.state_vector(x0), solver, scene)


def accuracy_section(scene: Any) -> OrbitSection | None:
    """Where ``--check-accuracy`` compares the scene's run and its refinement along the orbit
    (``legsim.accuracy.along_orbit``), from its ``[accuracy]`` section (``ACCURACY_KEYS``); None
    for the default, the run's entries into its initial mode. Raises SceneError naming the field
    for a bad section."""
    table = scene.sections.get("accuracy")
    if table is None:
        return None
    check_keys(scene.path, table, sorted(ACCURACY_KEYS), "accuracy")
    along = table.get("along", "entries")
    if along == "entries":
        _refuse_counts(scene, table, "counts crossings of a section; along = 'entries' has none", "accuracy")
        return None
    if along == "orbit":
        if scene.sections.get("orbit") is None:
            raise _fail(scene, "along", "'orbit' compares at the [orbit] section; the scene has none", "accuracy")
        _refuse_counts(scene, table, "with along = 'orbit' the [orbit] section's own counts apply", "accuracy")
        orbit = _orbit_table(scene)
        return _bound_section(scene, _section(scene, orbit), orbit, "orbit", "section")
    if isinstance(along, dict):
        return _bound_section(scene, _section(scene, table, "accuracy", "along"), table, "accuracy", "along")
    raise _fail(scene, "along", f"expected 'entries', 'orbit' or a section table, got {describe(along)}", "accuracy")


def _bound_section(scene: Any, section: Section, table: Mapping[str, Any], where: str, key: str) -> OrbitSection:
    """``section`` resolved against the scene's model, with the counts of ``table``."""
    try:
        bound = bind_section(section, scene.model.system)
    except OrbitError as exc:
        raise _fail(scene, key, str(exc), where) from None
    if section.transition is not None:
        return OrbitSection(bound.mode, section.label, transition=section.transition)
    return OrbitSection(
        bound.mode,
        section.label,
        bound.s,
        section.direction,
        min_transitions=_number(scene, table, "min_transitions", 1, int, 0, where),
        min_time=_number(scene, table, "min_time", 0.0, low=0.0, where=where),
    )


def _refuse_counts(scene: Any, table: Mapping[str, Any], why: str, where: str = "orbit") -> None:
    """Refuse ``min_transitions`` or ``min_time`` in ``table`` where no crossing is counted, rather
    than ignore them: a reader who set one expects it to change which return counts."""
    counts = sorted(set(table) & {"min_transitions", "min_time"})
    if counts:
        raise _fail(scene, counts[0], why, where)


def _fail(scene: Any, key: str, message: str, where: str = "orbit") -> SceneError:
    return field_error(scene.path, f"{where}.{key}", message)


def _orbit_table(scene: Any) -> dict[str, Any]:
    table = scene.sections.get("orbit")
    if table is None:
        names = _transition_names(scene)
        example = names[0] if names else "touchdown"
        listed = f" (its transitions: {', '.join(names[:8])}{', ...' if len(names) > 8 else ''})" if names else ""
        raise _fail(
            scene,
            "section",
            f'the scene has no [orbit] section; add one, e.g. [orbit] section = {{ after = "{example}" }}{listed}',
        )
    unknown = sorted(set(table) - set(ORBIT_KEYS))
    if unknown:
        # Named by the first unknown key's own path, where a typo is looked for.
        check_keys(scene.path, table, sorted(ORBIT_KEYS), f"orbit.{unknown[0]}")
    return table


def _transition_names(scene: Any) -> list[str]:
    """The names of the transitions of the modes the scene's run can reach, sorted (none when
    the model cannot list them)."""
    system = scene.model.system
    try:
        modes = reachable_modes(system, scene.initial_mode)
        return sorted({tr.name for mode in modes for tr in system.outgoing(mode)})
    except LegsimError:
        return []


def _section(scene: Any, table: Mapping[str, Any], where: str = "orbit", key: str = "section") -> Section:
    """The section at ``[where].key``: ``{ after = ... }`` or a level crossing."""
    if key not in table:
        raise _fail(scene, key, f"missing; expected {ORBIT_KEYS['section']}", where)
    sec = table_at(scene.path, table, key, f"{where}.{key}")
    try:
        if "after" in sec:
            return _after_section(scene, sec, where, key)
        if set(sec) - set(LEVEL_SECTION_KEYS) or "coordinate" not in sec:
            raise _fail(scene, key, f"expected {ORBIT_KEYS['section']}, got keys {sorted(sec)}", where)
        value = sec.get("value", 0.0)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise _fail(scene, f"{key}.value", f"expected a number, got {describe(value)}", where)
        return Section.level(
            sec.get("mode", scene.initial_mode), sec["coordinate"], value, sec.get("direction", "decreasing")
        )
    except OrbitError as exc:
        raise _fail(scene, key, str(exc), where) from None


def _after_section(scene: Any, sec: Mapping[str, Any], where: str, key: str) -> Section:
    """``{ after = TRANSITION }``, or ``{ after = TRANSITION, mode = MODE }`` for transitions of
    that name that lead to several modes; the names are checked against the model when the
    problem is built."""
    if set(sec) - {"after", "mode"}:
        raise _fail(scene, key, f"'after' takes only 'mode' besides, got {sorted(sec)}", where)
    for name in sec:
        if not isinstance(sec[name], str) or not sec[name]:
            raise _fail(
                scene,
                f"{key}.{name}",
                f"expected a {'transition' if name == 'after' else 'mode'} name, got {describe(sec[name])}",
                where,
            )
    return Section.after(sec["after"], sec.get("mode"))


def _names(scene: Any, table: Mapping[str, Any], key: str) -> tuple[str, ...]:
    value = table.get(key, [])
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise _fail(scene, key, f"expected a list of names, got {describe(value)}")
    return tuple(value)


def _number(
    scene: Any,
    table: Mapping[str, Any],
    key: str,
    default: Any,
    kind: type = float,
    low: float | None = None,
    where: str = "orbit",
) -> Any:
    """``table[key]`` (or ``default``) as a ``kind``, finite and >= ``low``; None stays None."""
    value = table.get(key, default)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or (kind is int and not isinstance(value, int)):
        raise _fail(scene, key, f"expected {'an integer' if kind is int else 'a number'}, got {describe(value)}", where)
    if not math.isfinite(value) or (low is not None and value < low):
        raise _fail(scene, key, f"must be finite{'' if low is None else f' and >= {low}'}, got {value!r}", where)
    return kind(value)


def _real_parameter(scene: Any, name: str, label: str) -> tuple[Param, float]:
    """(spec, value) of a real-valued robot parameter ``name`` or effect parameter
    ``EFFECT.PARAM``; errors name ``label`` (the [orbit] key, or the continued parameter)."""

    def fail(message: str) -> SceneError:
        return field_error(scene.path, label, message)

    builder = scene.builder
    if name.startswith("controller."):
        raise fail(
            f"'{name}' is a controller's parameter; only the robot's parameters (NAME) and its effects' "
            f"(EFFECT.PARAM) can be solved for or continued. To follow an orbit along a controller's "
            f"parameter, sweep it: legsim sweep SCENE --orbit --grid {name}=A:B:N"
        )
    if "." in name:
        effect, param = name.split(".", 1)
        if effect not in builder.effects:
            raise fail(
                f"unknown effect '{effect}' in '{name}': a parameter is the robot's (NAME: "
                f"{sorted(builder.parameters)}) or an effect's (EFFECT.PARAM; effects: {sorted(builder.effects)})"
            )
        if effect not in scene.effects:
            raise fail(f"effect '{effect}' is switched off in this scene")
        schema = builder.effects[effect].parameters
        if param not in schema:
            raise fail(f"effect '{effect}' has no parameter '{param}'; parameters: {sorted(schema)}")
        spec, value = schema[param], scene.effects[effect][param]
    else:
        if name not in builder.parameters:
            raise fail(f"robot '{scene.robot}' has no parameter '{name}'; parameters: {sorted(builder.parameters)}")
        spec, value = builder.parameters[name], scene.parameters[name]
    if type(spec.default) is not float:
        raise fail(
            f"parameter '{name}' is {type(spec.default).__name__}-valued; only real parameters can be "
            f"solved for or continued"
        )
    return spec, float(value)


def _parameter_factory(
    scene: Any, free: Sequence[str], extra: Sequence[str]
) -> tuple[dict[str, float], Callable[[Mapping[str, float]], Any]]:
    """(the scene's values of the free and extra parameters, a factory that builds the scene's
    model for new values of them, each checked against its spec)."""
    params: dict[str, float] = {}
    specs: dict[str, Param] = {}
    for name in tuple(free) + tuple(extra):
        label = "orbit.free" if name in free else "continued parameter"
        specs[name], params[name] = _real_parameter(scene, name, label)
    base_params = dict(scene.parameters)
    base_effects = {k: dict(v) for k, v in scene.effects.items()}
    builder = scene.builder
    where = f"{scene.path}: orbit"

    def factory(values: Mapping[str, float]) -> Any:
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

    return params, factory


def _problem(
    scene: Any,
    table: Mapping[str, Any],
    section: Section,
    free: tuple[str, ...],
    params: dict[str, float],
    factory: Callable[[Mapping[str, float]], Any],
) -> OrbitProblem:
    integ = _search_integrator(scene, table)
    energy = _number(scene, table, "energy", None)
    try:
        return OrbitProblem(
            system=factory if params else scene.model,
            section=section,
            **{key: integ[key] for key in INTEGRATOR_KEYS},
            t_max=_number(scene, table, "t_max", integ["t_final"], low=0.0),
            parameters=params,
            free=free,
            fixed=_names(scene, table, "fixed"),
            cyclic=_names(scene, table, "cyclic"),
            energy=energy,
            returns=_number(scene, table, "returns", 1, int, 1),
            min_transitions=_number(scene, table, "min_transitions", 1, int, 0),
            min_time=_number(scene, table, "min_time", 0.0, low=0.0),
            max_transitions=_number(scene, table, "max_transitions", 10_000, int, 1),
            trivial_multipliers=_number(scene, table, "trivial_multipliers", 0, int, 0),
            controller=_controller_maker(scene),
        )
    except OrbitError as exc:
        if exc.key in INTEGRATOR_KEYS or exc.key == "controller":
            where = "controller" if exc.key == "controller" else f"integrator.{exc.key}"
            raise field_error(scene.path, where, str(exc)) from None
        raise _fail(scene, exc.key or "section", str(exc)) from None


def shadowed_integrator_keys(scene: Any, overrides: Sequence[str]) -> dict[str, Any]:
    """The ``integrator.KEY=value`` overrides whose key the scene's ``[orbit.integrator]`` sets
    for the search, which they therefore do not reach: {KEY: the search's value}."""
    own = (scene.sections.get("orbit") or {}).get("integrator")
    if not isinstance(own, Mapping):
        return {}
    paths = [parse_override(text)[0] for text in overrides]
    return {path[1]: own[path[1]] for path in paths if len(path) == 2 and path[0] == "integrator" and path[1] in own}


def _search_integrator(scene: Any, table: Mapping[str, Any]) -> dict[str, Any]:
    """The integrator settings of the search's returns: the scene's ``[integrator]``, with
    ``[orbit.integrator]``'s keys (``INTEGRATOR_KEYS``) over it, validated as a whole (a return
    map resolves what its integrator resolves: a gait's map may need finer settings than its
    run), each error naming ``orbit.integrator.KEY``."""
    override = table.get("integrator")
    if override is None:
        return dict(scene.integrator)
    if not isinstance(override, Mapping):
        raise field_error(
            scene.path, "orbit.integrator", f"expected a table of {list(INTEGRATOR_KEYS)}, got {describe(override)}"
        )
    unknown = sorted(set(override) - set(INTEGRATOR_KEYS))
    if unknown:
        raise field_error(
            scene.path,
            f"orbit.integrator.{unknown[0]}",
            f"not an integrator setting of the search; allowed: {list(INTEGRATOR_KEYS)}",
        )
    merged = {k: v for k, v in scene.integrator.items() if v is not None}
    merged.update(override)
    settings = validated_integrator(scene.path, merged, "orbit.integrator")
    check_step_rule(scene.path, scene.model.info, settings, "orbit.integrator")
    return settings


def _controller_maker(scene: Any) -> Callable[[Any], Any] | None:
    """``controller(model)``: the scene's ``[controller]`` made anew for a model (the scene's, or
    one the factory built for other parameter values); None without the section."""
    if getattr(scene, "make_controller", None) is None:
        return None
    table = table_at(scene.path, scene.data, "controller")
    return functools.partial(scene_controller, scene.path, table)


def _guess(scene: Any, table: Mapping[str, Any], problem: OrbitProblem) -> tuple[np.ndarray, np.ndarray]:
    """The scene's initial state and the controller's memory (shapes (n,), (m,)) with
    ``orbit.guess`` applied: a coordinate or a memory value by name."""
    x0 = np.asarray(scene.initial_state, dtype=float).copy()
    memory = problem.memory_guess.copy()
    guess = table.get("guess", {})
    if not isinstance(guess, dict):
        raise _fail(scene, "guess", f"expected a table of coordinate = number, got {describe(guess)}")
    for key, value in guess.items():
        if key not in problem.names and key not in problem.memory_names:
            memory_note = f"; controller memory: {list(problem.memory_names)}" if problem.memory_names else ""
            raise _fail(scene, "guess", f"unknown coordinate '{key}'; coordinates: {list(problem.names)}{memory_note}")
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise _fail(scene, f"guess.{key}", f"expected a finite number, got {describe(value)}")
        if key in problem.names:
            x0[problem.names.index(key)] = float(value)
        else:
            memory[problem.memory_names.index(key)] = float(value)
    return x0, memory


def _solver(scene: Any, table: Mapping[str, Any], jacobian: str) -> dict[str, Any]:
    """The keyword arguments of ``find_orbit``."""
    solver = {
        "tol": _number(scene, table, "tol", 1e-9, low=0.0),
        "max_iterations": _number(scene, table, "max_iterations", 30, int, 0),
        "jacobian": jacobian,
        "fd_step": _number(scene, table, "fd_step", None, low=0.0),
        "singular_tol": _number(scene, table, "singular_tol", 1e-9, low=0.0),
    }
    if solver["tol"] == 0:
        raise _fail(scene, "tol", "must be > 0")
    if solver["fd_step"] is not None and not 0.0 < solver["fd_step"] <= MAX_FD_STEP:
        raise _fail(scene, "fd_step", f"must be a relative step in (0, {MAX_FD_STEP:g}], got {solver['fd_step']!r}")
    # A ratio of singular values is at most 1: from 1 on every Jacobian would count as singular.
    if not 0.0 < solver["singular_tol"] < 1.0:
        raise _fail(
            scene, "singular_tol", f"must be a ratio of singular values in (0, 1), got {solver['singular_tol']!r}"
        )
    return solver
