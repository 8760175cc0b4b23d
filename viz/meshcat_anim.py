"""Self-contained meshcat animations of a run (the ``--html`` output).

The page embeds meshcat's viewer bundle (``main.min.js``, three.js) and the scene as meshcat
commands, so it opens offline from the file system with no server. The commands are built
with meshcat's own Python classes (``SetObject``, ``SetProperty``, ``SetTransform``,
``SetAnimation`` with ``Animation``/``AnimationClip``) and packed with msgpack exactly as
``Visualizer.static_html()`` does. ``static_html()`` itself asks a running meshcat server for
the scene (``Visualizer()`` starts a ZMQ/tornado server process and binds ports), which a
headless batch run should not need, so we assemble the same page ourselves; the commands are
replayed in order by one script rather than by independent ``fetch`` promises, so that every
object exists before the animation that moves it is loaded.

meshcat animates transforms, not vertices, so each polyline segment of a part is a thin box
of unit length whose position, orientation (about the y axis) and length (x scale) are
keyframed; three.js interpolates between frames. The robot lives in the x-z plane of
meshcat's z-up world and the camera looks along +y. Parts use flat (unlit) colours.

What the page shows besides the robot: the ground (``ground`` or ``floor`` scenery) with a tick
every 0.5 m and a label every metre (coarser over long distances), fixed to the world; a
magenta ring at every active contact point while its contact mode is active
(``legsim.viz.contacts``); meshcat's own controls, whose "Animations" folder has the time
slider, play and pause. The camera is fixed and frames the whole run (``camera="fixed"``) so
that planted feet stay still on the screen and the travel is seen against the ground, or
follows the robot (``camera="follow"``; ``legsim run --html-camera follow``). Opening the page
as ``page.html#t=0.35`` pauses it at simulated time 0.35 s.
"""

from __future__ import annotations

import base64
import html as html_lib
import json
import math
import os
import uuid
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from legsim.builders import Model
from legsim.errors import OutputError
from legsim.execution import Execution
from legsim.hybrid import HybridSystem
from legsim.output.files import write_atomic
from legsim.output.trace import Frames, frame_times, geometry_frames, resolve_model

from ._common import run_title, writer_attributes
from .contacts import contact_frames

#: Frames per simulated second in an animation, and their most (longer runs get fewer).
HTML_FPS = 30.0
HTML_MAX_FRAMES = 900
PART_COLOURS = [0x1F77B4, 0xD62728, 0x2CA02C, 0xFF7F0E, 0x9467BD, 0x8C564B, 0xE377C2, 0x17BECF, 0xBCBD22]
SCENERY_COLOUR = 0x6E6E6E
BACKGROUND_TOP = [1.0, 1.0, 1.0]
BACKGROUND_BOTTOM = [0.90, 0.91, 0.93]
TINY = 1e-9  # scale of an absent segment: invisible yet an invertible transform
FOV_DEG = 75.0  # meshcat's default perspective camera
ASSUMED_ASPECT = 1.3  # window width / height the framing is computed for
#: Largest coordinate (m) drawn. A diverged run's geometry reaches inf, which would put the
#: camera at infinity (and three.js keyframes are float32): parts past it are left out.
HTML_LIMIT = 1e6
#: Camera modes: "fixed" frames the whole run, "follow" tracks a robot that makes headway.
CAMERAS = ("fixed", "follow")
CONTACT_COLOUR = 0xFF00FF
LABEL_COLOUR = 0x333333
#: Scenery parts that are the ground the ruler's ticks are drawn on (the first one present).
GROUND_PARTS = ("ground", "floor")
#: Tick spacings (m) of the ruler, finest first; the finest that gives at most MAX_TICKS ticks
#: over the shown ground is used, and every other tick is labelled.
TICK_SPACINGS = (0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0, 1000.0)
MAX_TICKS = 120
#: three.js keyframe interpolation "discrete": a contact marker jumps, it does not slide.
INTERPOLATE_DISCRETE = 2300


