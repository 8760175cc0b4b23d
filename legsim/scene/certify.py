"""A scene's ``[certify]`` section, read into the arguments of ``legsim.certify.certify``.

Keys (``section_schema``): h, method, pair, floor, t_final (defaults from ``[integrator]``),
alpha, max_refinements, max_transitions. ``certify_scene`` certifies the scene's execution from
its initial mode and state with them.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from ..builders import Param
from ..certify import Certificate, certify
from .error_bounds import numerical_solution_keys, pair_argument, read_settings, start_time


def section_schema(scene: Any) -> dict[str, Param]:
    """The keys of a scene's ``[certify]`` section, with defaults from its ``[integrator]``."""
    shared = numerical_solution_keys(scene, "initial step, divided by alpha at each refinement")
    return {
        "h": shared["h"],
        "method": shared["method"],
        "pair": shared["pair"],
        "floor": shared["floor"],
        "alpha": Param(2.0, "refinement factor h := h / alpha", low=1.0, low_open=True),
        "max_refinements": Param(6, "most refinements", low=0),
        "t_final": shared["t_final"],
        "max_transitions": Param(1000, "most transitions certified", low=1),
    }


def scene_settings(scene: Any, overrides: dict[str, Any] | None = None) -> dict[str, Any]:
    """The validated ``[certify]`` settings of a scene (``overrides`` take precedence).
    Raises SceneError naming the file and key."""
    return read_settings(scene, "certify", section_schema(scene), overrides)


def certify_scene(
    scene: Any, overrides: dict[str, Any] | None = None, *, progress: Callable[[int, float, float], None] | None = None
) -> Certificate:
    """Certify the transitions of a scene's execution (its ``[certify]`` section, defaults from
    ``[integrator]``) from the scene's initial mode and state; ``progress`` as in ``certify``."""
    s = scene_settings(scene, overrides)
    cert = certify(
        scene.model.system,
        scene.initial_mode,
        scene.initial_state,
        s["t_final"],
        s["h"],
        s["method"],
        t0=start_time(scene),
        pair=pair_argument(s),
        control=scene.model.control,
        floor=s["floor"],
        alpha=s["alpha"],
        max_refinements=s["max_refinements"],
        max_transitions=s["max_transitions"],
        progress=progress,
    )
    cert.settings["scene"] = scene.name
    return cert
