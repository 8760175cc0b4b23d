"""Contact declarations and their resolution against a Pinocchio model.

``PointContact``, ``JointStop`` and ``SpringLeg`` are what a robot declares; resolving one checks
it against the model and turns it into the ids the algorithms use (``RigidContact`` for point
contacts and stops, ``LegFrames`` for spring legs). Also the model helpers the robots build their
planar models with: ``planar_floating_base`` and ``add_point_frame``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import pinocchio as pin

from legsim.errors import ModelError


@dataclass(frozen=True)
class PointContact:
    """A point of the robot (the origin of Pinocchio frame ``frame``) against the ground.

    Attributes
    ----------
    name: contact name (used in mode and transition names).
    frame: Pinocchio frame whose origin touches the ground.
    restitution: Newton restitution coefficient c in [0, 1]; 0 sticks (enters the mode with
        the contact active), > 0 bounces.
    ground: ground height (m).
    tangential: True pins the point (no slip, x and z constrained); False constrains z only
        (frictionless sliding).
    friction: Coulomb friction coefficient mu >= 0, or None (the default) for no friction
        limit (a tangential contact then never slips). With mu the active contact is in one
        of three modes: stuck (``<name>``: x and z constrained, while the tangential force
        stays inside the cone |lambda_t| <= mu lambda_n), slipping towards +x (``<name>>``)
        or towards -x (``<name><``) (z constrained, friction force -s mu lambda_n on the
        point, s the slip direction); see ``legsim.robots.bridge.friction``. Needs
        ``tangential=True``.
    releases: names of contacts that become inactive when this one strikes.
    armed: optional ``Armed``: where the touchdown counts (a walker's swing foot lands only
        ahead of its stance foot, so that the scuff at mid-swing is not a heel strike).
    radius: 0 (m) for a point; r > 0 makes the contact round (a sphere, or a disc in the
        plane, of radius r about the frame's origin): it touches the ground at its lowest
        point, origin - r z, which is not fixed in the body. The gap is the origin's height
        minus r; the constraint rows, impacts and friction act at that point (its velocity
        v + w x (-r z): the slip velocity is the rolling one). The bridge gives the contact a
        frame of its own, ``<name>_round``, which the native library knows as round.
    """

    name: str
    frame: str
    restitution: float = 0.0
    ground: float = 0.0
    tangential: bool = True
    releases: tuple[str, ...] = ()
    armed: Armed | None = None
    friction: float | None = None
    radius: float = 0.0


@dataclass(frozen=True)
class Armed:
    """Where a point contact's touchdown counts, as data its guard evaluates: where the
    configuration coordinate ``coordinate`` (by name) exceeds ``beyond`` (rad or m), or where the
    point lies ahead of frame ``ahead_of`` along x by more than ``beyond`` (m); exactly one of the
    two is given. With ``armed = coordinate - beyond`` (or the lead minus ``beyond``) the
    touchdown guard becomes ``max(height, vertical velocity, -armed)``. The point must be above
    the ground when it becomes armed, or the guard jumps past its strip."""

    coordinate: str = ""
    ahead_of: str = ""
    beyond: float = 0.0


#: Suffixes of a Coulomb contact's slipping modes: ``<name>>`` slips towards +x, ``<name><``
#: towards -x; the stuck contact is named by its name alone.
SLIP_SUFFIX = {1.0: ">", -1.0: "<"}


@dataclass(frozen=True)
class JointStop:
    """A mechanical stop on a one-dof joint.

    Attributes
    ----------
    name: contact name.
    joint: Pinocchio joint name (one dof: revolute RX/RY/RZ or prismatic PX/PY/PZ).
    position: stop position (rad or m).
    side: ``"lower"`` (the domain is ``q >= position``) or ``"upper"`` (``q <= position``).
    restitution: Newton restitution coefficient c in [0, 1].
    """

    name: str
    joint: str
    position: float = 0.0
    side: Literal["lower", "upper"] = "lower"
    restitution: float = 0.0


@dataclass(frozen=True)
class SpringLeg:
    """A massless linear spring leg hinged at frame ``frame`` (the hip).

    Attributes
    ----------
    name: contact name.
    frame: hip frame.
    stiffness: k (N/m), > 0.
    rest_length: l (m), > 0.
    angle: leg angle in flight (rad) from the hip frame's -z axis towards its +x axis.
    damping: viscous damping along the leg in stance (N s/m), >= 0; 0 computes no damping term.
    ground: ground height (m).
    """

    name: str
    frame: str
    stiffness: float
    rest_length: float
    angle: float = 0.0
    damping: float = 0.0
    ground: float = 0.0


Contact = PointContact | JointStop | SpringLeg


@dataclass(frozen=True)
class RigidContact:
    """A point contact or joint stop resolved against the model: what its constraint rows need.

    Attributes
    ----------
    contact: the declaration.
    kind: ``"point"`` or ``"stop"``.
    frame_id: Pinocchio frame id of a point contact (-1 for a stop); for a round one, its own
        frame (``<name>_round``), whose kinematics the native library gives at its lowest point.
    dof: velocity index of a stop's joint (-1 for a point contact).
    sign: +1 for a lower stop, -1 for an upper one: ``sign * (q - position) >= 0`` inside.
    rows: constraint Jacobian rows (2 for a sticking point, else 1); the normal row is the last.
    armed_frame: the frame id a point is armed ahead of (``Armed.ahead_of``), else -1.
    centre_id: the frame at a point contact's centre, whose origin is the declared frame's
        (``frame_id`` itself for a point; -1 for a stop).
    """

    contact: PointContact | JointStop
    kind: str
    frame_id: int = -1
    dof: int = -1
    sign: float = 1.0
    rows: int = 1
    armed_frame: int = -1
    centre_id: int = -1

    @property
    def mu(self) -> float | None:
        """The Coulomb friction coefficient of a point contact, or None (no friction limit)."""
        return getattr(self.contact, "friction", None)

    @property
    def radius(self) -> float:
        """The radius (m) of a round point contact, 0 for a point or a stop."""
        return float(getattr(self.contact, "radius", 0.0))

    @property
    def point(self) -> PointContact:
        """The declaration of a point contact (kind ``"point"``)."""
        assert isinstance(self.contact, PointContact), f"'{self.contact.name}' is a joint stop"
        return self.contact

    @property
    def stop(self) -> JointStop:
        """The declaration of a joint stop (kind ``"stop"``)."""
        assert isinstance(self.contact, JointStop), f"'{self.contact.name}' is a point contact"
        return self.contact


@dataclass(frozen=True)
class LegFrames:
    """A spring leg resolved against the model: its hip frame and its flight foot frame."""

    leg: SpringLeg
    hip_id: int
    foot_id: int


def round_offset(radius: float, grade: float) -> tuple[float, float]:
    """(dx, dz) (m) from a round contact's centre to its point nearest a ground of uniform
    ``grade`` dh/dx: -r n, n = (-grade, 1) / sqrt(1 + grade^2) the ground's normal (on level
    ground (0, -r), the lowest point). The native library gives the kinematics of that point
    (``pinlegsim.cpp``, ``round_offset``)."""
    norm = math.sqrt(1.0 + grade * grade)
    return radius * grade / norm, -radius / norm


def finite_number(
    value: Any, where: str, *, low: float | None = None, high: float | None = None, low_open: bool = False
) -> float:
    """``value`` as a float, or ``ModelError`` naming ``where`` if it is not a finite number in
    ``[low, high]`` (``(low, high]`` with ``low_open``)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise ModelError(f"{where} must be a number, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise ModelError(f"{where} must be finite, got {value}")
    if low is not None and (value < low or (low_open and value == low)):
        raise ModelError(f"{where} must be {'>' if low_open else '>='} {low:g}, got {value:g}")
    if high is not None and value > high:
        raise ModelError(f"{where} must be <= {high:g}, got {value:g}")
    return value


def joint_id(model: pin.Model, jname: Any, where: str, robot: str) -> int:
    """Id of joint ``jname``, or ``ModelError`` listing the joints (``robot: where: ...``)."""
    if not isinstance(jname, str) or not model.existJointName(jname):
        raise ModelError(f"{robot}: {where}: unknown joint {jname!r}; joints: {list(model.names)[1:]}")
    return int(model.getJointId(jname))


def frame_id(model: pin.Model, fname: Any, where: str, robot: str) -> int:
    """Id of frame ``fname``, or ``ModelError`` listing the frames (``robot: where: ...``)."""
    if not isinstance(fname, str) or not model.existFrame(fname):
        raise ModelError(f"{robot}: {where}: unknown frame {fname!r}; frames: {[f.name for f in model.frames][1:]}")
    return int(model.getFrameId(fname))


def declared_contacts(contacts: Sequence[Any], robot: str) -> dict[str, Contact]:
    """The contacts by name, in declared order; ``ModelError`` for a record of another type, a
    bad name (empty, or with the mode-name separator ``+``) or a name used twice."""
    out: dict[str, Contact] = {}
    for c in contacts:
        if not isinstance(c, (PointContact, JointStop, SpringLeg)):
            raise ModelError(f"{robot}: contacts must be PointContact, JointStop or SpringLeg, got {type(c).__name__}")
        if not isinstance(c.name, str) or not c.name or "+" in c.name:
            raise ModelError(f"{robot}: contact names must be non-empty strings without '+', got {c.name!r}")
        if getattr(c, "friction", None) is not None and any(ch in c.name for ch in SLIP_SUFFIX.values()):
            raise ModelError(
                f"{robot}: the name of a contact with friction may not contain '<' or '>' (they name "
                f"its slipping modes), got {c.name!r}"
            )
        if c.name in out:
            raise ModelError(f"{robot}: duplicate contact name '{c.name}'")
        out[c.name] = c
    return out


def resolve_contact(
    model: pin.Model, contact: Contact, robot: str, declared: Sequence[str]
) -> RigidContact | LegFrames:
    """Check ``contact`` against ``model`` and resolve it; a spring leg adds its flight foot
    frame ``<name>_foot`` to ``model`` (which must therefore be the bridge's own copy).
    ``robot`` names the robot in error messages; ``declared``: every contact name, in declared
    order (what ``releases`` may name)."""
    where = f"{'stop' if isinstance(contact, JointStop) else 'contact'} '{contact.name}'"
    if isinstance(contact, SpringLeg):
        return _resolve_leg(model, contact, robot, where)
    finite_number(contact.restitution, f"{robot}: {where}: restitution", low=0.0, high=1.0)
    if isinstance(contact, PointContact):
        return _resolve_point(model, contact, robot, where, declared)
    return _resolve_stop(model, contact, robot, where)


def _resolve_leg(model: pin.Model, leg: SpringLeg, robot: str, where: str) -> LegFrames:
    finite_number(leg.stiffness, f"{robot}: {where}: stiffness", low=0.0, low_open=True)
    finite_number(leg.rest_length, f"{robot}: {where}: rest_length", low=0.0, low_open=True)
    finite_number(leg.angle, f"{robot}: {where}: angle")
    finite_number(leg.damping, f"{robot}: {where}: damping", low=0.0)
    finite_number(leg.ground, f"{robot}: {where}: ground")
    hip = frame_id(model, leg.frame, where, robot)
    frame = model.frames[hip]
    # The flight foot is rigidly attached to the hip's joint: a frame gives its position
    # and velocity from the same kinematics pass as everything else.
    offset = leg.rest_length * np.array([math.sin(leg.angle), 0.0, -math.cos(leg.angle)])
    placement = frame.placement * pin.SE3(np.eye(3), offset)
    foot_name = f"{leg.name}_foot"
    if model.existFrame(foot_name):
        raise ModelError(f"{robot}: {where}: the model already has a frame '{foot_name}'")
    foot = model.addFrame(pin.Frame(foot_name, frame.parentJoint, placement, pin.FrameType.OP_FRAME), False)
    return LegFrames(leg, hip, int(foot))


def _resolve_point(model: pin.Model, c: PointContact, robot: str, where: str, declared: Sequence[str]) -> RigidContact:
    finite_number(c.ground, f"{robot}: {where}: ground")
    centre = fid = frame_id(model, c.frame, where, robot)
    if finite_number(c.radius, f"{robot}: {where}: radius", low=0.0) > 0.0:
        fid = _round_frame(model, c, fid, robot, where)
    if isinstance(c.releases, str) or not all(isinstance(o, str) for o in c.releases):
        raise ModelError(f"{robot}: {where}: releases must be a tuple of contact names, got {c.releases!r}")
    armed_frame = _resolve_armed(model, c.armed, robot, where)
    for other in c.releases:
        if other not in declared or other == c.name:
            raise ModelError(f"{robot}: {where}: releases unknown contact {other!r} (contacts: {list(declared)})")
    if c.friction is not None:
        finite_number(c.friction, f"{robot}: {where}: friction", low=0.0)
        if not c.tangential:
            raise ModelError(
                f"{robot}: {where}: friction {c.friction!r} needs tangential=True (a contact with "
                f"tangential=False is frictionless)"
            )
    rows = 2 if c.tangential else 1
    return RigidContact(c, "point", frame_id=fid, rows=rows, armed_frame=armed_frame, centre_id=centre)


def _round_frame(model: pin.Model, c: PointContact, fid: int, robot: str, where: str) -> int:
    """A round contact's own frame ``<name>_round``, at frame ``fid``'s placement: the native
    library gives its kinematics at its lowest point, which no other user of the frame wants."""
    name = f"{c.name}_round"
    if model.existFrame(name):
        raise ModelError(f"{robot}: {where}: the model already has a frame '{name}'")
    frame = model.frames[fid]
    return int(model.addFrame(pin.Frame(name, frame.parentJoint, frame.placement, pin.FrameType.OP_FRAME), False))


def _resolve_armed(model: pin.Model, armed: Any, robot: str, where: str) -> int:
    """The frame id an ``Armed`` point is armed ahead of (-1: none, or armed by a coordinate,
    which ``model.build_model`` resolves with the coordinate names)."""
    if armed is None:
        return -1
    if not isinstance(armed, Armed):
        raise ModelError(f"{robot}: {where}: armed must be a legsim.robots.bridge.Armed or None, got {armed!r}")
    finite_number(armed.beyond, f"{robot}: {where}: armed.beyond")
    if bool(armed.coordinate) == bool(armed.ahead_of):
        raise ModelError(f"{robot}: {where}: armed names exactly one of coordinate and ahead_of, got {armed!r}")
    return frame_id(model, armed.ahead_of, f"{where}: armed.ahead_of", robot) if armed.ahead_of else -1


def _resolve_stop(model: pin.Model, c: JointStop, robot: str, where: str) -> RigidContact:
    finite_number(c.position, f"{robot}: {where}: position")
    if c.side not in ("lower", "upper"):
        raise ModelError(f"{robot}: {where}: side must be 'lower' or 'upper', got {c.side!r}")
    joint = model.joints[joint_id(model, c.joint, where, robot)]
    if joint.nv != 1:
        raise ModelError(f"{robot}: {where}: joint '{c.joint}' has {joint.nv} dofs; a stop needs one")
    return RigidContact(c, "stop", dof=int(joint.idx_v), sign=1.0 if c.side == "lower" else -1.0)


def planar_floating_base(
    model: pin.Model,
    parent: int = 0,
    placement: pin.SE3 | None = None,
    names: tuple[str, str, str] = ("x", "z", "theta"),
) -> int:
    """Add the planar floating base (PX, PZ, RY joints) of a body moving in the (x, z) plane;
    returns the id of the pitch joint, to which the body's inertia is attached. Positive pitch
    (rotation about +y) turns the body's +x axis downwards (nose down)."""
    jx = model.addJoint(parent, pin.JointModelPX(), placement or pin.SE3.Identity(), names[0])
    jz = model.addJoint(jx, pin.JointModelPZ(), pin.SE3.Identity(), names[1])
    return int(model.addJoint(jz, pin.JointModelRY(), pin.SE3.Identity(), names[2]))


def add_point_frame(model: pin.Model, name: str, joint: int, xyz: Sequence[float]) -> int:
    """Add an operational frame ``name`` at ``xyz`` (m) in joint ``joint``'s frame; returns its id."""
    return int(
        model.addFrame(
            pin.Frame(name, joint, pin.SE3(np.eye(3), np.asarray(xyz, dtype=float)), pin.FrameType.OP_FRAME), False
        )
    )