def html_frames(
    execution: Execution | None,
    scene: Any = None,
    *,
    model: Model | HybridSystem | None = None,
    recording: dict[str, Any] | None = None,
    fps: float = HTML_FPS,
    max_frames: int = HTML_MAX_FRAMES,
) -> Frames:
    """The geometry frames to animate: from ``recording`` (``legsim.record.read_rrd``) when
    given, else ``model.geometry`` evaluated on ``execution`` at ``fps`` frames per simulated
    second; parts past ``HTML_LIMIT`` (a diverged run) are absent. Raises OutputError when
    there is no geometry to draw."""
    return _frames_and_cut(execution, scene, model=model, recording=recording, fps=fps, max_frames=max_frames)[0]


def _frames_and_cut(
    execution: Execution | None,
    scene: Any = None,
    *,
    model: Model | HybridSystem | None = None,
    recording: dict[str, Any] | None = None,
    fps: float = HTML_FPS,
    max_frames: int = HTML_MAX_FRAMES,
) -> tuple[Frames, float | None]:
    """``html_frames`` and the time from which parts were left out (``drawable_frames``)."""
    if recording is not None:
        frames = recording.get("frames")
        if frames is None or not len(frames):
            name = recording.get("summary", {}).get("system", "this run")
            raise OutputError(
                f"an html animation needs the robot's geometry, and the recording of {name} has "
                f"none (its model defines no Model.geometry)"
            )
        return drawable_frames(frames)
    if not isinstance(execution, Execution):
        raise OutputError(f"an html animation needs a legsim Execution (or recording=), got {type(execution).__name__}")
    model = resolve_model(scene, model, "html")
    if model is None:
        raise OutputError("an html animation needs the robot's geometry: pass a scene or model=")
    if model.geometry is None:
        raise OutputError(
            f"an html animation needs the robot's geometry, and {model.system.name} defines none "
            f"(Model.geometry is None); use --plot or --rrd for this system"
        )
    # Interpolating a diverged run's last steps (values near the float64 limit) overflows;
    # those frames are left out by drawable_frames.
    with np.errstate(over="ignore", invalid="ignore"):
        frames = geometry_frames(execution, model, frame_times(execution, fps, max_frames))
    return drawable_frames(frames)


def drawable_frames(frames: Frames) -> tuple[Frames, float | None]:
    """``frames`` with every part that has a coordinate beyond ``HTML_LIMIT`` or not finite
    made absent (None) in that frame, and the first time that happened (None if never)."""
    first: float | None = None
    parts: dict[str, list[np.ndarray | None]] = {}
    for part, lines in frames.parts.items():
        kept: list[np.ndarray | None] = []
        for t, line in zip(frames.times, lines, strict=True):
            if line is not None and len(line) and not np.all(np.abs(line) <= HTML_LIMIT):
                first = float(t) if first is None else min(first, float(t))
                line = None
            kept.append(line)
        parts[part] = kept
    if first is None:
        return frames, None
    return Frames(frames.times, frames.modes, parts, frames.scenery), first


# -- geometry of the animation ------------------------------------------------------------------
def _segments(line: np.ndarray | None, count: int) -> np.ndarray:
    """(count, 6) rows (mx, mz, length, angle, present, _) for the segments of a polyline."""
    out = np.zeros((count, 6))
    if line is None or len(line) < 2:
        return out
    a, b = line[:-1], line[1:]
    d = b - a
    k = min(count, len(d))
    out[:k, 0:2] = ((a + b) / 2)[:k]
    out[:k, 2] = np.hypot(d[:k, 0], d[:k, 1])
    # Rotating the box's x axis about +y by phi sends it to (cos phi, 0, -sin phi).
    out[:k, 3] = -np.arctan2(d[:k, 1], d[:k, 0])
    out[:k, 4] = 1.0
    return out


def _robot_points(frames: Frames) -> list[np.ndarray]:
    """All robot points of each frame, (k, 2) per frame (empty where nothing is drawn)."""
    per_frame = []
    for i in range(len(frames)):
        at_frame = (lines[i] for lines in frames.parts.values())
        pts = [line for line in at_frame if line is not None and len(line)]
        per_frame.append(np.concatenate(pts) if pts else np.zeros((0, 2)))
    return per_frame


