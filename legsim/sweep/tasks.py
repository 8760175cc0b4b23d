"""What a worker does with a batch of variations: load each variation's scene, run it, measure
it, and return one row per variation. Nothing here raises for a variation: an error or a
timeout is that variation's row (``task_status``, ``error``), so one bad cell never ends a
sweep.

Every row depends only on the sweep's specification and its variation: scenes are loaded
afresh for each variation, and the only thing a worker keeps between rows is the reference gait
of a walk (found by a deterministic orbit search, once per worker and scene variant).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

from ..crossings import returns, takings
from ..errors import LegsimError, ModelError
from .measures import check_measures, measure_columns
from .spec import SweepError, SweepSpec, variation_overrides

#: Reference gaits a worker keeps (scene variants: different robot parameters or settings).
_GAIT_CACHE_SIZE = 64
_gaits: dict[tuple[str, ...], Any] = {}


class TaskTimeout(LegsimError):
    """A variation took longer than the sweep's ``timeout``."""


class Deadline:
    """``timeout`` seconds from now; ``check()`` raises ``TaskTimeout`` past it. As a
    ``progress(t, t0, t_final)`` callback of ``simulate`` it checks a few times a second."""

    def __init__(self, timeout: float | None) -> None:
        self.timeout = timeout
        self.end = None if timeout is None else time.perf_counter() + timeout

    def check(self) -> None:
        if self.end is not None and time.perf_counter() > self.end:
            raise TaskTimeout(f"timed out: the variation took longer than --timeout {self.timeout:g} s")

    def __call__(self, t: float, t0: float, t_final: float) -> None:
        self.check()

    @property
    def progress(self) -> Callable[[float, float, float], None] | None:
        """The callback for ``simulate``, or None without a timeout (no checks to pay for)."""
        return None if self.end is None else self


def run_batch(spec: SweepSpec, items: list[tuple[int, dict[str, Any]]]) -> list[dict[str, Any]]:
    """The rows of a batch of variations (index, field values)."""
    # A diverging run ends with status non_finite naming mode, time and state; numpy's overflow
    # warnings on the way would only fill the workers' logs.
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        return [run_variation(spec, index, values) for index, values in items]


def run_variation(spec: SweepSpec, index: int, values: dict[str, Any]) -> dict[str, Any]:
    """One variation's row: its inputs, task status and error, measures and wall time (s)."""
    from ..scene import load_scene

    start = time.perf_counter()
    row: dict[str, Any] = {"index": index, **values}
    deadline = Deadline(spec.timeout)
    try:
        scene = load_scene(spec.scene, list(spec.overrides) + variation_overrides(values))
        execution = None
        if spec.run == "scene":
            execution = scene.simulate(progress=deadline.progress)
            row.update(run_columns(scene, execution, spec.measures))
        elif spec.run == "walk":
            row.update(walk_row(scene, spec, values, deadline))
        if spec.orbit:
            row.update(orbit_columns(scene, deadline, execution if spec.orbit_guess == "run" else None))
        deadline.check()
        row.update(task_status="done", error=None)
    except TaskTimeout as exc:
        row.update(task_status="timeout", error=str(exc))
    except LegsimError as exc:
        row.update(task_status="error", error=str(exc))
    except Exception as exc:  # a model's own bug: that variation's row says so, the sweep goes on
        row.update(task_status="error", error=f"internal error: {type(exc).__name__}: {exc}")
    row["wall_time_s"] = time.perf_counter() - start
    return row


def run_columns(scene: Any, execution: Any, measures: tuple[str, ...] = ()) -> dict[str, Any]:
    """The scene's run to its t_final: the run summary's columns, ``fell`` and the ``measures``'
    columns (``legsim.sweep.measures``)."""
    from ..output.summary import run_summary

    summary = run_summary(execution, scene)
    out = {
        key: summary.get(key)
        for key in (
            "status",
            "message",
            "final_mode",
            "final_state",
            "transitions",
            "steps",
            "halvings",
            "field_evals",
            "guard_evals",
            "reset_evals",
            "energy_initial",
            "energy_final",
        )
    }
    out["t_end"] = summary["t_final"]
    # A run the method cannot vouch for (held in strips, an accumulation, ...) says so in its row.
    out["warnings"] = [f"{w['kind']}: {w['message']}" for w in summary["warnings"]]
    # A fall the scene declares ([fall]: status fell), or a model that says it left its range
    # (a compass gait's hip below the slope, a link through the ground under below_ground = "strict").
    out["fell"] = summary["status"] in ("fell", "model_breakdown")
    out.update(measure_columns(check_measures(measures), execution, scene.model.system))
    return out


