"""The run summary: the one JSON object that describes a run.

``legsim run --json`` prints it, a Rerun recording stores it (``legsim replay --json`` prints
it back), ``run_summary(execution)`` and ``Scene.summary()`` return it. Its keys are public:

* from the execution: ``system``, ``status``, ``message``, ``t_final`` (the time reached, s),
  ``final_mode``, ``final_state``, ``state_names`` (of the final mode), ``final_in_strip``,
  ``mode_sequence``, ``transitions`` (a count), ``steps``, ``halvings``, ``field_evals``,
  ``guard_evals``, ``reset_evals``, ``strip_time`` (total time held in strips, s),
  ``longest_strip_hold`` (s), ``wall_time_s``, ``h``, ``eps``, ``method``, ``warnings`` (what the
  run cannot vouch for: a list of ``{kind, message, time, ...}``, see ``RunWarning``);
* with a scene: ``scene`` (its name) and ``robot``;
* when the system defines an energy: ``energy_initial`` and ``energy_final`` (J);
* every other counter of ``execution.counters`` (the model's own, ``error_rejections``);
* with a scene read from a file: ``scene_file``;
* from the commands that write files: ``outputs`` (kind -> path written).

Numbers that are not finite become None, so the summary is valid JSON.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from ..errors import ModelError
from ..hybrid import HybridSystem

if TYPE_CHECKING:
    from ..builders import Model
    from ..execution import Execution


class SceneLike(Protocol):
    """What the summary reads of a scene (a ``legsim.scene.Scene``): its name, robot, model
    and the file it was read from (None for a scene made in code)."""

    @property
    def name(self) -> str: ...
    @property
    def robot(self) -> str: ...
    @property
    def model(self) -> Model: ...
    @property
    def path(self) -> Path | None: ...


#: ``energy(mode, x) -> float`` (J), as ``HybridSystem.energy``.
EnergyFn = Callable[[str, np.ndarray], float]


def run_summary(
    execution: Execution,
    scene: SceneLike | None = None,
    model: Model | HybridSystem | None = None,
    *,
    outputs: Mapping[str, str | Path] | None = None,
) -> dict[str, Any]:
    """The JSON-ready summary of ``execution`` (keys: see the module docstring).

    ``scene`` (a ``legsim.scene.Scene``) adds its name, robot and file; its model, or else
    ``model=`` (a ``legsim.builders.Model`` or a ``HybridSystem``), gives the energies at the
    start and the end of the run. ``outputs`` (kind -> path) is added as ``outputs`` by
    commands that wrote files.
    """
    if scene is not None:
        model = scene.model
    system = model if isinstance(model, HybridSystem) else None if model is None else model.system
    out = _execution_keys(execution)
    if scene is not None:
        out["scene"] = scene.name
        out["robot"] = scene.robot
    if system is not None and system.energy is not None and execution.segments:
        out.update(_energies(execution, system.energy, system.name))
    for key, value in execution.counters.items():
        out.setdefault(key, value)
    if scene is not None and scene.path is not None:
        out["scene_file"] = str(scene.path)
    if outputs is not None:
        out["outputs"] = {kind: str(path) for kind, path in outputs.items()}
    return finite_or_none(out)


def _execution_keys(execution: Execution) -> dict[str, Any]:
    """The keys every run has: status, final state, mode sequence, counters, settings."""
    mode, x = execution.final_mode, execution.final_state
    counters, settings = execution.counters, execution.settings
    return {
        "system": execution.system_name,
        "status": execution.status,
        "message": execution.message,
        "t_final": float(execution.t_end),
        "final_mode": mode,
        "final_state": [float(v) for v in x],
        "state_names": list(execution.state_names.get(mode, ())),
        "final_in_strip": bool(execution.final_in_strip),
        "mode_sequence": execution.mode_sequence,
        "transitions": len(execution.transitions),
        "steps": int(counters.get("steps", 0)),
        "halvings": int(counters.get("halvings", 0)),
        "field_evals": int(counters.get("field_evals", 0)),
        "guard_evals": int(counters.get("guard_evals", 0)),
        "reset_evals": int(counters.get("reset_evals", 0)),
        "strip_time": float(counters.get("strip_time", 0.0)),
        "wall_time_s": float(counters.get("wall_time_s", 0.0)),
        "h": settings.get("h"),
        "eps": settings.get("eps"),
        "method": settings.get("method"),
        "longest_strip_hold": longest_hold(execution),
        "warnings": [w.as_dict() for w in execution.warnings],
    }


def longest_hold(execution: Execution) -> float:
    """The longest time (s) the state was held in one strip."""
    return max((strip.exit_time - strip.time for strip in execution.strips), default=0.0)


def _energies(execution: Execution, energy: EnergyFn, system: str) -> dict[str, float | None]:
    """``energy_initial`` at the first computed point and ``energy_final`` at t_end (J).

    A run that stopped early (non_finite, ...) may end on a state the energy cannot take (a
    float overflow); its summary must still be printed, so its final energy is then None.
    After a finished run a failing energy is the model's bug and is raised.
    """
    first = execution.segments[0]
    initial = _energy(energy, system, first.mode, first.x[0].copy())
    try:
        final = _energy(energy, system, execution.final_mode, execution.final_state)
    except ModelError:
        if execution.status == "finished":
            raise
        final = None
    return {"energy_initial": initial, "energy_final": final}


def _energy(energy: EnergyFn, system: str, mode: str, x: np.ndarray) -> float:
    """The energy (J) of the system named ``system`` at (mode, x); ModelError naming the mode
    when it fails."""
    try:
        return float(energy(mode, np.asarray(x, dtype=float)))
    except Exception as exc:
        raise ModelError(f"{system}: energy in mode '{mode}' failed: {type(exc).__name__}: {exc}") from exc


def finite_or_none(obj: Any) -> Any:
    """``obj`` (nested dicts and lists) with numpy scalars made Python numbers and floats that
    are not finite replaced by None, so that ``json.dumps(..., allow_nan=False)`` accepts it."""
    if isinstance(obj, dict):
        return {k: finite_or_none(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [finite_or_none(v) for v in obj]
    if isinstance(obj, (np.floating, np.integer)):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj
