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
a profile's curvature is 0 (a corner is where the slope jumps: a point resting on the profile
that slides across one is not resolved there, see ``docs/scenes.md``).

``parse_terrain`` validates a scene's ``[terrain]`` table into a ``Terrain``.
"""

from __future__ import annotations

import csv
import io
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .errors import SceneError
from .heights import FLAT, PROFILE, SINE, SLOPE, curvature, height, slope

__all__ = ["FLAT", "PROFILE", "SINE", "SLOPE", "Terrain", "curvature", "height", "parse_terrain", "slope"]
#: The kinds a ``[terrain]`` table may name.
KINDS = ("flat", "slope", "steps", "profile", "sine")
#: Most breakpoints of a profile (points inline or from a CSV file, or twice the steps).
MAX_POINTS = 100_000
#: Largest profile CSV file read (bytes).
MAX_CSV_BYTES = 8 << 20


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
        xs = np.asarray(x, dtype=float)
        return np.vectorize(lambda v: height(self.array, 0, float(v)), otypes=[float])(xs)

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
KEYS: dict[str, dict[str, str]] = {
    "flat": {"height": "a finite number (m), default 0"},
    "slope": {
        "angle": "a finite number of degrees in (-60, 60), > 0 rising towards +x (or give grade)",
        "grade": "a finite number dz/dx in (-1.7, 1.7) (or give angle)",
        "through": "an array [x, z] of two finite numbers (m), default [0, 0]",
    },
    "steps": {
        "positions": "an array of finite x (m), strictly increasing: where each step begins",
        "heights": "an array of finite z (m), one per position: each step's tread height (or give rise)",
        "rise": "a finite number (m): each tread this much above the one before, the first above base "
        "(or give heights)",
        "base": "a finite number (m): the ground left of the first step, default 0",
        "riser": "a finite number (m) > 0: the run of each riser ramp, default 0.001, below the shortest tread",
    },
    "profile": {
        "points": "an array of [x, z] pairs (m), x strictly increasing, at least 2 (or give file)",
        "file": "a CSV file of x,z rows (m) in the scene's folder (or give points)",
    },
    "sine": {
        "amplitude": "a finite number (m) >= 0",
        "wavelength": "a finite number (m) > 0",
        "phase": "a finite number (rad), default 0",
        "height": "a finite number (m): the mean height, default 0",
    },
}


class _Fields:
    """Reads the fields of a ``[terrain]`` table, each error naming file, field and what is allowed."""

    def __init__(self, path: Path, table: Mapping[str, Any], kind: str) -> None:
        self.path, self.table, self.kind = path, table, kind

    def error(self, key: str, message: str) -> SceneError:
        return SceneError(f"{self.path}: terrain.{key}: {message}; allowed: {KEYS[self.kind].get(key, '')}")

    def number(self, key: str, default: float | None = None) -> float:
        value = self.table.get(key, default)
        if value is None:
            raise self.error(key, f"missing (terrain kind '{self.kind}')")
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise self.error(key, f"got {value!r}")
        return float(value)

    def numbers(self, key: str) -> np.ndarray:
        value = self.table.get(key)
        if value is None:
            raise self.error(key, f"missing (terrain kind '{self.kind}')")
        if not isinstance(value, list) or not value or len(value) > MAX_POINTS:
            raise self.error(key, f"expected a non-empty array of at most {MAX_POINTS} numbers, got {value!r:.80}")
        for i, v in enumerate(value):
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise self.error(f"{key}[{i}]", f"got {v!r}")
        return np.array(value, dtype=float)


def parse_terrain(path: Path, table: Mapping[str, Any]) -> Terrain:
    """The terrain of scene ``path``'s ``[terrain]`` table; ``SceneError`` naming the file, the
    field and the allowed values for anything wrong (a profile file is read relative to the
    scene's folder, and must lie inside it)."""
    kind = table.get("kind")
    if kind not in KINDS:
        raise SceneError(f"{path}: terrain.kind: got {kind!r}; allowed: one of {list(KINDS)}")
    unknown = sorted(set(table) - set(KEYS[kind]) - {"kind"})
    if unknown:
        raise SceneError(
            f"{path}: terrain: unknown key(s) {unknown} for kind '{kind}'; allowed: {['kind', *KEYS[kind]]}"
        )
    f = _Fields(path, table, kind)
    if kind == "flat":
        return flat_terrain(f.number("height", 0.0))
    if kind == "slope":
        return _slope(f)
    if kind == "sine":
        return _sine(f)
    if kind == "steps":
        return _steps(f)
    return _profile(f)


def _slope(f: _Fields) -> Terrain:
    if ("angle" in f.table) == ("grade" in f.table):
        raise f.error("angle", "give exactly one of angle and grade")
    if "angle" in f.table:
        degrees = f.number("angle")
        if not -60.0 < degrees < 60.0:
            raise f.error("angle", f"{degrees:g} is out of range")
        angle = math.radians(degrees)
    else:
        grade = f.number("grade")
        if not -1.7 < grade < 1.7:
            raise f.error("grade", f"{grade:g} is out of range")
        angle = math.atan(grade)
    through = f.table.get("through", [0.0, 0.0])
    if (
        not isinstance(through, list)
        or len(through) != 2
        or not all(not isinstance(v, bool) and isinstance(v, (int, float)) and math.isfinite(v) for v in through)
    ):
        raise f.error("through", f"got {through!r}")
    terrain = slope_terrain(angle, float(through[0]), float(through[1]))
    if "grade" in f.table:  # keep the grade as given, not tan(atan(grade))
        terrain.array[1] = f.number("grade")
    return terrain


def _sine(f: _Fields) -> Terrain:
    amplitude, wavelength = f.number("amplitude"), f.number("wavelength")
    if amplitude < 0.0:
        raise f.error("amplitude", f"{amplitude:g} is out of range")
    if wavelength <= 0.0:
        raise f.error("wavelength", f"{wavelength:g} is out of range")
    return sine_terrain(amplitude, wavelength, f.number("phase", 0.0), f.number("height", 0.0))


def _steps(f: _Fields) -> Terrain:
    positions = f.numbers("positions")
    if ("heights" in f.table) == ("rise" in f.table):
        raise f.error("heights", "give exactly one of heights and rise")
    base = f.number("base", 0.0)
    # A staircase of equal risers is one number, ``rise``, so that a sweep can vary the step height.
    rise = f.number("rise") if "rise" in f.table else None
    heights = f.numbers("heights") if rise is None else base + rise * np.arange(1, len(positions) + 1)
    if len(heights) != len(positions):
        raise f.error("heights", f"{len(heights)} heights for {len(positions)} positions")
    if np.any(np.diff(positions) <= 0.0):
        raise f.error("positions", f"not strictly increasing: {positions.tolist()!r:.80}")
    riser = f.number("riser", 1e-3)
    shortest = float(np.min(np.diff(positions))) if len(positions) > 1 else math.inf
    if not 0.0 < riser < shortest:
        raise f.error("riser", f"{riser:g} is out of range (the shortest tread is {shortest:g} m)")
    xs, zs = steps_profile(positions, heights, base, riser)
    terrain = profile_terrain(xs, zs, "steps")
    return Terrain(terrain.array, f"{len(positions)} steps from x = {positions[0]:g} m (risers {riser:g} m wide)")


def _profile(f: _Fields) -> Terrain:
    if ("points" in f.table) == ("file" in f.table):
        raise f.error("points", "give exactly one of points and file")
    if "file" in f.table:
        rows, where = _csv_rows(f), "file"
    else:
        points = f.table["points"]
        if not isinstance(points, list) or len(points) > MAX_POINTS:
            raise f.error("points", f"expected an array of at most {MAX_POINTS} [x, z] pairs, got {points!r:.80}")
        rows, where = points, "points"
    xs, zs = _checked_points(f, rows, where)
    return profile_terrain(xs, zs)


def _csv_rows(f: _Fields) -> list[Any]:
    """The rows of the profile's CSV file, numbers parsed; errors name the file's line."""
    from .scene.files import inside_folder, read_input_file

    value = f.table["file"]
    if not isinstance(value, str) or not value or "\x00" in value:
        raise f.error("file", f"got {value!r}")
    file = inside_folder(f.path.parent, os.path.expanduser(value))
    if file is None:
        raise f.error("file", f"{value!r} lies outside the scene's folder {f.path.parent} (links resolved)")
    raw = read_input_file(file, MAX_CSV_BYTES, "terrain profile CSV file")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise f.error("file", f"{file}: not UTF-8 text") from None
    rows: list[Any] = []
    for line, record in enumerate(csv.reader(io.StringIO(text)), start=1):
        if not record or record[0].strip().startswith("#"):
            continue
        try:
            rows.append([float(v) for v in record])
        except ValueError:
            if not rows and line == 1:  # a header line
                continue
            raise f.error("file", f"{file}: line {line}: expected two numbers x,z, got {record!r:.80}") from None
        if len(rows) > MAX_POINTS:
            raise f.error("file", f"{file}: more than {MAX_POINTS} points")
    return rows


def _checked_points(f: _Fields, rows: list[Any], where: str) -> tuple[np.ndarray, np.ndarray]:
    """x and z of a profile's rows: pairs of finite numbers, at least 2, x strictly increasing."""
    for i, row in enumerate(rows):
        ok = (
            isinstance(row, list)
            and len(row) == 2
            and all(not isinstance(v, bool) and isinstance(v, (int, float)) and math.isfinite(v) for v in row)
        )
        if not ok:
            raise f.error(where, f"point {i}: expected [x, z], two finite numbers, got {row!r:.80}")
    if len(rows) < 2:
        raise f.error(where, f"{len(rows)} point(s): a profile needs at least 2")
    pts = np.array(rows, dtype=float)
    bad = np.nonzero(np.diff(pts[:, 0]) <= 0.0)[0]
    if len(bad):
        i = int(bad[0]) + 1
        raise f.error(where, f"x not strictly increasing at point {i}: {pts[i - 1, 0]:g} then {pts[i, 0]:g}")
    return pts[:, 0].copy(), pts[:, 1].copy()
