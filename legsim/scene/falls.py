"""A scene's ``[fall]`` section: when a run has failed. Each condition is a stop watch
(``legsim.relaxed.watches``) that ends the run with status ``fell``, naming the condition, the
time and the mode::

    [fall]
    pitch_max = 1.0          # rad: |pitch| reaching it is a fall
    pitch = "pitch"          # the pitch coordinate (default "pitch")
    height_min = 0.2         # m: the height coordinate reaching it from above is a fall (on a
                             # [terrain], the height above the ground under the coordinate x)
    height = "z"             # the height coordinate (default "z")
    contacts = ["trunk"]     # contacts whose touchdown is a fall (a point contact on the link)

Every field is checked when the scene loads: unknown keys, values out of range, coordinates the
initial mode does not have, contacts the robot does not declare.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import SimulationError
from ..relaxed.watches import Watch
from ..terrain import Terrain
from .fields import check_keys, describe, field_error

FALL_KEYS = {
    "pitch_max": "the bound on |pitch| (rad, > 0)",
    "pitch": "the pitch coordinate's name (default 'pitch')",
    "height_min": "the bound below which the height coordinate (above the terrain under x) is a fall (m)",
    "height": "the height coordinate's name (default 'z')",
    "contacts": "contacts whose touchdown is a fall (names the robot declares)",
}
#: ``Model.info`` keys a builder sets so that ``[fall] contacts`` can be checked: the robot's
#: contact names, and ``active_contacts(mode) -> names`` of the contacts active in a mode.
CONTACT_NAMES, ACTIVE_CONTACTS = "contact_names", "active_contacts"


def fall_watches(
    path: Path, table: Mapping[str, Any], model: Any, mode: str, terrain: Terrain | None = None
) -> tuple[Watch, ...]:
    """The stop watches of a ``[fall]`` table, checked against the model and its initial mode;
    on a ``terrain`` other than level ground at 0, the height is taken above the ground under
    the coordinate ``x``."""
    check_keys(path, table, FALL_KEYS, "fall")
    system = model.system
    names = tuple(system.state_names(mode))
    out = []
    if "pitch_max" in table:
        bound = _number(path, "fall.pitch_max", table["pitch_max"], positive=True)
        index = _coordinate(path, "fall.pitch", table.get("pitch", "pitch"), names, mode)
        out.append(_pitch(system, names[index], bound))
    elif "pitch" in table:
        raise field_error(path, "fall.pitch", "given without fall.pitch_max, the bound it names the coordinate of")
    if "height_min" in table:
        bound = _number(path, "fall.height_min", table["height_min"])
        index = _coordinate(path, "fall.height", table.get("height", "z"), names, mode)
        ground = None
        if terrain is not None and not (terrain.flat and float(terrain.height(0.0)) == 0.0):
            _coordinate(path, "fall.height_min", "x", names, mode)  # the ground is under x
            ground = terrain
        out.append(_height(system, names[index], bound, ground))
    elif "height" in table:
        raise field_error(path, "fall.height", "given without fall.height_min, the bound it names the coordinate of")
    if "contacts" in table:
        out.append(_contacts(path, table["contacts"], model))
    return tuple(out)


def _number(path: Path, where: str, value: Any, positive: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise field_error(path, where, f"expected a finite number, got {describe(value)}")
    if positive and value <= 0:
        raise field_error(path, where, f"{value!r} is out of range, allowed: float in (0, inf)")
    return float(value)


def _coordinate(path: Path, where: str, name: Any, names: tuple[str, ...], mode: str) -> int:
    if not isinstance(name, str) or name not in names:
        raise field_error(
            path, where, f"{describe(name)} is not a coordinate of mode '{mode}'; coordinates: {list(names)}"
        )
    return names.index(name)


def _index_in(system: Any, coordinate: str) -> Callable[[str], int]:
    """The coordinate's index in each mode (SimulationError for a mode without it)."""
    cache: dict[str, int] = {}

    def index(mode: str) -> int:
        if mode not in cache:
            names = tuple(system.state_names(mode))
            if coordinate not in names:
                raise SimulationError(f"[fall]: mode '{mode}' has no coordinate '{coordinate}': {list(names)}")
            cache[mode] = names.index(coordinate)
        return cache[mode]

    return index


def _pitch(system: Any, coordinate: str, bound: float) -> Watch:
    index = _index_in(system, coordinate)

    def value(mode: str, t: np.ndarray, x: np.ndarray) -> np.ndarray:
        return bound - np.abs(x[:, index(mode)])

    def message(t: float, mode: str, x: np.ndarray) -> str:
        return (
            f"fell: pitch_max: |{coordinate}| = {abs(x[index(mode)]):.6g} rad reached pitch_max = {bound:g} rad "
            f"at t={t:.17g} in mode '{mode}'"
        )

    return Watch("pitch_max", value, "stop", message)


def _height(system: Any, coordinate: str, bound: float, ground: Terrain | None) -> Watch:
    """The watch of ``coordinate`` coming down to ``bound``: its value, or on ``ground`` its
    height above the terrain under the coordinate x."""
    index = _index_in(system, coordinate)
    along = _index_in(system, "x")
    above = "" if ground is None else " above the ground"

    def height(mode: str, x: np.ndarray) -> np.ndarray:
        if ground is None:
            return x[..., index(mode)]
        return x[..., index(mode)] - ground.height(x[..., along(mode)])

    def value(mode: str, t: np.ndarray, x: np.ndarray) -> np.ndarray:
        return height(mode, x) - bound

    def message(t: float, mode: str, x: np.ndarray) -> str:
        return (
            f"fell: height_min: {coordinate}{above} = {float(height(mode, x)):.6g} m reached height_min = "
            f"{bound:g} m at t={t:.17g} in mode '{mode}'"
        )

    return Watch("height_min", value, "stop", message)


def _contacts(path: Path, value: Any, model: Any) -> Watch:
    info = model.info if isinstance(model.info, Mapping) else {}
    declared, active = info.get(CONTACT_NAMES), info.get(ACTIVE_CONTACTS)
    if declared is None or not callable(active):
        raise field_error(path, "fall.contacts", f"robot '{model.system.name}' names no contacts in its modes")
    if not isinstance(value, list) or not value or not all(isinstance(v, str) for v in value):
        got = "an empty array" if value == [] else describe(value)
        raise field_error(path, "fall.contacts", f"expected a non-empty list of contact names, got {got}")
    unknown = sorted(set(value) - set(declared))
    if unknown:
        raise field_error(path, "fall.contacts", f"unknown contact(s) {unknown}; contacts: {list(declared)}")
    wanted = tuple(value)
    touching: dict[str, tuple[str, ...]] = {}

    def touched(mode: str) -> tuple[str, ...]:
        if mode not in touching:
            touching[mode] = tuple(c for c in active(mode) if c in wanted)
        return touching[mode]

    def values(mode: str, t: np.ndarray, x: np.ndarray) -> np.ndarray:
        return np.full(t.shape[0], -1.0 if touched(mode) else 1.0)

    def message(t: float, mode: str, x: np.ndarray) -> str:
        names = ", ".join(f"'{c}'" for c in touched(mode))
        return f"fell: contacts: {names} touched the ground at t={t:.17g} (mode '{mode}')"

    return Watch("contacts", values, "stop", message)
