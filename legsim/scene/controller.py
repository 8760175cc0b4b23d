"""The ``[controller]`` section: a controller from the registry (``legsim.controllers``) with
its parameters, for the scene's model::

    [controller]
    name = "raibert"                 # a registered controller (see `legsim scenes --controllers`)
    hold = true                      # optional: zero-order hold over each step (default: the controller's)
    [controller.parameters]
    speed = 1.0
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

from ..builders import Model
from ..control import ControlLaw, Controller, available, get_controller
from ..errors import LegsimError, SceneError
from .fields import check_keys, describe, field_error

CONTROLLER_KEYS = {
    "name": "a registered controller's name",
    "parameters": "a table of its parameters",
    "hold": "true: hold u over each step (zero-order hold); false: evaluate it at every stage",
}


def scene_controller(path: Path, table: dict[str, Any], model: Model) -> Controller | ControlLaw | None:
    """The controller the section asks for, made for ``model``; None without the section."""
    if not table:
        return None
    check_keys(path, table, CONTROLLER_KEYS, "controller")
    name = table.get("name")
    if not isinstance(name, str):
        raise field_error(
            path,
            "controller.name",
            f"expected a controller name, got {describe(name)}; available: {sorted(available())}",
        )
    try:
        spec = get_controller(name)
    except SceneError as exc:
        raise field_error(path, "controller.name", str(exc)) from None
    parameters = table.get("parameters", {})
    try:
        controller = spec.build(model, parameters, str(path))
    except SceneError:
        raise
    except LegsimError as exc:
        raise field_error(path, "controller", str(exc)) from exc
    hold = table.get("hold")
    if hold is not None:
        if not isinstance(hold, bool):
            raise field_error(path, "controller.hold", f"expected true or false, got {describe(hold)}")
        if isinstance(controller, ControlLaw):
            controller = dataclasses.replace(controller, hold=hold)
        else:
            controller.hold = hold
    return controller
