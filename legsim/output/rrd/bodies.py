"""Logging the robot's parts (``/world/robot/<part>``): each part's shape once, a Transform3D
per sample, block by block so that memory stays bounded.

Each part keeps what the viewer shows of it: its shape under the fitted pose (``SHAPE``),
nothing (``ABSENT``: the model does not draw it in that sample) or its own polyline in world
coordinates under an identity transform (``POLYLINE``: no pose of the shape reproduces it).
Geometry is logged only where that changes; a part shown by its shape in every sample from
the first gets the shape statically, once. See ``legsim.output.rrd.layout``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .layout import PALETTE, ROBOT, entity
from .poses import Shape, to_3d, transform_columns

SHAPE, ABSENT, POLYLINE = "shape", "absent", "polyline"
#: Largest change of a rotation (quaternion) or scale since the value last sent that is not
#: sent again: the rounding noise of the fit, far below the float32 the viewer stores.
UNCHANGED = 1e-12
#: Radii of the drawn parts in the viewer's user-interface points (negative in Rerun).
LINE_RADIUS, POINT_RADIUS = -2.5, -6.0

Indexes = Callable[[np.ndarray], list]


@dataclass
class PartTrack:
    """What has been logged of one part: its shape, whether it is drawn as points, what the
    viewer shows since the last row logged, and the last transform components sent."""

    entity: str
    colour: tuple[int, int, int]
    shape: Shape
    points: bool
    first_row: int
    shown: str | None = None
    only_shape: bool = True
    deferred_shape_row: int | None = None
    last: dict[str, np.ndarray] = field(default_factory=dict)


class BodyLogger:
    """Logs the parts of each block of samples (``add``) and their shapes at the end (``finish``)."""

    def __init__(self, rr: Any, rec: Any, indexes: Indexes) -> None:
        self.rr, self.rec, self.indexes = rr, rec, indexes
        self.tracks: dict[str, PartTrack] = {}
        self.low = np.full(2, np.inf)
        self.high = np.full(2, -np.inf)

    def add(self, rows: np.ndarray, drawn: list[dict[str, np.ndarray]]) -> None:
        """Log the parts drawn at the sample ``rows`` (``drawn[i]``: part -> (k, 2) polyline)."""
        for row, parts in zip(rows.tolist(), drawn, strict=True):
            for part, line in parts.items():
                if part not in self.tracks:
                    self._start(part, line, row)
                self.low = np.minimum(self.low, line.min(axis=0))
                self.high = np.maximum(self.high, line.max(axis=0))
        for part, track in self.tracks.items():
            mine = rows >= track.first_row
            lines = [parts.get(part) for parts, keep in zip(drawn, mine, strict=True) if keep]
            if len(lines):
                self._add_part(track, rows[mine], lines)

    def _start(self, part: str, line: np.ndarray, row: int) -> None:
        rr = self.rr
        colour = PALETTE[len(self.tracks) % len(PALETTE)]
        track = PartTrack(entity(ROBOT, part), colour, Shape.of(line), len(line) == 1, row)
        style = (
            rr.Points3D.from_fields(colors=[colour], radii=[POINT_RADIUS])
            if track.points
            else rr.LineStrips3D.from_fields(colors=[colour], radii=[LINE_RADIUS])
        )
        self.rec.log(track.entity, style, static=True)
        self.tracks[part] = track

    def _add_part(self, track: PartTrack, rows: np.ndarray, lines: list[np.ndarray | None]) -> None:
        n = len(rows)
        origin, angle, scale = np.zeros((n, 2)), np.zeros(n), np.ones((n, 2))
        fitted = np.zeros(n, dtype=bool)
        matching = {
            i: line for i, line in enumerate(lines) if line is not None and line.shape == track.shape.local.shape
        }
        same = list(matching)
        if same:
            fit = track.shape.fit(np.stack(list(matching.values())))
            origin[same], angle[same], scale[same], fitted[same] = fit
        shown = [SHAPE if fitted[i] else ABSENT if lines[i] is None else POLYLINE for i in range(n)]
        self._log_geometry(track, rows, lines, shown)
        self._log_transforms(track, rows, *transform_columns(origin, angle, scale))

    def _log_geometry(
        self, track: PartTrack, rows: np.ndarray, lines: list[np.ndarray | None], shown: list[str]
    ) -> None:
        """Geometry rows where what the part shows changes (and every row it is its own polyline)."""
        logged_rows, drawn = [], []
        for i, (row, now) in enumerate(zip(rows.tolist(), shown, strict=False)):
            if now != SHAPE:
                track.only_shape = False
            if now == track.shown and now != POLYLINE:
                continue
            if track.shown is None and now == SHAPE:
                track.deferred_shape_row = row  # static, unless the part ever shows otherwise
            else:
                logged_rows.append(row)
                drawn.append(track.shape.local if now == SHAPE else lines[i] if now == POLYLINE else None)
            track.shown = now
        if logged_rows:
            self._send_geometry(track, np.array(logged_rows), drawn)

    def _send_geometry(self, track: PartTrack, rows: np.ndarray, drawn: list[np.ndarray | None]) -> None:
        rr = self.rr
        present = [to_3d(line) for line in drawn if line is not None]
        if track.points:
            positions = np.concatenate(present) if present else np.zeros((0, 3))
            counts = [0 if line is None else len(line) for line in drawn]
            columns = rr.Points3D.columns(positions=positions).partition(counts)
        else:
            columns = rr.LineStrips3D.columns(strips=present).partition([0 if line is None else 1 for line in drawn])
        self.rec.send_columns(track.entity, indexes=self.indexes(rows), columns=columns)

    def _log_transforms(
        self, track: PartTrack, rows: np.ndarray, translation: np.ndarray, quaternion: np.ndarray, scale: np.ndarray
    ) -> None:
        """A translation per row; rotation and scale in the blocks where they are not what was
        last sent (the viewer takes each component's latest value)."""
        identity = {"quaternion": np.array([0.0, 0.0, 0.0, 1.0]), "scale": np.ones(3)}
        sent: dict[str, np.ndarray] = {"translation": translation}
        for key, value in (("quaternion", quaternion), ("scale", scale)):
            if np.abs(value - track.last.get(key, identity[key])).max(initial=0.0) > UNCHANGED:
                sent[key] = value
        for key, value in sent.items():
            track.last[key] = value[-1]
        self.rec.send_columns(track.entity, indexes=self.indexes(rows), columns=self.rr.Transform3D.columns(**sent))

    def finish(self) -> None:
        """Log each part's shape: statically when every sample shows it, else at its first row."""
        for track in self.tracks.values():
            if track.deferred_shape_row is None:
                continue
            if track.only_shape and track.first_row == 0:
                rr = self.rr
                local = to_3d(track.shape.local)
                shape = (
                    rr.Points3D.from_fields(positions=local)
                    if track.points
                    else rr.LineStrips3D.from_fields(strips=[local])
                )
                self.rec.log(track.entity, shape, static=True)
            else:
                self._send_geometry(track, np.array([track.deferred_shape_row]), [track.shape.local])

    def box(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The (x, z) corners of everything drawn, or None when nothing was."""
        return (self.low, self.high) if np.all(np.isfinite(self.low)) else None

    @property
    def parts(self) -> dict[str, str]:
        """Part name -> its entity path."""
        return {part: track.entity for part, track in self.tracks.items()}

    @property
    def point_parts(self) -> list[str]:
        return [part for part, track in self.tracks.items() if track.points]
