"""Reading a recording written by ``write_rrd`` back into numbers (``read_rrd``), without the
model: what ``legsim replay`` prints and draws."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from ..trace import Frames, RecordingError
from .columns import Columns, read_columns
from .layout import FORMAT


def read_rrd(path: str | os.PathLike) -> dict[str, Any]:
    """Load a recording written by ``write_rrd`` with Rerun's reader (``rerun.chunk.RrdReader``).

    Returns a dict:

    * ``summary``: the run summary (keys of ``legsim run --json``); ``meta``: the whole
      ``legsim/meta`` document (state names per mode, mode list, part names, scene path).
    * ``times`` (N,), ``modes`` (N names), ``in_strip`` (N,) bool: the recorded samples.
    * ``series``: coordinate name -> (times (M,), values (M,)) for the samples whose mode has it;
      ``series_rows``: name -> the sample indices (M,) of those values.
    * ``mode_sequence``: the mode of every segment, in order; ``segments``: (mode, t_start,
      t_end) of every segment (s).
    * ``strips``: list of dicts (mode, name, time, exit_time).
    * ``transitions``: list of dicts (name, source, target, index, time, landing_time,
      exit_time, depth, state_before, state_after arrays).
    * ``frames``: a ``Frames`` (geometry, float32 precision) or None; ``scenery``: part -> (k, 2).

    Raises RecordingError naming the file when it is missing, not a Rerun file, or not written
    by legsim.
    """
    path = Path(path)
    if not path.is_file():
        raise RecordingError(f"{path}: no such recording file")
    columns = read_columns(path)
    meta = _read_meta(path, columns)
    try:
        return _assemble(columns, meta)
    except (KeyError, IndexError, ValueError, TypeError) as exc:
        raise RecordingError(f"{path}: incomplete or damaged legsim recording ({type(exc).__name__}: {exc})") from exc


def _read_meta(path: Path, columns: Columns) -> dict[str, Any]:
    """The ``legsim/meta`` document, checked to be of this format."""
    meta_rows = columns.values("/legsim/meta", "TextDocument:text")
    if not meta_rows:
        raise RecordingError(f"{path}: a Rerun recording without legsim data (no legsim/meta entity); "
                             f"was it written by `legsim run --rrd`?")
    try:
        meta = json.loads(meta_rows[0][0])
    except (ValueError, IndexError, TypeError) as exc:
        raise RecordingError(f"{path}: legsim/meta is not valid JSON: {exc}") from exc
    if meta.get("format") != FORMAT:
        raise RecordingError(f"{path}: unknown legsim recording format {meta.get('format')!r} (expected {FORMAT})")
    return meta


def _assemble(columns: Columns, meta: dict[str, Any]) -> dict[str, Any]:
    """The dict ``read_rrd`` returns; KeyError, IndexError or ValueError when parts are missing."""
    idx, times = columns.numbers("/samples/t")
    if not np.array_equal(idx, np.arange(len(idx))):
        raise ValueError("sample rows are not contiguous")
    _, in_strip = columns.numbers("/strip/active")
    _, mode_idx = columns.numbers("/mode/index")
    if not (len(in_strip) == len(mode_idx) == len(times)):
        raise ValueError("sample columns differ in length")
    series, series_rows = _series(columns, times)
    mode_sequence = columns.strings("/mode", "TextLog:text")
    _, t_start = columns.numbers("/mode", "t_start")
    _, t_end = columns.numbers("/mode", "t_end")
    scenery = _scenery(columns, meta)
    return {
        "summary": meta["summary"],
        "meta": meta,
        "times": times,
        "modes": [meta["modes"][i] for i in mode_idx.astype(np.int64)],
        "in_strip": in_strip.astype(bool),
        "series": series,
        "series_rows": series_rows,
        "mode_sequence": mode_sequence,
        "segments": [(m, float(a), float(b)) for m, a, b in zip(mode_sequence, t_start, t_end, strict=True)],
        "strips": _strips(columns),
        "transitions": _transitions(columns),
        "frames": _frames(columns, meta, scenery) if meta.get("has_geometry") else None,
        "scenery": scenery,
    }


def _series(columns: Columns, times: np.ndarray) -> tuple[dict[str, tuple[np.ndarray, np.ndarray]],
                                                           dict[str, np.ndarray]]:
    """name -> (times, values) and name -> sample rows of every ``state/<name>`` entity."""
    series: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    series_rows: dict[str, np.ndarray] = {}
    for entity in columns.entities():
        if entity.startswith("/state/"):
            rows, vals = columns.numbers(entity)
            if len(rows):
                name = entity[len("/state/"):]
                series[name] = (times[rows], vals)
                series_rows[name] = rows
    return series, series_rows


def _strips(columns: Columns) -> list[dict[str, Any]]:
    """The rows of ``events/strips``: mode, name, time (entry) and exit_time (s)."""
    ev = "/events/strips"
    _, entry = columns.numbers(ev, "entry")
    _, exit_ = columns.numbers(ev, "exit")
    return [{"mode": m, "name": n, "time": float(a), "exit_time": float(b)}
            for m, n, a, b in zip(columns.strings(ev, "mode"), columns.strings(ev, "name"), entry, exit_, strict=True)]


def _transitions(columns: Columns) -> list[dict[str, Any]]:
    """The rows of ``events/transitions``, with the states before and after the reset."""
    ev = "/events/transitions"
    text = {f: columns.strings(ev, f) for f in ("name", "source", "target")}
    nums = {f: columns.numbers(ev, f)[1] for f in ("index", "time", "landing_time", "exit_time", "depth")}
    before = columns.arrays(ev, "state_before")
    after = columns.arrays(ev, "state_after")
    return [{
        "name": text["name"][k], "source": text["source"][k], "target": text["target"][k],
        "index": int(nums["index"][k]), "time": float(nums["time"][k]),
        "landing_time": float(nums["landing_time"][k]), "exit_time": float(nums["exit_time"][k]),
        "depth": float(nums["depth"][k]),
        "state_before": before[k], "state_after": after[k],
    } for k in range(len(text["name"]))]


def _xz(points: list) -> np.ndarray:
    """Recorded 3D points (x, 0, z) back as (k, 2) points (x, z)."""
    return np.array(points, dtype=float)[:, [0, 2]].reshape(-1, 2)


def _scenery(columns: Columns, meta: dict[str, Any]) -> dict[str, np.ndarray]:
    scenery = {}
    for part in meta.get("scenery", []):
        rows = columns.values(f"/scenery/{part}", "LineStrips3D:strips")
        if rows and rows[0]:
            scenery[part] = _xz(rows[0][0])
    return scenery


def _frames(columns: Columns, meta: dict[str, Any], scenery: dict[str, np.ndarray]) -> Frames:
    """The robot's polylines per frame (float32 precision; None where a part is absent)."""
    _, f_times = columns.numbers("/frames/t")
    f_modes = columns.strings("/frames/mode", "TextLog:text")
    point_parts = set(meta.get("point_parts", []))
    parts: dict[str, list[np.ndarray | None]] = {}
    for part in meta.get("parts", []):
        lines: list[np.ndarray | None] = [None] * len(f_times)
        if part in point_parts:
            for i, points in columns.rows(f"/robot/{part}", "Points3D:positions"):
                if 0 <= i < len(lines) and points:
                    lines[i] = _xz(points)
        else:
            for i, strips_row in columns.rows(f"/robot/{part}", "LineStrips3D:strips"):
                if 0 <= i < len(lines) and strips_row and len(strips_row[0]):
                    lines[i] = _xz(strips_row[0])
        parts[part] = lines
    return Frames(f_times, f_modes, parts, scenery)
