"""Bodies as Rerun users draw them: a shape in the body's own frame, logged once, moved by a
transform per sample.

``Model.geometry`` gives each part as a polyline in the world's (x, z) plane at every state.
``Shape.of`` takes a part's first polyline as its shape: the local frame has its origin at the
first point and its x axis towards the *axis point* (the last point, or for a closed outline
the point farthest from the first). ``Shape.fit`` finds, for later polylines of the part, the
pose that maps the shape onto them:

    world = origin + R(angle) @ diag(scale_along, scale_across) @ local

(rotation in the x-z plane, from x towards z), exact for a part that moves rigidly (a link, a
trunk, a wheel), stretches along its axis (a spring leg) or across it; where no such pose
reproduces the polyline to ``FIT_TOLERANCE`` the sample is marked not fitted and the recording
draws that polyline as it is. ``apply_poses`` is the inverse, used when reading back.

In the 3D view the plane (x, z) is y = 0 of a z-up frame: a rotation by ``angle`` in the plane
is a rotation by ``-angle`` about +y, the quaternion (0, -sin(angle / 2), 0, cos(angle / 2)).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Largest distance (relative to 1 + the largest coordinate, m) between a polyline and its
#: fitted pose: far below the float32 rounding of the recorded transforms.
FIT_TOLERANCE = 1e-9


@dataclass(frozen=True)
class Shape:
    """A part's shape in its own frame: ``local`` (k, 2) points (m), the first at the origin;
    ``axis`` the index of the point on the local x axis (0 for a shape without extent)."""

    local: np.ndarray
    axis: int
    reference_length: float

    @classmethod
    def of(cls, polyline: np.ndarray) -> Shape:
        """The shape of ``polyline`` (k, 2): its points relative to the first, turned so that
        the axis point lies on +x."""
        points = np.asarray(polyline, dtype=float)
        offsets = points - points[0]
        distances = np.hypot(offsets[:, 0], offsets[:, 1])
        size = float(distances.max()) if len(points) else 0.0
        if size == 0.0:
            return cls(np.zeros_like(points), 0, 0.0)
        # An open polyline is measured along its ends; a closed one (its ends meet) from its
        # first point to the point farthest from it.
        axis = len(points) - 1 if distances[-1] > 1e-6 * size else int(np.argmax(distances))
        angle = float(np.arctan2(offsets[axis, 1], offsets[axis, 0]))
        return cls(_rotate(offsets, -angle), axis, float(distances[axis]))

    @property
    def is_point(self) -> bool:
        return self.reference_length == 0.0

    def fit(self, polylines: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Poses of ``polylines`` (n, k, 2), each of this shape's point count: (origin (n, 2) m,
        angle (n,) rad, scale (n, 2) along and across the axis, fitted (n,) bool)."""
        # A diverging run draws parts near the float64 limit: a pose that overflows there is
        # not finite, hence not fitted, and the polyline is recorded as it is.
        with np.errstate(over="ignore", invalid="ignore"):
            return self._fit(polylines)

    def _fit(self, polylines: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        polylines = np.asarray(polylines, dtype=float)
        n = len(polylines)
        origin = polylines[:, 0, :].copy()
        offsets = polylines - origin[:, None, :]
        if self.is_point:
            fitted = np.abs(offsets).max(axis=(1, 2), initial=0.0) <= _tolerance(polylines)
            return origin, np.zeros(n), np.ones((n, 2)), fitted
        axis = offsets[:, self.axis, :]
        length = np.hypot(axis[:, 0], axis[:, 1])
        angle = np.arctan2(axis[:, 1], axis[:, 0])
        turned = _rotate_each(offsets, -angle)
        across = self.local[:, 1]
        weight = float(across @ across)
        scale = np.ones((n, 2))
        scale[:, 0] = length / self.reference_length
        if weight > 0.0:
            scale[:, 1] = turned[:, :, 1] @ across / weight
        predicted = self.local[None, :, :] * scale[:, None, :]
        error = np.abs(turned - predicted).max(axis=(1, 2))
        # A part drawn with no length along its axis (a spring pressed flat) is its shape scaled
        # by 0 along the axis: arctan2 gives angle 0 there, and the error check decides.
        fitted = error <= _tolerance(polylines)
        return origin, angle, scale, fitted


def _tolerance(polylines: np.ndarray) -> np.ndarray:
    return FIT_TOLERANCE * (1.0 + np.abs(polylines).max(axis=(1, 2), initial=0.0))


def _rotate(points: np.ndarray, angle: float) -> np.ndarray:
    """``points`` (k, 2) turned by ``angle`` (rad) in the (x, z) plane."""
    c, s = np.cos(angle), np.sin(angle)
    return np.column_stack([c * points[:, 0] - s * points[:, 1], s * points[:, 0] + c * points[:, 1]])


def _rotate_each(points: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """``points`` (n, k, 2), each set turned by its own ``angles`` (n,) rad."""
    c, s = np.cos(angles)[:, None], np.sin(angles)[:, None]
    x, z = points[:, :, 0], points[:, :, 1]
    return np.stack([c * x - s * z, s * x + c * z], axis=-1)


# -- the 3D form of a pose --------------------------------------------------------------------
def to_3d(points: np.ndarray) -> np.ndarray:
    """(k, 2) points (x, z) as (k, 3) points (x, 0, z) of the z-up 3D view."""
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    out = np.zeros((len(points), 3))
    out[:, 0] = points[:, 0]
    out[:, 2] = points[:, 1]
    return out


def transform_columns(
    origin: np.ndarray, angle: np.ndarray, scale: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rerun's Transform3D components of the poses: translation (n, 3), quaternion (n, 4),
    xyzw, and scale (n, 3)."""
    n = len(angle)
    translation = np.zeros((n, 3))
    translation[:, 0], translation[:, 2] = origin[:, 0], origin[:, 1]
    quaternion = np.zeros((n, 4))
    quaternion[:, 1], quaternion[:, 3] = -np.sin(angle / 2), np.cos(angle / 2)
    scale3 = np.ones((n, 3))
    scale3[:, 0], scale3[:, 2] = scale[:, 0], scale[:, 1]
    return translation, quaternion, scale3


def apply_poses(local: np.ndarray, translation: np.ndarray, quaternion: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """World points (n, k, 2) of a shape with ``local`` (k, 3) points under n transforms:
    translation (n, 3), quaternion (n, 4) xyzw about y, scale (n, 3)."""
    # A diverged run's positions exceed float32, in which Rerun stores them: they come back
    # infinite, and the points computed from them not finite, which the drawings leave out.
    with np.errstate(over="ignore", invalid="ignore"):
        angle = -2.0 * np.arctan2(quaternion[:, 1], quaternion[:, 3])
        scaled = np.stack([local[None, :, 0] * scale[:, None, 0], local[None, :, 2] * scale[:, None, 2]], axis=-1)
        turned = _rotate_each(scaled, angle)
        return turned + np.stack([translation[:, 0], translation[:, 2]], axis=-1)[:, None, :]
