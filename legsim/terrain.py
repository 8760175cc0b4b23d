"""Terrain: the ground as a height profile z = h(x) in the sagittal plane, encoded as a plain float
array that model functions read (numba-compiled and interpreted alike).

Kinds (``Terrain.array``, float64; the first entry is the kind code):

``flat``     ``[FLAT, h0]``: h = h0.
``slope``    ``[SLOPE, g, x0, z0]``: h = z0 + g (x - x0), g = tan(angle) the grade.
``profile``  ``[PROFILE, n, x_0 .. x_{n-1}, z_0 .. z_{n-1}]``: piecewise linear through the n
             points (x strictly increasing), level beyond the first and last (h = z_0 left of
             x_0, z_{n-1} right of x_{n-1}). Steps are such a profile: each riser a steep
             ramp of run ``riser`` (``steps_profile``).
``sine``     ``[SINE, z0, a, k, phase]``: h = z0 + a sin(k x + phase), k = 2 pi / wavelength.

``height``, ``slope`` and ``curvature`` (model functions, ``legsim.heights``) give h, dh/dx and
d2h/dx2 at x (m, 1, 1/m) from the array and the offset ``at`` of its first entry (the terrain
sits in a model's parameter array). At a profile's breakpoint the slope is the right segment's;
a profile's curvature is 0 (a corner is where the slope jumps: a point at one takes the face it
moves onto, ``face_slope``, and one stuck in a notch both faces, ``notch``; ``docs/scenes.md``).

A scene's ``[terrain]`` table is validated into a ``Terrain`` by ``legsim.scene.terrain``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from .errors import SceneError
from .heights import FLAT, PROFILE, SINE, SLOPE, curvature, height, heights_along, nearest_along, slope, slopes_along

__all__ = ["FLAT", "PROFILE", "SINE", "SLOPE", "Terrain", "curvature", "height", "slope"]
#: The kinds a ``[terrain]`` table may name.
KINDS = ("flat", "slope", "steps", "profile", "sine")
#: Most breakpoints of a profile (points inline or from a CSV file, or twice the steps).
MAX_POINTS = 100_000


@dataclass(frozen=True)
class Terrain:
    """A validated terrain.

    Attributes
    ----------
    array: its encoding (module docstring), float64.
    description: one line naming the kind and its numbers (for summaries).
    """

    array: np.ndarray
    description: str

    @property
    def flat(self) -> bool:
        """Whether the terrain is level everywhere (a ``flat`` one)."""
        return bool(self.array[0] == FLAT)

    @property
    def uniform_grade(self) -> float | None:
        """The grade dh/dx where the ground's normal is the same everywhere (0 for a ``flat``
        terrain, g for a ``slope``); None where it turns (steps, profiles, sines)."""
        if self.flat:
            return 0.0
        return float(self.array[1]) if self.array[0] == SLOPE else None

    def height(self, x: Any) -> np.ndarray:
        """h at each x (m), shape of x."""
        return along(heights_along, self.array, x)

    def slope(self, x: Any) -> np.ndarray:
        """dh/dx at each x, shape of x (a profile's right segment's at a breakpoint)."""
        return along(slopes_along, self.array, x)

    @property
    def smooth(self) -> bool:
        """Whether the terrain's slope is continuous everywhere (no profile's or steps' corners)."""
        return corner_positions(self.array).size == 0

    def pieces(self, x: Any) -> np.ndarray:
        """Which smooth piece of the terrain lies under each x (``pieces_along``), shape of x."""
        return pieces_along(self.array, x)

    def highest(self, low: Any, high: Any) -> np.ndarray:
        """The highest h (m) over each [low, high] (m; arrays of one shape, low <= high): the
        higher end's, a profile's corners between them, a sine's crest."""
        lo, hi = np.asarray(low, dtype=float), np.asarray(high, dtype=float)
        if self.array[0] == SINE:
            return np.full(lo.shape, self.array[1] + abs(self.array[2]))
        ends = np.maximum(self.height(lo), self.height(hi))
        xs = corner_positions(self.array)
        if xs.size == 0:  # flat or a slope: a line, highest at an end
            return ends
        heights = np.append(self.array[2 + xs.size : 2 + 2 * xs.size], -np.inf)
        first, last = np.searchsorted(xs, lo.ravel(), side="left"), np.searchsorted(xs, hi.ravel(), side="right")
        # the corners first .. last - 1 lie in the range: each pair's reduceat is their highest
        between = np.maximum.reduceat(heights, np.column_stack([first, last]).ravel())[::2]
        return np.maximum(ends, np.where(last > first, between, -np.inf).reshape(lo.shape))

    def polyline(self, x_low: float, x_high: float, samples: int = 400) -> np.ndarray:
        """(k, 2) points (x, h(x)) over [x_low, x_high] (m) for drawing: a profile's breakpoints
        inside the range, a sine sampled ``samples`` times (more for a short wavelength), a line's
        two ends."""
        kind = self.array[0]
        if kind == PROFILE:
            n = int(self.array[1])
            xs = self.array[2 : 2 + n]
            inner = xs[(xs > x_low) & (xs < x_high)]
            grid = np.concatenate([[x_low], inner, [x_high]])
        elif kind == SINE:  # at least 32 points a wavelength, at most 20000 in all
            per_wave = 32.0 * (x_high - x_low) * self.array[3] / (2.0 * math.pi)
            grid = np.linspace(x_low, x_high, int(min(20_000, max(samples, math.ceil(per_wave) + 1))))
        else:
            grid = np.array([x_low, x_high])
        return np.column_stack([grid, self.height(grid)])


