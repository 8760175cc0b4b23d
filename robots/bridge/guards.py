"""What the scene tools read about a bridge robot's guards: the initial-state check and each
guard's unit (the guards themselves are ``events``' model functions).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pinocchio as pin

from legsim.heights import SINE, nearest
from legsim.heights import height as terrain_height

from .contacts import SLIP_SUFFIX, PointContact, RigidContact, SpringLeg, joint_id
from .model import BridgeModel


def initial_check(
    model: BridgeModel, data: pin.Data, active_contacts: Callable[[str], tuple[str, ...]]
) -> Callable[[str, np.ndarray, float], str | None]:
    """The scene's initial-state check (``Model.info["initial_check"]``): ``check(mode, x, eps)``
    names the first inactive joint stop or point contact whose position lies past it by more
    than eps (rad or m), else None. The guards are "and" conditions (past the stop AND moving
    into it), so they count a state deep past a stop but moving away as inside; no execution
    reaches such a state, and a run started there would not be the model's."""

    def check(mode: str, x: np.ndarray, eps: float) -> str | None:
        active = active_contacts(mode)
        q = np.asarray(x, dtype=float)[: model.n]
        for r in model.rigid.values():
            if r.contact.name in active:
                continue
            if r.kind == "stop":
                message = _past_stop(model, r, q, eps, mode)
            else:
                message = _below_ground(model, data, r, q, eps, mode)
            if message is not None:
                return message
        return None

    return check


def _past_stop(model: BridgeModel, r: RigidContact, q: np.ndarray, eps: float, mode: str) -> str | None:
    """A message if q lies past the inactive stop by more than eps (rad or m), else None."""
    c = r.stop
    depth = -r.sign * (q[r.dof] - c.position)
    if depth > eps:
        name = model.coordinate_names[r.dof]
        bound = ">=" if c.side == "lower" else "<="
        return (
            f"{name} = {q[r.dof]:g} lies past the {c.side} stop '{c.name}' ({name} {bound} "
            f"{c.position:g}) by {depth:.3g} > eps = {eps:g} in mode '{mode}' where the "
            f"stop is inactive"
        )
    return None


def _below_ground(
    model: BridgeModel, data: pin.Data, r: RigidContact, q: np.ndarray, eps: float, mode: str
) -> str | None:
    """A message if the inactive contact point (a round one's point nearest the ground) lies below
    the ground (the terrain under it) at q by more than eps (m), else None."""
    c = r.point
    pin.forwardKinematics(model.pin_model, data, q)
    x, _, z = pin.updateFramePlacement(model.pin_model, data, r.frame_id).translation
    if r.radius > 0.0 and model.terrain is not None and model.terrain[0] == SINE:
        # the point nearest the terrain moves with the centre: its depth is r less the centre's distance
        s, distance, grade, _ = nearest(model.terrain, 0, float(x), float(z))
        ground, depth = terrain_height(model.terrain, 0, s), r.radius - distance
        z = ground - depth / float(np.sqrt(1.0 + grade * grade))
    else:
        dx, dz = model.round_offsets.get(r.frame_id, (0.0, 0.0))  # a round contact's point nearest the ground
        x, z = x + dx, z + dz
        ground = c.ground if model.terrain is None else terrain_height(model.terrain, 0, float(x))
        depth = ground - z
    if depth > eps:
        shape = f", radius {r.radius:g} m: its point nearest the ground" if r.radius > 0.0 else ""
        return (
            f"contact point '{c.name}' (frame '{c.frame}'{shape}) at height {z:g} m lies below the "
            f"ground {ground:g} m under it by {depth:.3g} > eps = {eps:g} in mode '{mode}' where "
            f"the contact is inactive"
        )
    return None


def guard_units(model: BridgeModel) -> dict[str, str]:
    """Unit of each kind of guard by transition name prefix (eps is measured in these)."""
    units = {}
    for cname, c in model.contacts.items():
        if isinstance(c, SpringLeg):
            units[f"touchdown_{cname}"] = "m (foot height, while descending)"
            units[f"liftoff_{cname}"] = "m (rest length minus leg length, while extending)"
        elif isinstance(c, PointContact):
            kind = "touchdown" if c.restitution == 0.0 else "bounce"
            point = "the round contact's lowest point" if c.radius > 0.0 else "the point"
            units[f"{kind}_{cname}"] = f"m (height of {point}, while descending)"
            if c.restitution == 0.0:
                units[f"graze_{cname}"] = units[f"{kind}_{cname}"]
                units[f"liftoff_{cname}"] = "N (normal contact force)"
            if c.friction is not None:
                units[f"liftoff_{cname}"] = "N (normal contact force)"
                for suffix in SLIP_SUFFIX.values():
                    units[f"slip_{cname}{suffix}"] = (
                        "N (mu f_n -+ f_t: the force's distance to the friction cone's edge)"
                    )
                units[f"stick_{cname}"] = "m/s (slip velocity, while the friction decelerates it)"
        else:
            joint = model.pin_model.joints[joint_id(model.pin_model, c.joint, "stop", model.name)]
            rot = joint.shortname().startswith(("JointModelR",))
            kind = "impact" if c.restitution == 0.0 else "bounce"
            units[f"{kind}_{cname}"] = f"{'rad' if rot else 'm'} (distance to the stop, while approaching)"
            if c.restitution == 0.0:
                units[f"graze_{cname}"] = units[f"{kind}_{cname}"]
                units[f"release_{cname}"] = f"{'N m' if rot else 'N'} (stop force)"
    return units
