"""The robot as the bridge's model functions see it: a ``BridgeModel`` is fixed once built (the
Pinocchio model with the spring legs' foot frames, the resolved contacts, names, damping,
actuation, its native handle and the rows of its parameter arrays every mode shares).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import pinocchio as pin
from legsim.robots._native.calls import lsn_round_moving

from legsim.errors import ModelError
from legsim.heights import PROFILE, SINE
from legsim.terrain import Terrain

from .contacts import (
    Contact,
    LegFrames,
    PointContact,
    RigidContact,
    SpringLeg,
    declared_contacts,
    finite_number,
    joint_id,
    resolve_contact,
    round_offset,
)
from .native import handle_for


@dataclass(frozen=True, eq=False)
class BridgeModel:
    """A planar robot and its contacts, resolved and checked.

    Attributes
    ----------
    name: the system's name (prefixes every error message).
    pin_model: the bridge's own copy of the Pinocchio model, with a ``<leg>_foot`` frame per spring leg.
    n: number of configuration coordinates, ``nq == nv``.
    contacts: the declarations by name, in declared order.
    rigid: resolved point contacts and joint stops by name, in declared order.
    legs: resolved spring legs by name, in declared order.
    coordinate_names, velocity_names: the n names of q and of v.
    damping_idx, damping_b: velocity indices with joint damping and their coefficients (N m s/rad or N s/m).
    actuated_idx: velocity index of each entry of the control u.
    effort_limits: the bound on |u_i| of each entry of u (N m or N; inf: none): the input is
        saturated there inside the model functions.
    handle: the model's handle in the native library.
    frames: the frames whose kinematics the guards read (frame ids; a contact's or leg's *slot*
        is its index here).
    terrain: the encoding of a terrain that is not level (``legsim.terrain``), or None: each
        contact's ground is level at its own height (a flat terrain sets those heights).
    round_offsets: each round contact's frame id -> (dx, dz) (m) from its centre to its point
        nearest the ground (``contacts.round_offset``), as the native library has them.
    """

    name: str
    pin_model: pin.Model
    n: int
    contacts: Mapping[str, Contact]
    rigid: Mapping[str, RigidContact]
    legs: Mapping[str, LegFrames]
    coordinate_names: tuple[str, ...]
    velocity_names: tuple[str, ...]
    damping_idx: np.ndarray
    damping_b: np.ndarray
    actuated_idx: np.ndarray
    effort_limits: np.ndarray
    handle: int
    frames: tuple[int, ...]
    terrain: np.ndarray | None = None
    round_offsets: Mapping[int, tuple[float, float]] = field(default_factory=dict)

    @property
    def order(self) -> list[str]:
        """Contact names in declared order."""
        return list(self.contacts)

    @property
    def coulomb(self) -> bool:
        """Whether some contact has Coulomb friction (its events then choose stuck or slipping
        outcomes, ``friction``)."""
        return any(r.mu is not None for r in self.rigid.values())

    @property
    def cornered(self) -> bool:
        """Whether the terrain has corners (a piecewise-linear profile), which a sliding point
        passes as an event (``events.corner_base``)."""
        return self.coulomb and self.terrain is not None and float(self.terrain[0]) == PROFILE

    def index(self, contact: str) -> int:
        """The index of a rigid contact among the rigid ones (declared order)."""
        return list(self.rigid).index(contact)

    def slot(self, frame: int) -> int:
        """The kinematics slot of a frame (its index in ``frames``)."""
        return self.frames.index(frame)


def rounds_move(terrain: np.ndarray | None) -> bool:
    """Whether a round contact's point nearest the terrain (its array, ``legsim.terrain``; None:
    level ground) moves in the body as it rolls: on a sine and on a profile's corners, not on
    level ground or a uniform slope."""
    return terrain is not None and float(terrain[0]) in (SINE, PROFILE)


def native_handle(model: pin.Model, name: str, offsets: Mapping[int, tuple[float, float]], moving: bool) -> int:
    """The native library's handle of a bridge's Pinocchio ``model``: its round contacts' frames
    (``offsets``, frame id -> (dx, dz) (m)) at their points nearest the ground, which on a sine
    or a profile (``moving``) move with the configuration."""
    handle = handle_for(model, name, offsets)
    if moving:
        for frame in offsets:
            lsn_round_moving(handle, frame)
    return handle


def build_model(
    model: pin.Model,
    contacts: Sequence[Contact],
    *,
    coordinate_names: Sequence[str] | None,
    velocity_names: Sequence[str] | None,
    joint_damping: Mapping[str, float] | None,
    actuated: Sequence[str],
    name: str,
    effort_limits: Mapping[str, float] | None = None,
    terrain: Terrain | None = None,
) -> BridgeModel:
    """Check and resolve the ``ContactBridge`` arguments (see there); ``ModelError`` names the
    contact, frame or joint at fault."""
    _check_pin_model(model, name)
    own = pin.Model(model)  # private copy: foot frames are added to it
    declared = _on_terrain(declared_contacts(contacts, name), terrain, name)
    rigid: dict[str, RigidContact] = {}
    legs: dict[str, LegFrames] = {}
    for contact in declared.values():
        resolved = resolve_contact(own, contact, name, list(declared))
        if isinstance(resolved, LegFrames):
            legs[contact.name] = resolved
        else:
            rigid[contact.name] = resolved
    n = int(own.nv)
    coords = _unique_names(coordinate_names, "coordinate_names", _joint_dof_names(own), n, name)
    vels = _unique_names(velocity_names, "velocity_names", tuple(f"{c}d" for c in coords), n, name)
    if set(coords) & set(vels):
        raise ModelError(f"{name}: coordinate and velocity names overlap: {sorted(set(coords) & set(vels))}")
    damping_idx, damping_b = _joint_damping(own, joint_damping, name)
    actuated_idx = _actuated_dofs(own, actuated, name)
    limits = _effort_limits(actuated, effort_limits, name)
    for c in rigid.values():
        armed = getattr(c.contact, "armed", None)
        if armed is not None and armed.coordinate and armed.coordinate not in coords:
            raise ModelError(
                f"{name}: contact '{c.contact.name}': armed.coordinate {armed.coordinate!r} "
                f"is not a coordinate: {coords}"
            )
    # Where the ground's grade is one a round contact's offset to its point nearest the ground is
    # fixed; on a sine or a profile it moves with the configuration, which the model functions set
    # (``dynamics.place_rounds``).
    grade = 0.0 if terrain is None else terrain.uniform_grade or 0.0
    offsets = {r.frame_id: round_offset(r.radius, grade) for r in rigid.values() if r.radius > 0.0}
    handle = native_handle(own, name, offsets, rounds_move(None if terrain is None else terrain.array))
    return BridgeModel(
        name, own, n, declared, rigid, legs, coords, vels, damping_idx, damping_b, actuated_idx, limits,
        handle,
        _kinematics_frames(rigid, legs),
        None if terrain is None or terrain.flat else terrain.array.copy(),
        offsets,
    )  # fmt: skip


def _on_terrain(declared: dict[str, Contact], terrain: Terrain | None, name: str) -> dict[str, Contact]:
    """The contacts on ``terrain``: a flat one is each contact's ground height (so that it runs
    exactly as ``ground = h0`` does); the others replace the grounds. A contact that gives its
    own ground besides a terrain, a spring leg on a terrain that is not level, or a round contact
    on one that is neither level nor a uniform slope, is refused."""
    if terrain is None:
        return declared
    if not isinstance(terrain, Terrain):
        raise ModelError(f"{name}: terrain must be a legsim.terrain.Terrain or None, got {type(terrain).__name__}")
    grounded = [c for c in declared.values() if isinstance(c, (PointContact, SpringLeg))]
    for c in grounded:
        if c.ground != 0.0:
            raise ModelError(
                f"{name}: contact '{c.name}' gives its own ground = {c.ground:g} m besides the terrain "
                f"({terrain.description}); give the ground one way"
            )
    if terrain.flat:
        h0 = float(terrain.array[1])
        return {
            k: replace(c, ground=h0) if isinstance(c, (PointContact, SpringLeg)) else c for k, c in declared.items()
        }
    legs = [c.name for c in grounded if isinstance(c, SpringLeg)]
    if legs:
        raise ModelError(
            f"{name}: spring legs {legs} stand only on level ground; the terrain {terrain.description} "
            f"is not (use a flat terrain)"
        )
    # A round contact touches the ground at its point nearest it, along the ground's normal there.
    # On a sine that point moves smoothly with the centre, one point as long as the radius is below
    # the sine's least radius of curvature; on a profile it rolls round convex corners and strikes
    # the next face at concave ones (its corner event).
    rounds = [c for c in grounded if isinstance(c, PointContact) and c.radius > 0.0]
    # A concave corner is an event of the friction law's (``events.corner_base``), which a robot
    # whose contacts have no friction coefficient does not take.
    coulomb = any(getattr(c, "friction", None) is not None for c in declared.values())
    if rounds and terrain.array[0] == PROFILE and not coulomb:
        raise ModelError(
            f"{name}: round contacts {[c.name for c in rounds]} on the terrain {terrain.description}, which has "
            f"corners, need the friction law: give the robot's contacts a friction coefficient"
        )
    if rounds and terrain.array[0] == SINE:
        amplitude, wavenumber = abs(float(terrain.array[2])), float(terrain.array[3])
        least = math.inf if amplitude == 0.0 else 1.0 / (amplitude * wavenumber**2)
        too_big = [f"'{c.name}' (radius {c.radius:g} m)" for c in rounds if c.radius >= least]
        if too_big:
            raise ModelError(
                f"{name}: a round contact must fit the troughs of the terrain {terrain.description} (their least "
                f"radius of curvature is {least:.4g} m; a wider ball touches a trough at two points): "
                f"{', '.join(too_big)} {'is' if len(too_big) == 1 else 'are'} wider; give smaller radii or a "
                f"gentler sine"
            )
    return declared


def _kinematics_frames(rigid: Mapping[str, RigidContact], legs: Mapping[str, LegFrames]) -> tuple[int, ...]:
    """The frames the guards read: each point contact's (and the frame it is armed ahead of),
    each leg's hip and flight foot, once each."""
    frames: list[int] = []
    for r in rigid.values():
        for frame in (r.frame_id, r.armed_frame):
            if frame >= 0 and frame not in frames:
                frames.append(frame)
    for lg in legs.values():
        for frame in (lg.hip_id, lg.foot_id):
            if frame not in frames:
                frames.append(frame)
    return tuple(frames)