def camera_track(frames: Frames, follow: bool = False) -> tuple[np.ndarray, float, float]:
    """Camera x per frame (m), its height z (m) and its distance along -y (m).

    By default the camera stays put and frames the whole motion, so that the ground stands
    still under the robot. With ``follow`` it tracks the robot's (smoothed) horizontal centre
    when the robot travels more than a few body sizes in one direction (a runner stays in
    view at a readable size), and stays put otherwise (an oscillator reads better from a
    fixed camera).
    """
    per_frame = _robot_points(frames)
    drawn = [p for p in per_frame if len(p)]
    if drawn:
        allp = np.concatenate(drawn)
    elif frames.scenery:
        allp = np.concatenate(list(frames.scenery.values()))
    else:
        allp = np.zeros((1, 2))
    lo, hi = allp.min(axis=0), allp.max(axis=0)
    body = max(float(np.median([float(np.ptp(p[:, 0])) for p in drawn] or [0.0])), 1e-3)
    cam_x = _following(per_frame, frames, body) if follow else None
    if cam_x is None:
        cam_x = np.full(len(per_frame), (lo[0] + hi[0]) / 2)
        half_w = (hi[0] - lo[0]) / 2
    else:
        half_w = max(
            (float(np.max(np.abs(p[:, 0] - cx))) for p, cx in zip(per_frame, cam_x, strict=False) if len(p)),
            default=body,
        )
    # Show the ground below the robot: scenery points within the robot's horizontal range.
    z_lo, z_hi = lo[1], hi[1]
    for line in frames.scenery.values():
        near = line[(line[:, 0] >= lo[0] - body) & (line[:, 0] <= hi[0] + body)]
        if len(near):
            z_lo = min(z_lo, float(near[:, 1].min()))
    cam_z = (z_lo + z_hi) / 2
    half_h = max((z_hi - z_lo) / 2, 0.05)
    half_w = max(half_w, 0.05)
    tan = math.tan(math.radians(FOV_DEG / 2))
    distance = 1.25 * max(half_h, half_w / ASSUMED_ASPECT) / tan
    return cam_x, float(cam_z), float(distance)


