"""Where a robot touches the ground: the active contact points of each frame of an animation.

A model says where its contacts are in one of two ways:

* ``Model.info["contact_points"]``: a callable ``(mode, x) -> {name: (x, z)}`` giving the world
  position (m) of every contact that is active in ``mode`` (the walkers publish their stance
  foot this way);
* a model built on the contact bridge (``Model.info["bridge"]``, ``legsim.robots.bridge``) needs
  nothing more: the active contacts of a mode are the bridge's, a spring leg's point is its
  foothold and a point contact's the origin of its frame. Joint stops are not points on the
  ground and are not marked.

Models with neither have no contact markers.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from legsim.builders import Model
from legsim.errors import ModelError
from legsim.execution import Execution

ContactPoints = Callable[[str, np.ndarray], dict[str, np.ndarray]]


def contact_points_of(model: Model | None) -> ContactPoints | None:
    """The model's ``(mode, x) -> {contact: (x, z)}`` of active contacts, None when it has none."""
    if model is None:
        return None
    hook = model.info.get("contact_points")
    if callable(hook):
        return hook
    bridge = model.info.get("bridge")
    if bridge is not None and callable(getattr(bridge, "active_contacts", None)):
        return lambda mode, x: bridge_contact_points(bridge, mode, x)
    return None


def bridge_contact_points(bridge: Any, mode: str, x: np.ndarray) -> dict[str, np.ndarray]:
    """World (x, z) points (m) of the contacts active in ``mode`` of a contact bridge: spring
    legs' footholds, point contacts' frame origins (a round one's lowest point; joint stops have
    no point)."""
    active = bridge.active_contacts(mode)
    if not active:
        return {}
    contacts = {c.name: c for c in bridge.contacts}
    feet = bridge.foot_positions(mode, x)
    points = {name: np.asarray(feet[name], dtype=float) for name in active if name in feet}
    frames = {
        name: contacts[name].frame
        for name in active
        if name not in feet and hasattr(contacts[name], "frame") and not hasattr(contacts[name], "joint")
    }
    if frames:
        positions = bridge.frame_positions(np.asarray(x, dtype=float)[: bridge.n], list(frames.values()))
        # a round contact touches at its lowest point, its radius below the frame's origin
        lowest = {name: np.array([0.0, float(getattr(contacts[name], "radius", 0.0))]) for name in frames}
        points.update({name: positions[frame] - lowest[name] for name, frame in frames.items()})
    return points


def contact_frames(execution: Execution, model: Model | None, times: np.ndarray) -> dict[str, list[np.ndarray | None]]:
    """Contact name -> its (2,) point (m) at each of ``times`` (s), None where it is not active
    (or not finite: a diverged run's last frames); empty when the model says nothing about its
    contacts. ModelError naming the mode and time when the model's hook fails."""
    points_of = contact_points_of(model)
    if points_of is None or not len(times):
        return {}
    samples = execution.sample(times)
    per_frame = [
        _evaluated(points_of, mode, x, float(t), model)
        for t, mode, x in zip(samples.times, samples.modes, samples.states, strict=True)
    ]
    names = list(dict.fromkeys(name for frame in per_frame for name in frame))
    return {name: [frame.get(name) for frame in per_frame] for name in names}


def _evaluated(points_of: ContactPoints, mode: str, x: np.ndarray, t: float, model: Any) -> dict[str, np.ndarray]:
    """The finite contact points of (mode, x); ModelError naming mode and time when the hook fails."""
    try:
        found = points_of(mode, np.asarray(x, dtype=float))
        points = {str(name): np.asarray(p, dtype=float).reshape(2) for name, p in found.items()}
    except Exception as exc:
        raise ModelError(
            f"{model.system.name}: contact points failed in mode '{mode}' at t={t:.6g}: {type(exc).__name__}: {exc}"
        ) from exc
    return {name: p for name, p in points.items() if np.all(np.isfinite(p))}
