"""A Pinocchio model in the native library (``legsim.robots._native``): its flat description, its handle
(created once per model object) and the robot's evaluation counters.

The bridge's model functions call Pinocchio's C++ algorithms through the library by a model
handle that travels in their parameter arrays; without the library a bridge robot cannot be
built (``ModelError`` says why).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from legsim.errors import ModelError

from .. import _native

#: The robot's counters, by slot of the library's counter array (``lsn_counts``): the first five
#: and ``cache_hits`` (a solve served by the last one with the same inputs) are counted by the
#: library's algorithms, the others by the model functions (``lsn_tally``).
COUNTERS = (
    "aba",
    "kkt",
    "jacobians",
    "kinematics",
    "impacts",
    "spring_forces",
    "damping_evals",
    "actuation_evals",
    "painleve_sticks",
    "cache_hits",
)
#: Slots the model functions tally (lsn_tally); C_IMPACTS is the library's own impact slot, which
#: the impacts solved with friction (robots.bridge.friction) count too.
C_IMPACTS = 4
C_SPRINGS, C_DAMPING, C_ACTUATION, C_PAINLEVE = 5, 6, 7, 8

_HANDLES: dict[int, tuple[Any, int]] = {}
_JOINT_CODES = {
    "JointModelRX": 0,
    "JointModelRY": 1,
    "JointModelRZ": 2,
    "JointModelPX": 3,
    "JointModelPY": 4,
    "JointModelPZ": 5,
}
COMPOSITE = 6


def describe(model: Any, offsets: Mapping[int, tuple[float, float]] | None = None) -> np.ndarray | None:
    """The flat description of a Pinocchio model for ``lsn_create`` (pinlegsim.cpp), or None
    when it has a joint the library does not take or a gravity with an angular part. ``offsets``:
    the round frames (frame id -> (dx, dz), m, ``contacts.round_offset``), whose kinematics the
    library gives at their origin moved by that offset (a sphere's or disc's contact point)."""
    out: list[float] = [model.njoints - 1]
    for j in range(1, model.njoints):
        joint = _joint_description(model.joints[j])
        if joint is None:
            return None
        placement, inertia = model.jointPlacements[j], model.inertias[j]
        out += [*joint, model.parents[j], *placement.rotation.reshape(-1), *placement.translation]
        out += [inertia.mass, *inertia.lever, *inertia.inertia.reshape(-1)]
    out.append(len(model.frames) - 1)
    for frame in list(model.frames)[1:]:
        out += [frame.parentJoint, *frame.placement.rotation.reshape(-1), *frame.placement.translation]
    if np.any(model.gravity.angular != 0.0):
        return None
    out += list(model.gravity.linear)
    rounds = sorted((offsets or {}).items())
    out.append(len(rounds))
    out += [v for frame, (dx, dz) in rounds for v in (frame, dx, dz)]
    return np.array(out, dtype=float)


def _joint_description(joint: Any) -> list[float] | None:
    """A joint's code, and for a composite (the planar root: PX, PZ, RY) its parts' codes and
    placements; None for a joint the library does not take."""
    kind = joint.shortname()
    if kind != "JointModelComposite":
        code = _JOINT_CODES.get(kind)
        return None if code is None else [code]
    composite = joint.extract()
    out: list[float] = [COMPOSITE, len(composite.joints)]
    for part, placement in zip(composite.joints, composite.jointPlacements, strict=True):
        code = _JOINT_CODES.get(part.shortname())
        if code is None:
            return None
        out += [code, *placement.rotation.reshape(-1), *placement.translation]
    return out


def handle_for(model: Any, robot: str, offsets: Mapping[int, tuple[float, float]] | None = None) -> int:
    """The native handle of a Pinocchio model (created once per model object, with its round
    frames' ``offsets``: see ``describe``); ``ModelError`` naming ``robot`` when the library is
    unavailable or cannot take the model."""
    found = _HANDLES.get(id(model))
    if found is not None and found[0] is model:
        return found[1]
    if not _native.load():
        raise ModelError(f"{robot}: the native Pinocchio library is unavailable: {_native.status()}")
    desc = describe(model, offsets)
    if desc is None:
        raise ModelError(
            f"{robot}: the native library takes revolute and prismatic joints about or along x, y, z "
            f"(and their composites) and a gravity without angular part; this model has others"
        )
    handle = _native.create_model(desc)
    _HANDLES[id(model)] = (model, handle)  # holding the model keeps its id from being reused
    return handle


def bare_aba(handle: int) -> Callable[[np.ndarray, np.ndarray, np.ndarray, int], float]:
    """``time(q, v, tau, reps)``: seconds per bare C++ ABA call on the model ``handle``, timed inside
    the library (``_native.time_aba``), for ``Model.info["bare_aba"]``: the floor a field's cost
    is measured against (``legsim bench robots``)."""
    return functools.partial(_native.time_aba, handle)


def counts(handle: int, reset: bool = False) -> dict[str, int]:
    """The robot's evaluation counters by name (``COUNTERS``), zeroed afterwards with ``reset``."""
    values = _native.counts(handle, reset)
    return {name: int(values[i]) for i, name in enumerate(COUNTERS)}