def _following(per_frame: list[np.ndarray], frames: Frames, body: float) -> np.ndarray | None:
    """The smoothed horizontal centre of the robot per frame (m, half a second's moving
    average), or None when the robot makes no headway: it stays within a few body sizes, or
    swings back and forth over a wide range rather than travelling."""
    centres = np.array([(p[:, 0].min() + p[:, 0].max()) / 2 if len(p) else np.nan for p in per_frame])
    if len(centres) < 2 or np.all(np.isnan(centres)):
        return None
    centres = np.where(np.isnan(centres), np.nanmean(centres), centres)
    spread = float(np.ptp(centres))
    progress = abs(float(centres[-1] - centres[0]))
    if not (spread > 3.0 * body and progress > 0.5 * spread):
        return None
    per_second = len(centres) / max(frames.times[-1] - frames.times[0], 1e-9)
    window = max(1, min(len(centres), round(per_second * 0.5)))
    pad = np.pad(centres, (window // 2, window - 1 - window // 2), mode="edge")
    return np.convolve(pad, np.ones(window) / window, mode="valid")


def view_half_width(distance: float) -> float:
    """Half the width (m) of the world seen in the robot's plane from ``distance`` (m)."""
    return distance * math.tan(math.radians(FOV_DEG / 2)) * ASSUMED_ASPECT


def ground_ruler(
    scenery: dict[str, np.ndarray], lo: float, hi: float
) -> tuple[float, np.ndarray, np.ndarray, np.ndarray] | None:
    """Ticks along the ground between x = ``lo`` and ``hi`` (m): (spacing (m), tick x (k,),
    ground height z at each tick (k,), which ticks are labelled (k,) bool: every other one,
    on whole multiples of twice the spacing). None when the scenery has no ground part
    (``GROUND_PARTS``) or the ground is outside [lo, hi]."""
    part = next((scenery[name] for name in GROUND_PARTS if name in scenery and len(scenery[name]) >= 2), None)
    if part is None:
        return None
    order = np.argsort(part[:, 0], kind="stable")
    gx, gz = part[order, 0], part[order, 1]
    a, b = max(lo, float(gx[0])), min(hi, float(gx[-1]))
    if not b > a:
        return None
    spacing = next((s for s in TICK_SPACINGS if (b - a) / s <= MAX_TICKS), TICK_SPACINGS[-1])
    first, last = math.ceil(a / spacing - 1e-9), math.floor(b / spacing + 1e-9)
    steps = np.arange(first, last + 1)
    xs = steps * spacing
    return spacing, xs, np.interp(xs, gx, gz), steps % 2 == 0


def _thickness(frames: Frames, distance: float) -> float:
    """Width (m) of the drawn lines: 1.2 % of the robot's size, and at least about 2 px of a
    900 px wide window, so a small robot moving over a wide range stays visible."""
    drawn = [p for p in _robot_points(frames) if len(p)]
    if drawn:
        sizes = [float(np.hypot(*np.ptp(p, axis=0))) for p in drawn]
        size = float(np.median(sizes))
    else:
        size = 0.0
    if size <= 0:
        pts = np.concatenate(drawn) if drawn else np.zeros((1, 2))
        size = max(float(np.hypot(*np.ptp(pts, axis=0))), 1.0)
    return max(0.012 * size, 0.004 * view_half_width(distance))


# -- meshcat commands ---------------------------------------------------------------------------
def _meshcat():
    # Importing any part of meshcat imports its ZMQ server module, which warns that
    # zmq.eventloop.ioloop is deprecated; nothing here uses the server.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        import meshcat
        import meshcat.animation
        import meshcat.commands
        import meshcat.geometry
        import meshcat.path
    return meshcat


def _commands(
    frames: Frames, speed: float, contacts: dict[str, list[np.ndarray | None]] | None = None, camera: str = "fixed"
) -> list[dict[str, Any]]:
    """The meshcat commands of the page, in the order they must run: background, scenery and
    the ground's ruler, the robot's parts, the contact markers, the camera, and last the
    animation that moves what exists by then."""
    if camera not in CAMERAS:
        raise OutputError(f"camera must be one of {list(CAMERAS)}, got {camera!r}")
    cam_x, cam_z, distance = camera_track(frames, follow=camera == "follow")
    scene = _SceneCommands(frames, speed, _thickness(frames, distance))
    scene.background()
    for part, line in frames.scenery.items():
        scene.scenery(part, line)
    half = view_half_width(distance)
    ruler = ground_ruler(frames.scenery, float(np.min(cam_x)) - half, float(np.max(cam_x)) + half)
    if ruler is not None:
        scene.ruler(*ruler, view_height=half / ASSUMED_ASPECT * 2)
    for k, (part, lines) in enumerate(frames.parts.items()):
        scene.part(part, lines, PART_COLOURS[k % len(PART_COLOURS)])
    for name, points in (contacts or {}).items():
        scene.contact(name, points)
    scene.camera(cam_x, cam_z, distance)
    return scene.finish()


class _Geometry:
    """A three.js geometry meshcat has no class for (``TorusGeometry``, ``PlaneGeometry``),
    lowered the way meshcat lowers its own; ``intrinsic`` turns it (4x4) inside its object."""

    field = "geometries"

    def __init__(self, kind: str, intrinsic: np.ndarray | None = None, **params: float) -> None:
        self.uuid = str(uuid.uuid4())
        self.data = {"type": kind, **params}
        self.intrinsic = np.eye(4) if intrinsic is None else intrinsic

    def intrinsic_transform(self) -> np.ndarray:
        # meshcat writes this matrix row by row (``flatten()``) and three.js reads it column by
        # column: hand over the transpose.
        return self.intrinsic.T

    def lower(self, object_data: dict[str, Any]) -> dict[str, Any]:
        return {"uuid": self.uuid, **self.data}

    def lower_in_object(self, object_data: dict[str, Any]) -> str:
        object_data.setdefault(self.field, []).append(self.lower(object_data))
        return self.uuid


#: Turns three.js's xy-plane shapes (planes, rings) to face the camera, which looks along +y:
#: a quarter turn about x sends their normal +z to -y and their up +y to +z.
FACING_CAMERA = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, -1.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]])


