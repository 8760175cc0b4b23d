"""The robot of a recording back as polylines (``Frames``) at a selection of its samples: each
part's shape under its recorded transform, for the animation and plots ``legsim replay`` draws.

The frames are the recorded samples thinned like ``legsim.output.trace.frame_times`` thins time:
about ``fps`` per simulated second (coarser beyond ``max_frames``), plus the samples at every
strip's entry and exit while the total stays within ``max_frames``. Positions come back at the
float32 precision Rerun stores them in.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..trace import DEFAULT_FPS, DEFAULT_MAX_FRAMES, Frames
from .columns import Columns
from .layout import ROBOT, entity
from .poses import apply_poses

#: Where Rerun's URDF loader logs the joints' frames at joint value 0.
TF_STATIC = "/tf_static"
IDENTITY = {"translation": np.zeros(3), "quaternion": np.array([0.0, 0.0, 0.0, 1.0]), "scale": np.ones(3)}


def frame_rows(
    times: np.ndarray, strip_rows: list[int], fps: float = DEFAULT_FPS, max_frames: int = DEFAULT_MAX_FRAMES
) -> np.ndarray:
    """Sample rows to draw: the last sample at or before each time of a uniform grid of ``fps``
    per second (at most ``max_frames``), and each strip's entry and exit sample while the total
    stays within ``max_frames``."""
    span = float(times[-1] - times[0])
    count = int(min(max_frames, np.floor(span * fps) + 1)) if span > 0 else 1
    grid = np.linspace(times[0], times[-1], max(count, 2)) if span > 0 else times[:1]
    rows = np.unique(np.clip(np.searchsorted(times, grid, side="right") - 1, 0, len(times) - 1))
    events = np.array([r + k for r in strip_rows for k in (0, 1)], dtype=np.int64)
    if len(rows) + len(events) <= max_frames and len(events):
        rows = np.union1d(rows, events)
    return rows


def frames(
    columns: Columns,
    meta: dict[str, Any],
    times: np.ndarray,
    strips: list[dict[str, Any]],
    scenery: dict[str, np.ndarray],
) -> tuple[Frames, np.ndarray]:
    """The robot's polylines at ``frame_rows`` (None where a part is absent), and those rows."""
    rows = frame_rows(times, [s["row"] for s in strips])
    modes = _modes_at(columns, rows)
    if meta.get("urdf"):
        parts = _urdf_parts(columns, rows)
    else:
        parts = {part: _part_lines(columns, entity(ROBOT, part), rows) for part in meta.get("parts", [])}
    return Frames(times[rows], modes, parts, scenery), rows


def _modes_at(columns: Columns, rows: np.ndarray) -> list[str]:
    from .layout import MODE

    starts, _ = columns.numbers(MODE, "t_start")
    sequence = columns.strings(MODE, "StateChange:state")
    at = np.searchsorted(starts, rows, side="right") - 1
    return [sequence[i] for i in at.tolist()]


def _part_lines(columns: Columns, path: str, rows: np.ndarray) -> list[np.ndarray | None]:
    """One part's world polylines (k, 2) at ``rows``: its shape (static, or the latest logged
    at or before each row; None where that is empty) under the latest transform."""
    shape_rows, shapes = _shapes(columns, path)
    transforms = {
        key: _latest(columns, path, f"Transform3D:{key}", width, rows)
        for key, width in (("translation", 3), ("quaternion", 4), ("scale", 3))
    }
    which = np.searchsorted(shape_rows, rows, side="right") - 1
    lines: list[np.ndarray | None] = [None] * len(rows)
    for k in np.unique(which[which >= 0]).tolist():
        if shapes[k] is None:
            continue
        at = np.flatnonzero(which == k)
        world = apply_poses(shapes[k], *(transforms[key][at] for key in ("translation", "quaternion", "scale")))
        for i, points in zip(at.tolist(), world, strict=False):
            lines[i] = points
    return lines


