"""A scene's ``[stochastic]`` section, read into the arguments of
``legsim.stochastic.sample_ensemble``.

Keys (``section_schema``): samples, seed, h, method, pair, floor, t_final (defaults from
``[integrator]``), intensity, max_transitions, carry, hazard_cap. ``ensemble_from_scene``
samples the scene's stochastic approximation from its initial mode and state with them.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

from ..builders import Param
from ..stochastic import HAZARD_CAP, INTENSITIES, MAX_SAMPLES, Ensemble, sample_ensemble
from .error_bounds import numerical_solution_keys, pair_argument, read_settings, start_time


def section_schema(scene: Any) -> dict[str, Param]:
    """The keys of a scene's ``[stochastic]`` section, with defaults from its ``[integrator]``."""
    shared = numerical_solution_keys(scene, "fixed step of the numerical solution")
    return {
        "samples": Param(100, "number of sampled executions", low=1, high=MAX_SAMPLES),
        "seed": Param(0, "seed of the random generator", low=0),
        "h": shared["h"],
        "method": shared["method"],
        "pair": shared["pair"],
        "floor": shared["floor"],
        "intensity": Param("hazard", "reading of the intensity (see legsim.stochastic)", choices=INTENSITIES),
        "t_final": shared["t_final"],
        "max_transitions": Param(1000, "most switches of one sampled execution", low=0),
        "carry": Param(True, "carry the error ball through switches"),
        "hazard_cap": Param(
            HAZARD_CAP,
            "most hazard per error-ball radius moved relative to a guard "
            "(bounded intensities: no Zeno behaviour; 1e300: in effect none)",
            low=0.0,
            low_open=True,
        ),
    }


def scene_settings(scene: Any, overrides: dict[str, Any] | None = None) -> dict[str, Any]:
    """The validated ``[stochastic]`` settings of a scene (``overrides``, e.g. from the command
    line, take precedence). Raises SceneError naming the file and key."""
    return read_settings(scene, "stochastic", section_schema(scene), overrides)


def ensemble_from_scene(
    scene: Any,
    overrides: dict[str, Any] | None = None,
    *,
    progress: Callable[[int, int], None] | None = None,
    indices: Sequence[int] | None = None,
) -> Ensemble:
    """Monte Carlo ensemble of the scene's stochastic approximation (its ``[stochastic]``
    section, with defaults from ``[integrator]``) from the scene's initial mode and state;
    ``progress`` and ``indices`` (the executions to draw, default all) as in ``sample_ensemble``."""
    s = scene_settings(scene, overrides)
    ens = sample_ensemble(
        scene.model.system,
        scene.initial_mode,
        scene.initial_state,
        s["t_final"],
        s["h"],
        s["method"],
        samples=s["samples"],
        seed=s["seed"],
        t0=start_time(scene),
        pair=pair_argument(s),
        control=scene.model.control,
        floor=s["floor"],
        intensity=s["intensity"],
        max_transitions=s["max_transitions"],
        carry=s["carry"],
        hazard_cap=s["hazard_cap"],
        progress=progress,
        indices=indices,
    )
    ens.settings["scene"] = scene.name
    return ens