class _DiscreteTrack:
    """A meshcat animation track whose values jump at the key times instead of being
    interpolated between them."""

    def __init__(self, track: Any) -> None:
        self.track = track

    def lower(self) -> dict[str, Any]:
        return {**self.track.lower(), "interpolation": INTERPOLATE_DISCRETE}


class _SceneCommands:
    """Collects the lowered meshcat commands (``cmds``) and animation clips of one page.

    ``key_times``: the frames' times in seconds of playback (clip fps 1; three.js interpolates
    between them); ``w``: the width (m) of the drawn lines.
    """

    def __init__(self, frames: Frames, speed: float, w: float) -> None:
        mc = _meshcat()
        self.g, self.anim, self.commands, self.Path = mc.geometry, mc.animation, mc.commands, mc.path.Path
        self.root = self.Path(("meshcat",))
        self.w = w
        self.key_times = [float(t) for t in (np.asarray(frames.times) - frames.times[0]) / speed]
        self.cmds: list[dict[str, Any]] = []
        self.animation = self.anim.Animation(default_framerate=1)

    def set_property(self, name: str, value: Any, *path: str) -> None:
        self.cmds.append(self.commands.SetProperty(name, value, self.Path(path)).lower())

    def add(self, shape: Any, material: Any, path: Any, transform: np.ndarray | None = None) -> None:
        self.cmds.append(self.commands.SetObject(shape, material, path).lower())
        if transform is not None:
            self.cmds.append(self.commands.SetTransform(transform, path).lower())

    def clip(self, path: Any, discrete: bool = False, **tracks: tuple[str, list]) -> None:
        """Animate ``path``: track name -> (value type, one value per key time); ``discrete``
        values hold until the next key time."""
        clip = self.anim.AnimationClip(fps=1)
        for name, (kind, values) in tracks.items():
            track = self.anim.AnimationTrack(name, kind, list(self.key_times), values)
            clip.tracks[name] = _DiscreteTrack(track) if discrete else track
        self.animation.clips[path] = clip

    def background(self) -> None:
        self.set_property("visible", False, "Grid")
        self.set_property("visible", False, "Axes")
        self.set_property("top_color", BACKGROUND_TOP, "Background")
        self.set_property("bottom_color", BACKGROUND_BOTTOM, "Background")

    def scenery(self, part: str, line: np.ndarray) -> None:
        """A static polyline: one box per segment."""
        material = self.g.MeshBasicMaterial(color=SCENERY_COLOUR)
        for j, (mx, mz, length, phi, _, _) in enumerate(_segments(line, max(len(line) - 1, 0))):
            self.add(
                self.g.Box([1.0, self.w, self.w]),
                material,
                self.root.append(f"scenery/{part}/{j}"),
                _matrix(mx, mz, max(length, TINY), phi),
            )

    def ruler(self, spacing: float, xs: np.ndarray, zs: np.ndarray, labelled: np.ndarray, view_height: float) -> None:
        """Ticks down from the ground at ``xs`` (m; heights ``zs``), the ``labelled`` ones
        longer and with their x below them (``view_height``: the height of the view, m)."""
        material = self.g.MeshBasicMaterial(color=SCENERY_COLOUR)
        size = 0.12 * view_height  # of a label's square: its text is about a quarter as tall
        for j, (x, z, big) in enumerate(zip(xs, zs, labelled, strict=False)):
            length = (0.04 if big else 0.02) * view_height
            self.add(
                self.g.Box([1.0, 0.7 * self.w, 0.7 * self.w]),
                material,
                self.root.append(f"scenery/ruler/tick/{j}"),
                _matrix(float(x), float(z) - length / 2, length, math.pi / 2),
            )
            if big:
                # meshcat draws the text just above its square's centre: the square's centre
                # goes a fifth of its size below the tick's end.
                self.label(
                    f"{float(x) + 0.0:g} m",
                    float(x),
                    float(z) - length - 0.01 * view_height - 0.2 * size,
                    size,
                    f"scenery/ruler/label/{j}",
                )

    def label(self, text: str, x: float, z: float, size: float, path: str) -> None:
        """``text`` on a transparent square of side ``size`` (m) centred at (x, z), facing the camera."""
        texture = self.g.GenericTexture({"type": "_text", "text": text, "font_size": 64, "font_face": "sans-serif"})
        material = self.g.MeshBasicMaterial(color=0xFFFFFF, map=texture, transparent=True)
        self.add(
            _Geometry("PlaneGeometry", FACING_CAMERA, width=size, height=size),
            material,
            self.root.append(path),
            _matrix(x, z, 1.0, 0.0),
        )

    def contact(self, name: str, points: list[np.ndarray | None]) -> None:
        """A ring around contact ``name`` in the frames where it is active (``points``: its
        (x, z) per frame, None where inactive), in front of the robot."""
        path = self.root.append(f"contacts/{name}")
        ring = _Geometry(
            "TorusGeometry", FACING_CAMERA, radius=3.5 * self.w, tube=0.6 * self.w, radialSegments=8, tubularSegments=40
        )
        self.add(ring, self.g.MeshBasicMaterial(color=CONTACT_COLOUR), path)
        last = next((p for p in points if p is not None), np.zeros(2))
        pos, scale = [], []
        for p in points:
            last = last if p is None else p
            pos.append([float(last[0]), -2.0 * self.w, float(last[1])])
            scale.append([TINY] * 3 if p is None else [1.0] * 3)
        self.clip(path, discrete=True, position=("vector3", pos), scale=("vector3", scale))

    def part(self, part: str, lines: list[np.ndarray | None], colour: int) -> None:
        """A robot part: a moving ball when it is one point, else one keyframed box per segment."""
        material = self.g.MeshBasicMaterial(color=colour)
        most = max((len(line) for line in lines if line is not None), default=0)
        if most == 1:
            self.point(part, lines, material)
        if most > 1:
            table = np.stack([_segments(line, most - 1) for line in lines])  # (F, most - 1, 6)
            for j in range(most - 1):
                self.segment(part, j, table[:, j, :], material)

    def point(self, part: str, lines: list[np.ndarray | None], material: Any) -> None:
        path = self.root.append(f"robot/{part}/0")
        self.add(self.g.Sphere(2.5 * self.w), material, path)
        pos, scale = [], []
        for line in lines:
            there = line is not None and len(line) == 1
            p = line[0] if line is not None and there else np.zeros(2)
            pos.append([float(p[0]), 0.0, float(p[1])])
            s = 1.0 if there else TINY
            scale.append([s, s, s])
        self.clip(path, position=("vector3", pos), scale=("vector3", scale))

    def segment(self, part: str, j: int, rows: np.ndarray, material: Any) -> None:
        """Segment ``j`` of a part: ``rows`` (F, 6) as ``_segments`` gives them, one per frame."""
        path = self.root.append(f"robot/{part}/{j}")
        self.add(self.g.Box([1.0, self.w, self.w]), material, path)
        pos = [[float(r[0]), 0.0, float(r[1])] for r in rows]
        quat = [[0.0, math.sin(r[3] / 2), 0.0, math.cos(r[3] / 2)] for r in rows]
        scale = [[max(float(r[2]), TINY), 1.0, 1.0] if r[4] else [TINY, TINY, TINY] for r in rows]
        self.clip(path, position=("vector3", pos), quaternion=("quaternion", quat), scale=("vector3", scale))

    def camera(self, cam_x: np.ndarray, cam_z: float, distance: float) -> None:
        # meshcat's orbit controls always look at the world origin, so rather than moving the
        # camera we move the whole drawing (/meshcat) to put the point of interest there.
        self.cmds.append(self.commands.SetTransform(_matrix(-float(cam_x[0]), -cam_z, 1.0, 0.0), self.root).lower())
        # The camera sits in meshcat's y-up "rotated" frame: local +z is world -y.
        cam_obj = ("Cameras", "default", "rotated", "<object>")
        self.set_property("position", [0.0, 0.0, distance], *cam_obj)
        self.set_property("far", 20.0 * distance + 100.0, *cam_obj)
        if np.ptp(cam_x) > 0:
            self.clip(self.root, position=("vector3", [[-float(x), 0.0, -cam_z] for x in cam_x]))

    def finish(self) -> list[dict[str, Any]]:
        """The commands, with the animation of every clip last."""
        if self.animation.clips:
            self.cmds.append(self.commands.SetAnimation(self.animation, play=True, repetitions=1_000_000).lower())
        return self.cmds