def _shapes(columns: Columns, path: str) -> tuple[np.ndarray, list[np.ndarray | None]]:
    """(rows, shapes (k, 3) or None) of a part's geometry, static as row -1; both kinds of
    geometry are read, since a part is drawn by points or by line strips."""
    found: dict[int, np.ndarray | None] = {}
    for component, strips in (("LineStrips3D:strips", True), ("Points3D:positions", False)):
        for row, value in columns.rows(path, component):
            points = (value[0] if value else None) if strips else (value or None)
            found[row] = None if points is None or not len(points) else np.array(points, dtype=float).reshape(-1, 3)
    rows = sorted(found)
    if -1 in found:  # Rerun shows static data at every time, in place of any logged over time
        return np.array([-1]), [found[-1]]
    return np.array(rows, dtype=np.int64), [found[r] for r in rows]


def _latest(columns: Columns, path: str, component: str, width: int, rows: np.ndarray) -> np.ndarray:
    """The component's latest value at or before each of ``rows`` (identity before the first)."""
    logged, values = columns.matrix(path, component, width)
    at = np.searchsorted(logged, rows, side="right") - 1
    key = component.split(":")[1]
    out = np.tile(IDENTITY[key], (len(rows), 1))
    out[at >= 0] = values[at[at >= 0]]
    return out


# -- URDF robots: links composed from the recorded frames -------------------------------------
def _urdf_parts(columns: Columns, rows: np.ndarray) -> dict[str, list[np.ndarray | None]]:
    """Each link of a URDF recording (``legsim.output.rrd.urdf``) at ``rows`` as the polyline
    from its frame's origin to its child joints' origins (a point for a link without children),
    in the world's (x, z): the frames composed from the loader's static joint frames and the
    joints' and root's transforms recorded at or before each row."""
    from .urdf import JOINTS, WORLD_FRAME

    edges: dict[str, tuple[str, np.ndarray, np.ndarray]] = {}
    static_children = columns.strings(TF_STATIC, "Transform3D:child_frame")
    static_parents = columns.strings(TF_STATIC, "Transform3D:parent_frame")
    _, static_t = columns.matrix(TF_STATIC, "Transform3D:translation", 3)
    _, static_q = columns.matrix(TF_STATIC, "Transform3D:quaternion", 4)
    for i, (child, parent) in enumerate(zip(static_children, static_parents, strict=True)):
        edges[child] = (parent, np.tile(static_t[i], (len(rows), 1)), np.tile(static_q[i], (len(rows), 1)))
    for path in columns.entities():
        if path.startswith(f"{JOINTS}/"):
            (child, *_), (parent, *_) = (columns.strings(path, f"Transform3D:{k}_frame") for k in ("child", "parent"))
            translation = _latest(columns, path, "Transform3D:translation", 3, rows)
            edges[child] = (parent, translation, _latest(columns, path, "Transform3D:quaternion", 4, rows))
    placed: dict[str, tuple[np.ndarray, np.ndarray]] = {
        WORLD_FRAME: (np.tile(np.eye(3), (len(rows), 1, 1)), np.zeros((len(rows), 3)))
    }

    def place(frame: str) -> tuple[np.ndarray, np.ndarray]:
        """(rotations (F, 3, 3), origins (F, 3)) of ``frame`` in the world's."""
        if frame not in placed:
            parent, translation, quaternion = edges[frame]
            rotation, origin = place(parent)
            own = _rotations(quaternion)
            placed[frame] = (rotation @ own, origin + np.einsum("fij,fj->fi", rotation, translation))
        return placed[frame]

    children: dict[str, list[str]] = {}
    for child, (parent, _, _) in edges.items():
        children.setdefault(parent, []).append(child)
    parts: dict[str, list[np.ndarray | None]] = {}
    for link in edges:
        points = [place(link)[1]] + [place(child)[1] for child in children.get(link, [])]
        # origin, child, origin, child, ...: one polyline through every joint of the link.
        line = [points[0]] if len(points) == 1 else [p for child in points[1:] for p in (points[0], child)]
        stacked = np.stack(line, axis=1)[:, :, [0, 2]]
        parts[link] = list(stacked)
    return parts


def _rotations(quaternion: np.ndarray) -> np.ndarray:
    """Rotation matrices (F, 3, 3) of unit quaternions (F, 4), xyzw."""
    q = quaternion / np.linalg.norm(quaternion, axis=1, keepdims=True)
    x, y, z, w = q.T
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], axis=-1),
            np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], axis=-1),
            np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], axis=-1),
        ],
        axis=1,
    )