def nearest_points(array: np.ndarray, xz: np.ndarray) -> np.ndarray:
    """``legsim.heights.nearest``'s (s, d, g, k) for each point of xz (rows, 2) (m), (rows, 4), in
    one compiled call: the terrain's point nearest each, the distance, the slope there and the
    curvature of the level set through it."""
    points = np.ascontiguousarray(np.reshape(xz, (-1, 2)), dtype=float)
    out = np.empty((points.shape[0], 4))
    nearest_along(array, 0, np.ascontiguousarray(points[:, 0]), np.ascontiguousarray(points[:, 1]), out)
    return out


def top(array: np.ndarray | None) -> float:
    """The highest point (m) of the terrain encoded in ``array``: a flat ground's height, a
    sine's crest, a profile's highest breakpoint; +inf for a slope, and for None (level ground
    under each contact at its own height)."""
    if array is None or array[0] == SLOPE:
        return math.inf
    if array[0] == FLAT:
        return float(array[1])
    if array[0] == SINE:
        return float(array[1] + abs(array[2]))
    n = int(array[1])
    return float(np.max(array[2 + n : 2 + 2 * n]))


def along(function: Any, array: np.ndarray, x: Any) -> np.ndarray:
    """The terrain encoded in ``array`` read at each x in one compiled call, shape of x:
    ``function`` is ``heights_along`` (h, m) or ``slopes_along`` (dh/dx)."""
    xs = np.asarray(x, dtype=float)
    out = np.empty(xs.size)
    function(array, 0, np.ascontiguousarray(xs.reshape(-1)), out)
    return out.reshape(xs.shape)


def corner_positions(array: np.ndarray) -> np.ndarray:
    """The x (m) of the corners of the terrain encoded in ``array``, where its slope jumps: a
    profile's points; none for a smooth terrain (flat, slope, sine)."""
    if array[0] != PROFILE:
        return np.empty(0)
    return array[2 : 2 + int(array[1])]


def pieces_along(array: np.ndarray, x: Any) -> np.ndarray:
    """Which smooth piece of the terrain encoded in ``array`` lies under each x, shape of x: the
    number of its corners at or left of x (a corner belongs to the piece it starts, as its slope
    does; 0 everywhere on a smooth terrain). A height read under a point is as smooth as the
    point's motion while the point stays on one piece."""
    return np.searchsorted(corner_positions(array), np.asarray(x, dtype=float), side="right").astype(float)


def flat_terrain(h0: float = 0.0) -> Terrain:
    """The level ground z = h0 (m)."""
    return Terrain(np.array([FLAT, float(h0)]), f"flat at z = {h0:g} m")


