"""A scene's ``[terrain]`` table (``docs/scenes.md``) validated into a ``legsim.terrain.Terrain``:
every error names the scene's file, the field and the values allowed."""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import SceneError
from ..terrain import (
    KINDS,
    MAX_POINTS,
    Terrain,
    flat_terrain,
    profile_terrain,
    sine_terrain,
    slope_terrain,
    steps_profile,
)
from .files import inside_folder, read_input_file

#: Largest profile CSV file read (bytes).
MAX_CSV_BYTES = 8 << 20

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
        rows, labels, where = *_csv_rows(f), "file"
    else:
        points = f.table["points"]
        if not isinstance(points, list) or len(points) > MAX_POINTS:
            raise f.error("points", f"expected an array of at most {MAX_POINTS} [x, z] pairs, got {points!r:.80}")
        rows, labels, where = points, [f"point {i}" for i in range(len(points))], "points"
    xs, zs = _checked_points(f, rows, labels, where)
    return profile_terrain(xs, zs)


def profile_file(scene: Path, value: str) -> Path | None:
    """The profile's CSV file a ``[terrain] file`` names, resolved against the scene's folder;
    None when it leads out of that folder (links resolved)."""
    return inside_folder(scene.parent, os.path.expanduser(value))


def _csv_rows(f: _Fields) -> tuple[list[Any], list[str]]:
    """The rows of the profile's CSV file, numbers parsed, and each one's label (file and line)
    for the errors."""
    value = f.table["file"]
    if not isinstance(value, str) or not value or "\x00" in value:
        raise f.error("file", f"got {value!r}")
    file = profile_file(f.path, value)
    if file is None:
        raise f.error("file", f"{value!r} lies outside the scene's folder {f.path.parent} (links resolved)")
    try:
        raw = read_input_file(file, MAX_CSV_BYTES, "terrain profile CSV file")
    except SceneError as exc:
        raise f.error("file", str(exc)) from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise f.error("file", f"{file}: not UTF-8 text") from None
    rows: list[Any] = []
    labels: list[str] = []
    header_allowed = True
    for line, content in enumerate(text.splitlines(), start=1):
        content = content.split("#", 1)[0]  # a comment, whole-line or after the numbers
        record = next(csv.reader([content]), [])
        if not any(v.strip() for v in record):
            continue
        if header_allowed and not any(_is_number(v) for v in record):  # the first line, all names
            header_allowed = False
            continue
        header_allowed = False
        labels.append(f"{file}: line {line}")
        rows.append(_csv_numbers(f, labels[-1], record))
        if len(rows) > MAX_POINTS:
            raise f.error("file", f"{file}: more than {MAX_POINTS} points")
    return rows, labels


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _csv_numbers(f: _Fields, label: str, record: list[str]) -> list[float]:
    """A CSV line's two numbers (``_checked_points`` checks them as points)."""
    try:
        point = [float(v) for v in record]
    except ValueError:
        raise f.error("file", f"{label}: expected two numbers x,z, got {record!r:.80}") from None
    if len(point) != 2:
        raise f.error("file", f"{label}: expected two numbers x,z, got {len(record)}: {record!r:.80}")
    return point


def _checked_points(f: _Fields, rows: list[Any], labels: list[str], where: str) -> tuple[np.ndarray, np.ndarray]:
    """x and z of a profile's rows: pairs of finite numbers, at least 2, x strictly increasing;
    errors name the field ``where`` and the row's label (``point 3``, or a CSV file's line)."""
    for label, row in zip(labels, rows, strict=True):
        ok = (
            isinstance(row, list)
            and len(row) == 2
            and all(not isinstance(v, bool) and isinstance(v, (int, float)) and math.isfinite(v) for v in row)
        )
        if not ok:
            raise f.error(where, f"{label}: expected two finite numbers x,z, got {row!r:.80}")
    if len(rows) < 2:
        raise f.error(where, f"{len(rows)} point(s): a profile needs at least 2")
    pts = np.array(rows, dtype=float)
    bad = np.nonzero(np.diff(pts[:, 0]) <= 0.0)[0]
    if len(bad):
        i = int(bad[0]) + 1
        raise f.error(where, f"{labels[i]}: x not strictly increasing: {pts[i - 1, 0]:g} then {pts[i, 0]:g}")
    return pts[:, 0].copy(), pts[:, 1].copy()