def _matrix(x: float, z: float, length: float, phi: float) -> np.ndarray:
    c, s = math.cos(phi), math.sin(phi)
    m = np.eye(4)
    m[:3, :3] = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]]) @ np.diag([length, 1.0, 1.0])
    m[0, 3], m[2, 3] = x, z
    return m


def animation_html(
    frames: Frames,
    *,
    title: str = "legsim",
    speed: float = 1.0,
    contacts: dict[str, list[np.ndarray | None]] | None = None,
    camera: str = "fixed",
) -> str:
    """The complete page: meshcat's bundle, the scene commands and a clock showing the
    simulated time and mode of the frame on screen. ``contacts``: contact name -> its (x, z)
    point (m) per frame, None where inactive (``legsim.viz.contacts.contact_frames``);
    ``camera``: "fixed" (frames the whole run) or "follow"."""
    import umsgpack

    meshcat = _meshcat()

    if not len(frames):
        raise OutputError("an html animation needs at least one frame")
    if not (speed > 0 and math.isfinite(speed)):
        raise OutputError(f"speed must be finite and > 0, got {speed!r}")
    commands = _commands(frames, speed, _drawable_contacts(contacts or {}, len(frames)), camera)
    packed = [base64.b64encode(umsgpack.packb(c)).decode("ascii") for c in commands]
    bundle = Path(meshcat.viewer_assets_path()) / "dist" / "main.min.js"
    try:
        js = bundle.read_text(encoding="utf-8")
    except OSError as exc:
        raise OutputError(f"meshcat's viewer bundle is missing ({bundle}): {exc}") from exc
    clock = {
        "t": [float(t) for t in frames.times],
        "mode": list(frames.modes),
        "t0": float(frames.times[0]),
        "speed": float(speed),
    }
    # "</" cannot appear inside a <script> element.
    safe_js = js.replace("</script", "<\\/script")
    return _PAGE.format(
        title=html_lib.escape(title),
        bundle=safe_js,
        commands=json.dumps(packed),
        clock=json.dumps(clock).replace("</", "<\\/"),
    )