def slope_terrain(angle: float, x0: float = 0.0, z0: float = 0.0) -> Terrain:
    """The plane through (x0, z0) rising at ``angle`` (rad, > 0 uphill towards +x)."""
    return Terrain(
        np.array([SLOPE, math.tan(angle), float(x0), float(z0)]),
        f"slope {math.degrees(angle):g} deg through ({x0:g}, {z0:g}) m",
    )


def profile_terrain(xs: Any, zs: Any, what: str = "profile") -> Terrain:
    """The piecewise-linear profile through (xs[i], zs[i]) (m; xs strictly increasing)."""
    x, z = np.asarray(xs, dtype=float), np.asarray(zs, dtype=float)
    return Terrain(np.concatenate([[PROFILE, len(x)], x, z]), f"{what} of {len(x)} points over [{x[0]:g}, {x[-1]:g}] m")


def steps_profile(positions: Any, heights: Any, base: float, riser: float) -> tuple[np.ndarray, np.ndarray]:
    """The profile of steps: the ground at ``base`` (m) left of positions[0], at heights[i] from
    positions[i] on, each riser a ramp of run ``riser`` (m) ending at its position."""
    xs, zs = [], []
    level = base
    for x, h in zip(positions, heights, strict=True):
        xs += [x - riser, x]
        zs += [level, h]
        level = h
    return np.array(xs, dtype=float), np.array(zs, dtype=float)


def sine_terrain(amplitude: float, wavelength: float, phase: float = 0.0, z0: float = 0.0) -> Terrain:
    """h = z0 + amplitude sin(2 pi x / wavelength + phase) (m, m, rad, m)."""
    return Terrain(
        np.array([SINE, float(z0), float(amplitude), 2.0 * math.pi / float(wavelength), float(phase)]),
        f"sine of amplitude {amplitude:g} m, wavelength {wavelength:g} m, phase {phase:g} rad about z = {z0:g} m",
    )


def downhill_degrees(terrain: Terrain, robot: str, low: float, high: float) -> float:
    """The angle (degrees) a terrain descends by towards +x, for a robot whose slope is built in
    (the compass gait's and rimless wheel's tilted frame): the terrain must be a ``slope``
    through the origin, descending by an angle in [low, high]; ``SceneError`` naming
    ``terrain`` otherwise."""
    a = terrain.array
    if a[0] != SLOPE:
        raise SceneError(
            f"terrain: robot '{robot}' walks on a uniform slope: give kind = 'slope', got {terrain.description}"
        )
    if a[3] != a[1] * a[2]:  # h(0) = z0 - g x0 must be 0: the walker's frame starts at the origin
        raise SceneError(f"terrain.through: robot '{robot}' needs the slope through (0, 0), got {terrain.description}")
    degrees = -math.degrees(math.atan(a[1]))
    if not low <= degrees <= high:
        raise SceneError(
            f"terrain.angle: robot '{robot}' walks down slopes of {low:g} to {high:g} degrees (angle "
            f"{-high:g} to {-low:g}: falling towards +x), got {terrain.description}"
        )
    return degrees


def walker_slope(slope: float, default: float, terrain: Terrain | None, robot: str, low: float, high: float) -> float:
    """The slope (degrees) of a walker whose slope is built in: its ``slope`` parameter, or a
    scene's ``[terrain]`` slope (``downhill_degrees``) in its place; ``SceneError`` when both
    are given."""
    if terrain is None:
        return slope
    if slope != default:
        raise SceneError("robot.parameters.slope: given besides a [terrain]: give the slope one way")
    return downhill_degrees(terrain, robot, low, high)


def slope_frame(slope_deg: float) -> np.ndarray:
    """The rotation (2, 2) from a slope's coordinates (x downhill, z normal) to the world's (z up)."""
    s = math.radians(slope_deg)
    return np.array([[math.cos(s), math.sin(s)], [-math.sin(s), math.cos(s)]])


# -- a scene's [terrain] table -------------------------------------------------------------------

#: The keys each kind takes, with what they allow (the error messages quote these).
