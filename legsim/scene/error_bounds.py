"""Keys and checks shared by the sections of the tools built on the error bounds of paper 004,
``[certify]`` and ``[stochastic]``: the fixed-step numerical solution (h, method), its local
error estimation (pair, floor) and the end time, with defaults from ``[integrator]``."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ..bounds import check_steps
from ..builders import Param, resolve_parameters
from ..errors import SimulationError
from .fields import field_error

#: Embedded pairs a section may name for its local error estimates; ``auto`` is the method
#: itself when it is embedded, else dopri5.
PAIRS = ("auto", "bs32", "dopri5", "rk23", "rk45", "dp54")


def numerical_solution_keys(scene: Any, h_help: str) -> dict[str, Param]:
    """The ``h``, ``method``, ``pair``, ``floor`` and ``t_final`` keys (s for times), with
    defaults from the scene's ``[integrator]``; ``h_help`` says what h is for in the tool."""
    from ..methods import ALIASES, METHODS

    integ = scene.integrator
    return {
        "h": Param(float(integ["h"]), h_help, "s", low=0.0, low_open=True),
        "method": Param(
            str(integ["method"]),
            "Runge-Kutta method of the numerical solution",
            choices=tuple(sorted(METHODS) + sorted(ALIASES)),
        ),
        "pair": Param(
            "auto",
            "embedded pair of the local error estimates (auto: the method if embedded, else dopri5)",
            choices=PAIRS,
        ),
        "floor": Param(0.0, "declared local error floor coefficient (state units / s^(p+1))", low=0.0),
        "t_final": Param(float(integ["t_final"]), "end time", "s"),
    }


def start_time(scene: Any) -> float:
    """The scene's start time t0 (s)."""
    return float(scene.integrator.get("t0", 0.0))


def pair_argument(settings: Mapping[str, Any]) -> str | None:
    """The ``pair`` argument of the tools: None for ``auto``."""
    return None if settings["pair"] == "auto" else settings["pair"]


def read_settings(
    scene: Any, section: str, schema: Mapping[str, Param], overrides: Mapping[str, Any] | None
) -> dict[str, Any]:
    """The scene's ``[section]`` checked against ``schema`` (``overrides`` that are not None take
    precedence), with t_final after t0 and a number of steps of h the flows accept. Raises
    SceneError naming the file and key."""
    given = dict(scene.sections.get(section, {}))
    given.update({k: v for k, v in (overrides or {}).items() if v is not None})
    settings = resolve_parameters(schema, given, f"{scene.path}: {section}")
    t0 = start_time(scene)
    if not settings["t_final"] > t0:
        raise field_error(scene.path, f"{section}.t_final", f"must be > t0 = {t0}, got {settings['t_final']}")
    try:
        check_steps(settings["t_final"] - t0, settings["h"], section)
    except SimulationError as exc:
        raise field_error(scene.path, f"{section}.h / {section}.t_final", str(exc)) from None
    return settings