def _drawable_contacts(contacts: dict[str, list[np.ndarray | None]], count: int) -> dict[str, list[np.ndarray | None]]:
    """``contacts`` with points beyond ``HTML_LIMIT`` absent; OutputError unless every contact
    has one entry per frame."""
    wrong = {name: len(points) for name, points in contacts.items() if len(points) != count}
    if wrong:
        raise OutputError(f"contacts need one point (or None) per frame ({count}), got {wrong}")
    return {
        name: [p if p is not None and np.all(np.abs(p) <= HTML_LIMIT) else None for p in points]
        for name, points in contacts.items()
    }


_PAGE = """<!DOCTYPE html>
<html>
<head><meta charset="utf-8"><title>{title}</title>
<style>
body {{ margin: 0; }}
#meshcat-pane {{ width: 100vw; height: 100vh; overflow: hidden; }}
#legsim-clock {{ position: absolute; left: 12px; top: 10px; font: 14px sans-serif; color: #222;
                 background: rgba(255,255,255,0.7); padding: 4px 8px; border-radius: 4px; }}
</style></head>
<body>
<div id="meshcat-pane"></div>
<div id="legsim-clock">{title}</div>
<script>{bundle}</script>
<script>
var viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));
var legsimCommands = {commands};
for (var i = 0; i < legsimCommands.length; i++) {{
  var raw = atob(legsimCommands[i]);
  var bytes = new Uint8Array(raw.length);
  for (var j = 0; j < raw.length; j++) bytes[j] = raw.charCodeAt(j);
  viewer.handle_command_bytearray(bytes);
}}
var legsimClock = {clock};
var legsimTitle = document.getElementById("legsim-clock").textContent;
function legsimTick() {{
  var a = viewer.animator;
  var played = (a && a.actions && a.actions.length) ? a.actions[0].time : 0;
  var t = legsimClock.t0 + played * legsimClock.speed;
  var k = 0, times = legsimClock.t;
  while (k + 1 < times.length && times[k + 1] <= t) k++;
  document.getElementById("legsim-clock").textContent =
      legsimTitle + "   t = " + t.toFixed(3) + " s   mode " + legsimClock.mode[k];
  requestAnimationFrame(legsimTick);
}}
requestAnimationFrame(legsimTick);
// page.html#t=0.35: paused at simulated time 0.35 s (meshcat's time slider still moves it).
function legsimSeek(t) {{
  var a = viewer.animator;
  if (!a || !a.actions || !a.actions.length) return;
  a.pause();
  a.seek((t - legsimClock.t0) / legsimClock.speed);
  a.display_progress(a.actions[0].time);
}}
var legsimAt = /(?:^|&)t=([-+0-9.eE]+)/.exec(window.location.hash.slice(1));
if (legsimAt) legsimSeek(parseFloat(legsimAt[1]));
</script>
</body>
</html>
"""