def _check_pin_model(model: Any, name: str) -> None:
    if not isinstance(model, pin.Model):
        raise ModelError(f"{name}: model must be a pinocchio.Model, got {type(model).__name__}")
    if model.nq != model.nv:
        raise ModelError(
            f"{name}: the bridge needs model.nq == model.nv (prismatic and bounded revolute joints), "
            f"got nq={model.nq}, nv={model.nv}"
        )
    if model.nv < 1:
        raise ModelError(f"{name}: the model has no degree of freedom")


def _joint_dof_names(model: pin.Model) -> tuple[str, ...]:
    """Default coordinate names: a one-dof joint's name, or the name + dof index."""
    names = []
    for jid in range(1, model.njoints):
        j = model.joints[jid]
        base = model.names[jid]
        names.extend([base] if j.nv == 1 else [f"{base}{i}" for i in range(j.nv)])
    return tuple(names)


def _unique_names(
    given: Iterable[Any] | None, label: str, default: Iterable[str], n: int, robot: str
) -> tuple[str, ...]:
    names = tuple(default if given is None else (str(s) for s in given))
    if len(names) != n or len(set(names)) != len(names):
        raise ModelError(f"{robot}: {label} must be {n} unique names, got {names}")
    return names


def _joint_damping(
    model: pin.Model, joint_damping: Mapping[str, float] | None, robot: str
) -> tuple[np.ndarray, np.ndarray]:
    """(velocity indices, coefficients) of the joints with positive damping."""
    idx: list[int] = []
    bs: list[float] = []
    for jname, b in (joint_damping or {}).items():
        b = finite_number(b, f"{robot}: joint_damping['{jname}']", low=0.0)
        if b > 0.0:
            j = model.joints[joint_id(model, jname, "joint_damping", robot)]
            idx.extend(range(j.idx_v, j.idx_v + j.nv))
            bs.extend([b] * j.nv)
    return np.array(idx, dtype=int), np.array(bs)


