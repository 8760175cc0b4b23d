"""Contacts from a URDF's ``<collision>`` shapes, for a planar robot whose motion stays in the
(x, z) plane against a flat ground.

Each shape becomes the contacts through which it can touch the ground:

* a sphere, and a cylinder whose axis is along y (a disc in the plane): one round contact
  (``PointContact`` with ``radius``) at its centre: it touches the ground at its lowest point,
  centre - r z, which rolls over the body;
* a box, and a cylinder whose axis lies in the plane: a contact at each corner of its outline in
  the plane (the convex hull of its projection; 4 corners for a box turned about y only), fixed
  in the body. A polygon on a flat ground touches it first at a corner, so the corners are all
  of it.

Other shapes (meshes, cones, shapes tilted out of the plane) are refused with a ``ModelError``
naming the file and the shape; a scene can turn that link's shapes ``"off"`` and list its
contacts itself.

Each contact gets a frame of its own in the model, ``collision_<contact>``, on the shape's
joint. A link with one contact names it after the link; a link with several names them
``<link>_<k>``, k counting its shapes' contacts in the URDF's order (a polygon's corners by
increasing x, then z, in the joint's frame).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
from scipy.spatial import ConvexHull

from legsim.errors import ModelError, SceneError

from .bridge import PointContact
from .urdf_checks import read_geometry

#: Tolerance on a shape's axis being along y or in the (x, z) plane (a unit vector's y component).
PLANAR_TOL = 1e-9
#: What a contact from a collision shape takes from the scene, with its allowed values.
SETTINGS = {"restitution": "float in [0, 1]", "friction": "float in [0, inf) (mu)", "tangential": "true or false"}
WHERE = "robot.parameters.collision_contacts"


@dataclass(frozen=True)
class ShapePoint:
    """One contact of a collision shape: where it sits in its joint's frame (m) and its radius
    (m, 0 for a corner)."""

    link: str
    joint: int
    position: np.ndarray
    radius: float
    #: The shape's place among the URDF's collision shapes.
    shape: int = 0


def collision_points(model: pin.Model, file: str | Path) -> list[ShapePoint]:
    """The contacts of every ``<collision>`` shape of the URDF ``file`` (model: its Pinocchio
    model), in the URDF's order; ``ModelError`` naming the file and shape for one the planar
    contacts cannot take."""
    file = Path(file)
    geometry = read_geometry(model, file, "collision")
    out = []
    for k, obj in enumerate(geometry.geometryObjects):
        link = model.frames[obj.parentFrame].name
        for position, radius in _shape_contacts(obj.geometry, obj.placement, f"{file}: collision '{obj.name}'"):
            out.append(ShapePoint(link, int(obj.parentJoint), position, radius, k))
    return out


def collision_outlines(points: Sequence[ShapePoint], settings: Any) -> dict[str, tuple[int, np.ndarray]]:
    """The outlines whose corners are contacts (boxes, cylinders in the plane), by link (``<link>``,
    or ``<link>#<k>`` for its k-th such shape): each its joint and its corners in the joint's frame
    (k, 3), from the URDF's ``collision_points``; links turned off in ``settings`` (the
    ``collision_contacts`` table) left out."""
    _, links = _settings(settings)
    shapes: dict[tuple[str, int], list[ShapePoint]] = {}
    for p in points:
        if p.radius == 0.0 and links.get(p.link) != "off":
            shapes.setdefault((p.link, p.shape), []).append(p)
    out: dict[str, tuple[int, np.ndarray]] = {}
    seen: dict[str, int] = {}
    for (link, _), points in shapes.items():
        if len(points) >= 3:
            seen[link] = seen.get(link, -1) + 1
            out[link if seen[link] == 0 else f"{link}#{seen[link]}"] = (
                points[0].joint,
                np.array([p.position for p in points]),
            )
    return out


def _shape_contacts(shape: Any, placement: pin.SE3, where: str) -> list[tuple[np.ndarray, float]]:
    """(position in the joint's frame (3,), radius) of each contact of one shape placed at ``placement``."""
    kind = type(shape).__name__
    rotation, centre = placement.rotation, placement.translation
    axis = rotation[:, 2]  # a cylinder's axis (its local z)
    along_y, in_plane = abs(abs(axis[1]) - 1.0) < PLANAR_TOL, abs(axis[1]) < PLANAR_TOL
    if kind == "Sphere":
        return [(centre.copy(), float(shape.radius))]
    if kind == "Cylinder" and along_y:
        return [(centre.copy(), float(shape.radius))]
    if kind == "Box" and abs(abs(rotation[1, 1]) - 1.0) < PLANAR_TOL:
        half = np.asarray(shape.halfSide, dtype=float)
        corners = np.array([[sx, 0.0, sz] for sx in (-1, 1) for sz in (-1, 1)]) * half
        return [(p, 0.0) for p in _corners(corners @ rotation.T + centre)]
    if kind == "Cylinder" and in_plane:
        h, r = float(shape.halfLength), float(shape.radius)
        across = np.cross(np.array([0.0, 1.0, 0.0]), axis)  # in the plane, normal to the axis
        corners = np.array([centre + sa * h * axis + sr * r * across for sa in (-1, 1) for sr in (-1, 1)])
        return [(p, 0.0) for p in _corners(corners)]
    tilted = " tilted out of the (x, z) plane" if kind in ("Box", "Cylinder") else ""
    raise ModelError(
        f"{where} is a {_shape_word(kind)}{tilted}; "
        f"contacts come from spheres, boxes turned about y, and cylinders whose axis is along y "
        f"or in the (x, z) plane: set robot.parameters.collision_contacts.links.<link> = 'off' and list "
        f"the link's contacts in robot.parameters.contacts"
    )


def _corners(points: np.ndarray) -> list[np.ndarray]:
    """The corners of the outline in the (x, z) plane of ``points`` (k, 3): the vertices of their
    projection's convex hull, by increasing x then z, at the points' mean y."""
    flat = points[:, [0, 2]]
    vertices = flat[ConvexHull(flat).vertices]
    y = float(np.mean(points[:, 1]))
    # rounded for the order only, so that a corner at x = 1e-17 and one at x = -1e-17 keep theirs
    ordered = sorted(vertices.tolist(), key=lambda xz: (round(xz[0], 12), round(xz[1], 12)))
    return [np.array([x, y, z]) for x, z in ordered]


def collision_contacts(
    model: pin.Model, file: str | Path, settings: Any, points: Sequence[ShapePoint]
) -> list[PointContact]:
    """The point contacts of the URDF ``file``'s collision shapes (its ``collision_points``),
    under the scene's ``settings`` (the ``collision_contacts`` table: ``restitution``,
    ``friction``, ``tangential`` (false: the contact constrains the normal only, frictionless),
    ``ground``, ``links``). Adds a
    frame ``collision_<contact>`` per contact to ``model``. ``SceneError`` naming the field for a
    bad setting, ``ModelError`` naming the file for a shape it cannot take."""
    defaults, links = _settings(settings)
    known = sorted({p.link for p in points})
    unknown = sorted(set(links) - set(known))
    if unknown:
        raise SceneError(f"{WHERE}.links: unknown link(s) {unknown}; links with a <collision>: {known}")
    per_link: dict[str, list[ShapePoint]] = {}
    for p in points:
        if links.get(p.link) != "off":
            per_link.setdefault(p.link, []).append(p)
    out = []
    for link, shapes in per_link.items():
        options = _options(defaults, links.get(link, {}), f"{WHERE}.links.{link}")
        for k, p in enumerate(shapes):
            name = link if len(shapes) == 1 else f"{link}_{k}"
            frame = f"collision_{name}"
            if model.existFrame(frame):
                raise ModelError(f"{file}: link '{link}': the model already has a frame '{frame}'")
            placement = pin.SE3(np.eye(3), p.position)
            model.addFrame(pin.Frame(frame, p.joint, placement, pin.FrameType.OP_FRAME), False)
            out.append(PointContact(name, frame, radius=p.radius, **options))
    if not out:
        raise SceneError(
            f"robot.parameters.collisions: {file} has no <collision> shape to take contacts from"
            f"{' (every link is off)' if points else ''}"
        )
    return out


def _options(defaults: Mapping[str, Any], own: Mapping[str, Any], where: str) -> dict[str, Any]:
    """A link's contact options: its own over the defaults; a frictionless one (tangential
    false) drops the default friction, and may not give its own."""
    if own.get("tangential", defaults.get("tangential", True)) is False:
        if "friction" in own or ("tangential" not in own and "friction" in defaults):
            source = where if "friction" in own else WHERE
            raise SceneError(f"{source}.friction: given with tangential = false (a frictionless contact); drop one")
        return {key: value for key, value in {**defaults, **own}.items() if key != "friction"}
    return {**defaults, **own}


def _settings(settings: Any) -> tuple[dict[str, Any], dict[str, Any]]:
    """The defaults (restitution, friction, tangential, ground) and the per-link overrides (a
    table of restitution, friction and tangential, or "off") of the ``collision_contacts``
    table, checked."""
    if not isinstance(settings, Mapping):
        raise SceneError(
            f"{WHERE}: expected a table {{restitution, friction, tangential, ground, links}}, got {settings!r}"
        )
    allowed = {**SETTINGS, "ground": "float (m)", "links": "table {link = {restitution, friction, tangential} | 'off'}"}
    unknown = sorted(set(settings) - set(allowed))
    if unknown:
        raise SceneError(f"{WHERE}: unknown key(s) {unknown}; allowed: {list(allowed)}")
    defaults = {key: _number(settings[key], f"{WHERE}.{key}", key) for key in SETTINGS if key in settings}
    if "ground" in settings:
        defaults["ground"] = _number(settings["ground"], f"{WHERE}.ground", "ground")
    links = settings.get("links", {})
    if not isinstance(links, Mapping):
        raise SceneError(
            f"{WHERE}.links: expected a table {{link = {{restitution, friction, tangential}} | 'off'}}, got {links!r}"
        )
    out: dict[str, Any] = {}
    for link, table in links.items():
        where = f"{WHERE}.links.{link}"
        if table == "off":
            out[link] = "off"
            continue
        if not isinstance(table, Mapping):
            raise SceneError(f"{where}: expected a table {{restitution, friction, tangential}} or 'off', got {table!r}")
        extra = sorted(set(table) - set(SETTINGS))
        if extra:
            raise SceneError(f"{where}: unknown key(s) {extra}; allowed: {list(SETTINGS)}")
        out[link] = {key: _number(value, f"{where}.{key}", key) for key, value in table.items()}
    return defaults, out


def _number(value: Any, where: str, key: str) -> Any:
    """A setting's value checked against its range: SceneError naming ``where`` and the allowed values."""
    allowed = {**SETTINGS, "ground": "float (m)"}[key]
    if key == "tangential":
        if not isinstance(value, bool):
            raise SceneError(f"{where}: expected {allowed}, got {value!r}")
        return value
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise SceneError(f"{where}: expected a finite number ({allowed}), got {value!r}")
    value = float(value)
    if (key == "restitution" and not 0.0 <= value <= 1.0) or (key == "friction" and value < 0.0):
        raise SceneError(f"{where}: {value!r} is out of range, allowed: {allowed}")
    return value


def _shape_word(kind: str) -> str:
    """What to call a shape of hpp-fcl class ``kind``: a URDF's mesh is read as a BVH model or a
    convex hull, whose class names would not tell a user it is the mesh."""
    return f"mesh ({kind})" if kind.startswith(("BVHModel", "Convex")) else kind