# ``legsim run`` refuses --html before the run when the scene's model has no geometry.
@writer_attributes(needs_geometry=True)
def write_html(
    execution: Execution | None,
    scene: Any = None,
    path: str | os.PathLike | None = None,
    *,
    model: Model | HybridSystem | None = None,
    recording: dict[str, Any] | None = None,
    fps: float = HTML_FPS,
    max_frames: int = HTML_MAX_FRAMES,
    speed: float = 1.0,
    camera: str = "fixed",
) -> Path:
    """Write a self-contained meshcat animation of the run to ``path`` (the ``--html`` output).

    ``scene`` is a ``legsim.scene.Scene`` or None with ``model=`` a ``legsim.builders.Model``
    (a plain ``HybridSystem`` has no geometry to draw);
    ``recording=`` takes ``legsim.record.read_rrd`` output instead of an execution (its page
    has no contact markers: a recording does not say where the contacts are). Plays in real
    time (``speed`` > 1 faster) and loops; ``camera`` is "fixed" (the whole run in view, the
    default) or "follow" (tracks a travelling robot). Raises OutputError when the model has no
    geometry. Atomic write.
    """
    if path is None:
        raise OutputError("write_html needs a path to write to")
    if camera not in CAMERAS:
        raise OutputError(f"camera must be one of {list(CAMERAS)}, got {camera!r}")
    path = Path(path)
    frames, cut = _frames_and_cut(execution, scene, model=model, recording=recording, fps=fps, max_frames=max_frames)
    contacts = None
    if recording is not None:
        s = recording.get("summary", {})
        title = s.get("scene") or s.get("system") or "legsim"
    else:
        assert isinstance(execution, Execution)  # _frames_and_cut refuses anything else
        resolved = resolve_model(scene, model, "html")
        title = run_title(execution, scene, resolved).split("  ·  ")[0]
        with np.errstate(over="ignore", invalid="ignore"):
            contacts = contact_frames(execution, resolved, frames.times)
    if cut is not None:
        # Otherwise a robot vanishing mid-animation would look like a bug of the page.
        title += f" (diverged: not drawn past t = {cut:.6g} s)"
    page = animation_html(frames, title=title, speed=speed, contacts=contacts, camera=camera)
    return write_atomic(path, lambda tmp: tmp.write_text(page, encoding="utf-8"), what="html")