def walk_row(scene: Any, spec: SweepSpec, values: dict[str, Any], deadline: Deadline) -> dict[str, Any]:
    """The scene walked until it falls or converges onto its reference gait (``legsim.sweep.walk``):
    run columns describing the walk, and the walk's verdict."""
    from ..scene.orbit import problem_from_scene
    from .walk import walk, walk_columns

    gait = reference_gait(spec, values)
    if not gait.converged:
        raise SweepError(
            f"no reference gait to walk to: the orbit search of the scene's [orbit] section "
            f"({gait.status}) {gait.message}"
        )
    problem = problem_from_scene(scene).problem
    result = walk(
        problem,
        scene.initial_state,
        scene.integrator["t0"],
        gait.fixed_point,
        max_steps=spec.max_steps,
        tol=spec.tol,
        progress=deadline.progress,
        # A walk is checked as a run is: the [fall] conditions and the model's own (a link
        # through the ground under below_ground = "fall" is a fall), at the walk's strip width.
        watches=scene.watches(scene.control, problem.eps),
    )
    out = {
        "status": result.status,
        "message": result.message,
        "t_end": result.t_end,
        "final_mode": result.mode,
        "final_state": [float(v) for v in result.state],
        "transitions": result.transitions,
        **{
            key: int(result.counters.get(key, 0))
            for key in ("steps", "halvings", "field_evals", "guard_evals", "reset_evals")
        },
        "energy_initial": _energy(scene, scene.initial_mode, scene.initial_state),
        "energy_final": _energy(scene, result.mode, result.state),
        "fell": result.outcome == "falls",
        "warnings": result.warnings,
    }
    out.update(walk_columns(result))
    return out


def _energy(scene: Any, mode: str, x: np.ndarray) -> float | None:
    try:
        value = scene.energy(mode, x)
    except ModelError:  # a state the energy cannot take (a diverged run's end)
        return None
    return value if value is not None and np.isfinite(value) else None


def reference_gait(spec: SweepSpec, values: dict[str, Any]) -> Any:
    """The orbit search of the scene with this variation's fields other than ``initial.*``
    (guess: the sweep's own initial state), once per worker and scene variant."""
    from ..orbits import find_orbit
    from ..scene import load_scene
    from ..scene.orbit import problem_from_scene

    kept = {k: v for k, v in values.items() if not k.startswith("initial.")}
    overrides = tuple(spec.overrides) + tuple(variation_overrides(kept))
    key = (spec.scene, *overrides)
    if key not in _gaits:
        settings = problem_from_scene(load_scene(spec.scene, list(overrides)))
        if len(_gaits) >= _GAIT_CACHE_SIZE:
            _gaits.clear()
        _gaits[key] = find_orbit(settings.problem, settings.guess, **settings.solver)
    return _gaits[key]


def orbit_columns(scene: Any, deadline: Deadline, execution: Any = None) -> dict[str, Any]:
    """The variation's periodic orbit, from its scene's ``[orbit]`` section and initial state,
    or with ``execution`` (``--orbit-guess run``) from the last crossing of the section in it."""
    from ..orbits import find_orbit
    from ..orbits.returns import memory_at_crossing
    from ..scene.orbit import problem_from_scene

    settings = problem_from_scene(scene)
    settings.problem.progress = deadline.progress
    guess, solver = settings.guess, dict(settings.solver)
    if execution is not None:
        crossing = last_crossing(settings.problem, execution)
        if crossing is None:
            return {
                "orbit_status": "no_guess",
                "orbit_message": f"no guess: the run never crossed the section {settings.problem.section.label}",
                "orbit_warnings": [],
            }
        t, state = crossing
        guess = state[: settings.problem.dim].copy()
        if settings.problem.controller is not None:
            solver["memory"] = memory_at_crossing(settings.problem, t, state[settings.problem.dim :], execution.t0)
    result = find_orbit(settings.problem, guess, **solver)
    deadline.check()  # a search cut short by the deadline reports a failed simulation: say why
    data = result.to_json()
    multipliers = data["multipliers"] or []
    # Where no orbit was found, the search's last iterate is no gait: its point, period and step
    # length are left out (null), as its multipliers are; its residual says how far it was.
    found = result.converged
    return {
        "orbit_status": data["status"],
        "orbit_message": data["message"],
        "orbit_fixed_point": data["fixed_point"] if found else None,
        "orbit_period": data["period"] if found else None,
        "orbit_step_length": data["step_length"] if found else None,
        "orbit_multipliers_re": [m[0] for m in multipliers] if data["multipliers"] is not None else None,
        "orbit_multipliers_im": [m[1] for m in multipliers] if data["multipliers"] is not None else None,
        "orbit_spectral_radius": data["spectral_radius"],
        "orbit_stable": data["stable"],
        "orbit_differentiable": data["differentiable"],
        "orbit_warnings": list(data["warnings"]),
        "orbit_residual": data["residual"],
        "orbit_iterations": data["iterations"],
    }


def last_crossing(problem: Any, execution: Any) -> tuple[float, np.ndarray] | None:
    """The time (s) and state at the last crossing of ``problem``'s section in a run (after its
    last taking of a transition section), a ``ControlLaw``'s memory after the plant's
    coordinates; None without one."""
    bound, section = problem.bound, problem.section
    if section.kind == "transition":
        found = takings(execution, section.transition, bound.mode)
    else:
        found = [(t, x) for _, t, x in returns(execution, bound.mode, bound.s, section.direction, 0, 0.0)]
    return None if not found else (float(found[-1][0]), np.asarray(found[-1][1], dtype=float).copy())
