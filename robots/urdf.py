"""Robots from URDF files: parsed with Pinocchio, given a planar root, contacts and joint stops
declared by the scene, and drawn from the URDF's visual geometry.

A scene names the file (relative to the scene's folder) and declares what the URDF does not
say::

    [robot]
    name = "urdf"
    [robot.parameters]
    file = "quadruped.urdf"                  # read with pinocchio.buildModelFromUrdf
    root = "planar"                          # x, z, pitch (a PX + PZ + RY composite joint), or "fixed"
    actuated = ["hind_hip", "hind_knee"]     # joints driven by the control u, in this order ("all": every one)
    contacts = [{ name = "hind", frame = "hind_foot", friction = 0.8, restitution = 0.0 }]
    stops = [{ name = "hind_knee_stop", joint = "hind_knee", position = 0.2, side = "lower" }]

The robot must be planar: every joint rotates about y or slides in the (x, z) plane, so that
its motion stays in the sagittal plane the bridge simulates; every joint has nq == nv (a
``continuous`` joint, parsed as (cos, sin), must be declared ``revolute`` with limits). The
URDF's visual shapes (box, cylinder, sphere, capsule, mesh vertices) are drawn as their
outlines in the (x, z) plane (``Outlines``), which the meshcat page and the Rerun recording
draw like any robot's geometry.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
from scipy.spatial import ConvexHull

from legsim.builders import Builder, Model, Param
from legsim.errors import ModelError, SceneError
from legsim.terrain import PROFILE, SINE, Terrain

from .bridge import ContactBridge, JointStop, PointContact
from .collisions import collision_contacts, collision_outlines, collision_points
from .urdf_checks import check_urdf, parser_messages, read_geometry
from .watches import LinkHeights, TerrainPiercing, below_ground_watch, saturation_watches, terrain_inside_watch

PLANAR_ROOT = ("x", "z", "pitch")
#: Points sampled on a round visual shape's outline.
ROUND_SAMPLES = 32


def planar_root() -> pin.JointModel:
    """The planar root joint: PX, PZ and RY composed into one joint with nq == nv == 3
    (Pinocchio's own planar joint stores the angle as (cos, sin), nq = 4)."""
    root = pin.JointModelComposite()
    root.addJoint(pin.JointModelPX())
    root.addJoint(pin.JointModelPZ())
    root.addJoint(pin.JointModelRY())
    return root


def load_model(file: str | Path, root: str = "planar", g: float = 9.81) -> tuple[pin.Model, tuple[str, ...]]:
    """The URDF's Pinocchio model with its root (``"planar"``: x, z, pitch; ``"fixed"``: none)
    and gravity g (m/s^2) along -z, and the names of its nv coordinates (the root's, then each
    joint's name). ``ModelError`` naming the file and joint for anything the bridge cannot
    simulate."""
    file = Path(file)
    check_urdf(file)
    try:
        with parser_messages(file):
            if root == "planar":
                model = pin.buildModelFromUrdf(str(file), planar_root(), "root")
            else:
                model = pin.buildModelFromUrdf(str(file))
    except ModelError:
        raise
    except Exception as exc:  # Pinocchio's parser raises RuntimeError or ValueError with its reason
        raise ModelError(f"{file}: Pinocchio could not read the URDF: {type(exc).__name__}: {exc}") from exc
    first = 2 if root == "planar" else 1
    _check_joints(model, file, first)
    model.gravity = pin.Motion(np.array([0.0, 0.0, -g, 0.0, 0.0, 0.0]))
    names = (PLANAR_ROOT if root == "planar" else ()) + tuple(model.names[j] for j in range(first, model.njoints))
    return model, names


def _check_joints(model: pin.Model, file: Path, first: int) -> None:
    """``ModelError`` for a joint that is not one planar degree of freedom."""
    for j in range(first, model.njoints):
        joint, name = model.joints[j], model.names[j]
        kind = joint.shortname()
        if joint.nq != joint.nv:
            raise ModelError(
                f"{file}: joint '{name}' ({kind}) has nq = {joint.nq}, nv = {joint.nv}: the bridge needs "
                f"nq == nv; declare a continuous joint as revolute with limits"
            )
        axis = _axis(joint)
        rotation = model.jointPlacements[j].rotation
        planar = (kind.startswith("JointModelR") and abs(abs((rotation @ axis)[1]) - 1.0) < 1e-9) or (
            kind.startswith("JointModelP") and abs((rotation @ axis)[1]) < 1e-9
        )
        if not planar or abs(abs(rotation[1, 1]) - 1.0) > 1e-9:
            raise ModelError(
                f"{file}: joint '{name}' ({kind}) does not move in the (x, z) plane: revolute joints "
                f"must turn about y and prismatic ones slide along x or z"
            )


def _axis(joint: Any) -> np.ndarray:
    """The unit axis of a one-dof joint in its own frame."""
    kind = joint.shortname()
    for letter, axis in (("X", (1, 0, 0)), ("Y", (0, 1, 0)), ("Z", (0, 0, 1))):
        if kind in (f"JointModelR{letter}", f"JointModelP{letter}"):
            return np.array(axis, dtype=float)
    extracted = getattr(joint, "extract", lambda: joint)()
    return np.asarray(getattr(extracted, "axis", (0.0, 0.0, 0.0)), dtype=float)


class Outlines:
    """The visual shapes of a URDF as polylines in the (x, z) plane (m): each shape's outline
    (the convex hull of its projection) in its joint's frame, placed by the joint's pose."""

    def __init__(self, model: pin.Model, file: str | Path) -> None:
        file = Path(file)
        visual = read_geometry(model, file, "visual")
        self._model = model
        self._data = model.createData()
        self.parts: dict[str, tuple[int, np.ndarray]] = {}
        for obj in visual.geometryObjects:
            points = _shape_points(obj.geometry, obj.name, file)
            placed = points @ obj.placement.rotation.T + obj.placement.translation
            self.parts[_part_name(obj.name, self.parts)] = (int(obj.parentJoint), _hull(placed[:, [0, 2]]))

    def __call__(self, q: np.ndarray) -> dict[str, np.ndarray]:
        """Closed polylines (k, 2) of every visual shape at configuration q."""
        pin.forwardKinematics(self._model, self._data, np.asarray(q, dtype=float))
        out = {}
        for name, (joint, polygon) in self.parts.items():
            placement = self._data.oMi[joint]
            rotation = placement.rotation[np.ix_([0, 2], [0, 2])]
            out[name] = polygon @ rotation.T + placement.translation[[0, 2]]
        return out


def _part_name(name: str, taken: Mapping[str, Any]) -> str:
    """A geometry object's name without Pinocchio's ``_<index>`` suffix, unless that is taken."""
    base, _, index = name.rpartition("_")
    short = base if index.isdigit() and base else name
    return short if short not in taken else name


def _shape_points(shape: Any, name: str, file: Path) -> np.ndarray:
    """Points (k, 3) whose convex hull's projection on (x, z) is the shape's outline."""
    kind = type(shape).__name__
    ring = np.linspace(0.0, 2.0 * math.pi, ROUND_SAMPLES, endpoint=False)
    if kind == "Box":
        half = np.asarray(shape.halfSide, dtype=float)
        return np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half
    if kind in ("Cylinder", "Capsule"):
        r, h = float(shape.radius), float(shape.halfLength)
        circle = np.stack([r * np.cos(ring), r * np.sin(ring), np.zeros_like(ring)], axis=1)
        if kind == "Capsule":  # hemispherical caps: their silhouettes are circles about the ends
            circle = np.stack([r * np.cos(ring), np.zeros_like(ring), r * np.sin(ring)], axis=1)
        return np.concatenate([circle + np.array([0.0, 0.0, h]), circle - np.array([0.0, 0.0, h])])
    if kind == "Sphere":
        r = float(shape.radius)
        return np.stack([r * np.cos(ring), np.zeros_like(ring), r * np.sin(ring)], axis=1)
    vertices = getattr(shape, "vertices", None)
    if callable(vertices):
        points = np.asarray(vertices(), dtype=float).reshape(-1, 3)
        if len(points) >= 3:
            return points
    raise ModelError(
        f"{file}: visual '{name}' is a {kind}; the outlines know box, cylinder, sphere, capsule and meshes"
    )


def _hull(points: np.ndarray) -> np.ndarray:
    """The closed outline (k + 1, 2) of 2D points: their convex hull, first vertex repeated."""
    try:
        vertices = points[ConvexHull(points).vertices]
    except Exception:  # flat or degenerate: the extent along the longer axis
        axis = int(np.argmax(np.ptp(points, axis=0)))
        vertices = points[[int(np.argmin(points[:, axis])), int(np.argmax(points[:, axis]))]]
    return np.vstack([vertices, vertices[:1]])


CONTACT_KEYS = {"name": str, "frame": str, "restitution": float, "friction": float, "ground": float, "tangential": bool}
STOP_KEYS = {"name": str, "joint": str, "position": float, "side": str, "restitution": float}


def _record(table: Any, keys: Mapping[str, type], required: Sequence[str], where: str) -> dict[str, Any]:
    """A scene table checked against ``keys`` (name -> type): SceneError naming ``where`` and the key."""
    if not isinstance(table, Mapping):
        raise SceneError(f"{where}: expected a table {{{', '.join(keys)}}}, got {table!r}")
    unknown = sorted(set(table) - set(keys))
    if unknown:
        raise SceneError(f"{where}: unknown key(s) {unknown}; allowed: {list(keys)}")
    for key in required:
        if key not in table:
            raise SceneError(f"{where}.{key}: missing")
    out = {}
    for key, value in table.items():
        kind = keys[key]
        if kind is bool:
            ok = isinstance(value, bool)
        elif kind is float:
            ok = isinstance(value, (int, float)) and not isinstance(value, bool)
        else:
            ok = isinstance(value, kind)
        if not ok:
            raise SceneError(f"{where}.{key}: expected a {kind.__name__}, got {value!r}")
        out[key] = float(value) if kind is float else value
    return out


def scene_contacts(contacts: Sequence[Any], stops: Sequence[Any]) -> list[PointContact | JointStop]:
    """The ``contacts`` (point contacts on frames) and ``stops`` (joint stops) of a scene's tables."""
    out: list[PointContact | JointStop] = []
    where: dict[str, str] = {}  # each name's table: contacts and stops name modes alike
    for i, table in enumerate(contacts):
        record = _record(table, CONTACT_KEYS, ("name", "frame"), f"robot.parameters.contacts[{i}]")
        _check_restitution(record, f"robot.parameters.contacts[{i}]")
        out.append(PointContact(**record))
        _unique(out[-1].name, f"robot.parameters.contacts[{i}]", where)
    for i, table in enumerate(stops):
        record = _record(table, STOP_KEYS, ("name", "joint"), f"robot.parameters.stops[{i}]")
        _check_restitution(record, f"robot.parameters.stops[{i}]")
        if record.get("side", "lower") not in ("lower", "upper"):
            raise SceneError(f"robot.parameters.stops[{i}].side: expected 'lower' or 'upper', got {record['side']!r}")
        out.append(JointStop(**record))
        _unique(out[-1].name, f"robot.parameters.stops[{i}]", where)
    return out


def _check_restitution(record: Mapping[str, Any], where: str) -> None:
    value = record.get("restitution", 0.0)
    if not 0.0 <= value <= 1.0:  # nan fails too
        raise SceneError(f"{where}.restitution: expected a number in [0, 1], got {value!r}")


def _unique(name: str, table: str, where: dict[str, str]) -> None:
    """Record that ``table`` declares ``name``; SceneError naming both tables if one already did."""
    if name in where:
        raise SceneError(f"{table}.name: duplicate contact name {name!r} (also {where[name]}.name)")
    where[name] = table


PARAMETERS = {
    "file": Param("", "the URDF file (relative to the scene's folder)", path=True),
    "root": Param("planar", "the root joint: planar (x, z, pitch) or fixed to the world", choices=("planar", "fixed")),
    "actuated": Param(
        [], "joints driven by the control u, in the order of u's entries (N m or N); ['all']: every joint but the root"
    ),
    "contacts": Param(
        [],
        "point contacts: tables {name, frame, restitution = 0, friction (mu; none: no limit), "
        "ground = 0 (m), tangential = true}",
    ),
    "collisions": Param(
        False, "also take contacts from the URDF's <collision> shapes (spheres, boxes, cylinders: robots/collisions.py)"
    ),
    "collision_contacts": Param(
        {},
        "settings of the contacts from <collision> shapes: {restitution = 0, friction (mu; none: no limit), "
        "ground = 0 (m), links = {link = {restitution, friction} | 'off'}}",
    ),
    "stops": Param(
        [], "joint stops: tables {name, joint, position (rad or m), side = 'lower' | 'upper', restitution = 0}"
    ),
    "effort_limits": Param(
        {},
        "bounds on |u| per actuated joint (N m or N, > 0), overriding the URDF's <limit effort>; "
        "a joint given 'off' is not limited",
    ),
    "saturate": Param(
        True, "saturate each actuated joint's input at its effort limit (false: no limit, the URDF's nor the table's)"
    ),
    "below_ground": Param(
        "warn",
        "a link without a contact below the ground, the terrain's corner inside a body between its contacts, "
        "or an inactive contact carried through the ground by a step: "
        "'warn' (a warning naming link, time and depth), "
        "'strict' (the run stops with status model_breakdown: past the model) or 'fall' (a body through "
        "the ground stops the run with status fell: the robot crashed, as a [fall] condition; a contact "
        "carried through stops it with model_breakdown, as under 'strict': a touchdown the steps missed)",
        choices=("warn", "strict", "fall"),
    ),
    "g": Param(9.81, "gravitational acceleration", "m/s^2", low=0.0),
    "flight_mode": Param("flight", "name of the mode without active contacts"),
}


def effort_limits(model: pin.Model, actuated: Sequence[str], params: Mapping[str, Any]) -> dict[str, float]:
    """The effort limit (N m or N) of each actuated joint that has one: the URDF's ``<limit
    effort>`` (Pinocchio's ``effortLimit``; 0, which urdfdom also reads for a missing
    attribute, is no limit), overridden by ``params["effort_limits"]`` (a number > 0, or "off");
    none at all with ``saturate = false``. SceneError naming the field for a bad entry."""
    table = params.get("effort_limits") or {}
    where = "robot.parameters.effort_limits"
    if not isinstance(table, Mapping):
        raise SceneError(f"{where}: expected a table {{joint = limit (N m or N) | 'off'}}, got {table!r}")
    unknown = sorted(set(table) - set(actuated))
    if unknown:
        raise SceneError(f"{where}: unknown joint(s) {unknown}; actuated joints: {list(actuated)}")
    if not params.get("saturate", True):
        if table:
            raise SceneError(f"{where}: given with saturate = false, which turns every limit off; drop one of them")
        return {}
    out: dict[str, float] = {}
    for jname in actuated:
        j = model.getJointId(jname)
        urdf = float(model.effortLimit[model.joints[j].idx_v])
        if urdf < 0.0 and jname not in table:
            raise SceneError(
                f"{params['file']}: joint '{jname}': <limit effort='{urdf:g}'> is negative; give "
                f"{where}.{jname} (a limit > 0 or 'off')"
            )
        value: Any = table.get(jname, urdf)
        if value == "off":
            continue
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise SceneError(f"{where}.{jname}: expected a number > 0 (N m or N) or 'off', got {value!r}")
        if jname in table and value <= 0.0:
            raise SceneError(f"{where}.{jname}: {value!r} is out of range, allowed: float in (0, inf) or 'off'")
        if value > 0.0:
            out[jname] = float(value)
    return out


def make_bridge(
    params: Mapping[str, Any], terrain: Terrain | None = None
) -> tuple[ContactBridge, Outlines, dict[str, tuple[int, np.ndarray]]]:
    """The bridge of a URDF robot from the builder's parameters (on ``terrain``, the scene's
    ``[terrain]``), its visual outlines, and the collision outlines whose corners are its
    contacts (``collision_outlines``; none without ``collisions``), the URDF's collision shapes
    read once for both."""
    if not params["file"]:
        raise SceneError("robot.parameters.file: give the URDF file (a path relative to the scene)")
    model, names = load_model(params["file"], params["root"], params["g"])
    first = 2 if params["root"] == "planar" else 1
    joints = [model.names[j] for j in range(first, model.njoints)]
    actuated = joints if list(params["actuated"]) == ["all"] else list(params["actuated"])
    if not all(isinstance(name, str) for name in actuated):
        raise SceneError(
            f"robot.parameters.actuated: expected joint names (strings) or ['all'], got {params['actuated']!r:.200}; "
            f"joints: {joints}"
        )
    unknown = [name for name in actuated if name not in joints]
    if unknown:
        raise SceneError(f"robot.parameters.actuated: unknown joint(s) {unknown!r:.200}; joints: {joints}")
    repeated = sorted({name for name in actuated if actuated.count(name) > 1})
    if repeated:
        raise SceneError(f"robot.parameters.actuated: joint(s) {repeated} listed more than once: {actuated}")
    contacts = scene_contacts(params["contacts"], params["stops"])
    cornered: dict[str, tuple[int, np.ndarray]] = {}
    if params["collisions"]:
        shapes = collision_points(model, params["file"])
        contacts += collision_contacts(model, params["file"], params["collision_contacts"], shapes)
        cornered = collision_outlines(shapes, params["collision_contacts"])
    elif params["collision_contacts"]:
        raise SceneError(
            "robot.parameters.collision_contacts: given with collisions = false; set collisions = true or drop it"
        )
    limits = effort_limits(model, actuated, params)
    bridge = ContactBridge(
        model,
        contacts,
        coordinate_names=names,
        velocity_names=[f"{n}d" for n in names],
        mode_names={(): params["flight_mode"]},
        actuated=actuated,
        name=Path(params["file"]).stem,
        effort_limits=limits,
        terrain=terrain,
    )
    return bridge, Outlines(bridge.model, params["file"]), cornered


def link_heights(bridge: ContactBridge, outlines: Outlines, terrain: Terrain | None = None) -> LinkHeights:
    """The links without a point contact, each with its points: its visual outlines (in its
    joint's frame), or its joint's origin when it has no visual; heights above ``terrain``
    when given."""
    model = bridge.model
    touching = {
        int(model.frames[model.getFrameId(c.frame)].parentJoint) for c in bridge.contacts if isinstance(c, PointContact)
    }
    links: dict[str, tuple[int, np.ndarray]] = {}
    for j in range(1, model.njoints):
        if j in touching:
            continue
        bodies = [f.name for f in model.frames if f.type == pin.FrameType.BODY and int(f.parentJoint) == j]
        polygons = [poly for joint, poly in outlines.parts.values() if joint == j]
        if polygons:
            flat = np.vstack(polygons)
            points = np.column_stack([flat[:, 0], np.zeros(len(flat)), flat[:, 1]])
        else:
            points = np.zeros((1, 3))
        links[bodies[0] if bodies else model.names[j]] = (j, points)
    return LinkHeights(bridge.placements, links, terrain)


def terrain_piercing(
    bridge: ContactBridge,
    outlines: Outlines,
    heights: LinkHeights,
    cornered: Mapping[str, tuple[int, np.ndarray]],
    terrain: Terrain | None,
) -> TerrainPiercing | None:
    """On a terrain with corners or bumps (a profile, steps, a sine), the bodies a terrain point
    can pass into between their contacts: each collision outline whose corners are contacts
    (``cornered``), and each visual part of a link without a contact (``heights``' links); None
    on flat ground or a slope, which meets a convex body at a corner first."""
    if terrain is None or terrain.array[0] not in (PROFILE, SINE):
        return None
    bodies = dict(cornered)
    for name, (joint, _) in heights.links.items():
        # A part's outline is its convex hull closed by its first vertex: three corners or more
        # have an inside; a flat part's outline is a segment.
        hulls = [poly[:-1] for part_joint, poly in outlines.parts.values() if part_joint == joint and len(poly) >= 4]
        for k, hull in enumerate(hulls):
            bodies[name if k == 0 else f"{name}#{k}"] = (
                joint,
                np.column_stack([hull[:, 0], np.zeros(len(hull)), hull[:, 1]]),
            )
    return TerrainPiercing(bridge.placements, bodies, terrain) if bodies else None


def _starts_clear(
    contacts_check: Callable[[str, np.ndarray, float], str | None], ground_watches: list[Any]
) -> Callable[[str, np.ndarray, float], str | None]:
    """The scene's initial-state check: the contacts' (``bridge.initial_check``), then a link
    below the ground or the terrain inside a body by more than eps at the start, as its watch
    would name it: a run started there would report it at t = 0, which is a bad start, not an
    event of the run."""

    def check(mode: str, x: np.ndarray, eps: float) -> str | None:
        problem = contacts_check(mode, x, eps)
        if problem is not None:
            return problem
        held = [w for w in ground_watches if w.values(mode, np.zeros(1), x[None, :])[0] < -eps]
        return held[0].message(0.0, mode, x) if held else None

    return check


def _build(params: dict[str, Any], effects: dict[str, dict[str, Any]], terrain: Terrain | None = None) -> Model:
    bridge, outlines, cornered = make_bridge(params, terrain)
    n = bridge.n
    flight = params["flight_mode"]
    initial = dict.fromkeys(bridge.state_names(flight), 0.0)
    system = bridge.system(flight, np.zeros(2 * n))

    def geometry(mode: str, x: np.ndarray) -> dict[str, np.ndarray]:
        return outlines(np.asarray(x, dtype=float)[:n])

    heights = link_heights(bridge, outlines, terrain)
    ground = min((float(c.ground) for c in bridge.contacts if isinstance(c, PointContact)), default=0.0)
    if terrain is not None:  # heights are then measured above the terrain under each point
        ground = 0.0
    below = below_ground_watch(heights, ground, params["below_ground"]) if heights.links else None
    piercing = terrain_piercing(bridge, outlines, heights, cornered, terrain)
    inside = terrain_inside_watch(piercing, params["below_ground"]) if piercing is not None else None
    names, limits = bridge.actuated_names, bridge.effort_limits

    def watches(control: Any, eps: float) -> list[Any]:
        dims = lambda mode: system.mode(mode).dim  # noqa: E731
        ground_watches = [w for w in (below, inside) if w is not None]
        contacts = bridge.contact_watches(eps, params["below_ground"])
        return ground_watches + contacts + saturation_watches(control, names, limits, dims)

    info = bridge.model_info(
        parameters=dict(params),
        outlines=outlines,
        watches=watches,
        initial_check=_starts_clear(bridge.initial_check(), [w for w in (below, inside) if w is not None]),
        # What a recording needs to log the robot through Rerun's own URDF loader.
        urdf={"file": str(params["file"]), "root": params["root"]},
    )
    counters = bridge.counters
    return Model(
        system=system,
        initial_mode=flight,
        initial_state=initial,
        geometry=geometry,
        scenery={"ground": np.array([[-2.0, 0.0], [60.0, 0.0]]) if terrain is None else terrain.polyline(-2.0, 60.0)},
        counters=counters,
        info=info,
    )


BUILDER = Builder(
    "urdf",
    "a planar robot from a URDF file, with the contacts and stops the scene declares or its <collision> shapes",
    PARAMETERS,
    {},
    _build,
    terrain=True,
)


def make(parameters: dict[str, Any]) -> Model:
    """The URDF robot's model from builder parameters (``file`` absolute or relative to the
    working directory)."""
    return BUILDER.make(parameters, {})


def bundled(name: str) -> Path:
    """The path of a URDF file bundled with legsim's scenes (``legsim.scenarios``)."""
    from importlib import resources

    return Path(str(resources.files("legsim.scenarios"))) / name