def _actuated_dofs(model: pin.Model, actuated: Sequence[str], robot: str) -> np.ndarray:
    """Velocity index of each actuated joint, in the order of the control's entries."""
    dofs = []
    for jname in actuated:
        j = model.joints[joint_id(model, jname, "actuated", robot)]
        if j.nv != 1:
            raise ModelError(f"{robot}: actuated joint '{jname}' must have one dof, has {j.nv}")
        dofs.append(j.idx_v)
    return np.array(dofs, dtype=int)


def _effort_limits(actuated: Sequence[str], limits: Mapping[str, float] | None, robot: str) -> np.ndarray:
    """The bound on |u_i| of each actuated joint (inf where ``limits`` gives none); ModelError
    for a limit on a joint that is not actuated, or one that is not a number > 0."""
    limits = dict(limits or {})
    unknown = sorted(set(limits) - set(actuated))
    if unknown:
        raise ModelError(
            f"{robot}: effort_limits names joint(s) {unknown} that are not actuated; actuated: {list(actuated)}"
        )
    out = np.full(len(actuated), np.inf)
    for i, jname in enumerate(actuated):
        if jname in limits:
            value = limits[jname]
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not float(value) > 0.0:
                raise ModelError(f"{robot}: effort_limits['{jname}']: expected a number > 0 (N m or N), got {value!r}")
            out[i] = float(value)
    return out
