"""Reading a recording written by ``write_rrd`` back into numbers (``read_rrd``), without the
model: what ``legsim replay`` prints and draws."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from ..trace import Frames, RecordingError
from ..untrusted import check_list, check_object, load_json
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


#: The keys of ``legsim/meta`` and their JSON types (None: null).
META_KEYS = {"format": (str,), "summary": (dict,), "state_names": (dict,), "modes": (list,),
             "t0": (int, float), "t_end": (int, float), "parts": (list,), "point_parts": (list,),
             "scenery": (list,), "has_geometry": (bool,)}
NUMBER = (int, float)
MAYBE_NUMBER = (int, float, type(None))
MAYBE_TEXT = (str, type(None))
#: The run summary's keys that ``legsim replay`` prints, and their types.
SUMMARY_KEYS = {"status": (str,), "t_final": MAYBE_NUMBER, "final_mode": (str,), "final_state": (list,),
                "state_names": (list,), "mode_sequence": (list,), "transitions": (int,), "steps": (int,),
                "halvings": (int,), "field_evals": (int,), "guard_evals": (int,), "reset_evals": (int,),
                "wall_time_s": NUMBER}
SUMMARY_OPTIONAL = {"system": (str,), "message": MAYBE_TEXT, "scene": MAYBE_TEXT, "robot": MAYBE_TEXT,
                    "scene_file": MAYBE_TEXT, "method": MAYBE_TEXT, "h": MAYBE_NUMBER, "eps": MAYBE_NUMBER,
                    "final_in_strip": (bool,), "strip_time": MAYBE_NUMBER, "error_rejections": MAYBE_NUMBER,
                    "energy_initial": MAYBE_NUMBER, "energy_final": MAYBE_NUMBER, "outputs": (dict,)}


def _read_meta(path: Path, columns: Columns) -> dict[str, Any]:
    """The ``legsim/meta`` document, checked to be of this format, every key of its type."""
    meta_rows = columns.values("/legsim/meta", "TextDocument:text")
    if not meta_rows:
        raise RecordingError(f"{path}: a Rerun recording without legsim data (no legsim/meta entity); "
                             f"was it written by `legsim run --rrd`?")
    try:
        meta = load_json(meta_rows[0][0] if meta_rows[0] else None)
    except ValueError as exc:
        raise RecordingError(f"{path}: legsim/meta is not valid JSON: {exc}") from exc
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        found = meta.get("format") if isinstance(meta, dict) else meta
        raise RecordingError(f"{path}: unknown legsim recording format {found!r:.80} (expected {FORMAT})")
    try:
        return checked_meta(meta)
    except ValueError as exc:
        raise RecordingError(f"{path}: damaged legsim recording: {exc}") from None


def checked_meta(meta: dict[str, Any]) -> dict[str, Any]:
    """``meta`` when every key ``read_rrd`` and ``legsim replay`` use has its type (strings in
    the lists, numbers finite); ValueError naming the key otherwise."""
    check_object(meta, META_KEYS, "legsim/meta")
    for key in ("modes", "parts", "point_parts", "scenery"):
        check_list(meta[key], (str,), f"legsim/meta.{key}")
    for mode, names in meta["state_names"].items():
        check_list(names, (str,), f"legsim/meta.state_names.{mode}")
    summary = check_object(meta["summary"], SUMMARY_KEYS, "summary", optional=SUMMARY_OPTIONAL)
    for key in ("state_names", "mode_sequence"):
        check_list(summary[key], (str,), f"summary.{key}")
    check_list(summary["final_state"], MAYBE_NUMBER, "summary.final_state")
    for key, value in summary.items():
        # Other keys are the model's counters, printed as numbers when they are numbers.
        if key not in SUMMARY_KEYS and key not in SUMMARY_OPTIONAL and isinstance(value, (int, float)):
            check_object({key: value}, {key: (int, float, bool)}, "summary")
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
    _ordered_times(times, "samples/t")
    if not np.all((in_strip == 0) | (in_strip == 1)):
        raise ValueError("strip/active holds values other than 0 and 1")
    series, series_rows = _series(columns, times)
    mode_sequence = columns.strings("/mode", "TextLog:text")
    _, t_start = columns.numbers("/mode", "t_start")
    _, t_end = columns.numbers("/mode", "t_end")
    _ordered_times(np.column_stack([t_start, t_end]).ravel() if len(t_start) == len(t_end) else t_start, "mode")
    scenery = _scenery(columns, meta)
    return {
        "summary": meta["summary"],
        "meta": meta,
        "times": times,
        "modes": [meta["modes"][i] for i in _indices(mode_idx, len(meta["modes"]), "mode/index")],
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


def _ordered_times(times: np.ndarray, entity: str) -> None:
    """ValueError unless ``times`` are finite and in order."""
    if not np.all(np.isfinite(times)) or np.any(np.diff(times) < 0):
        raise ValueError(f"{entity} holds times that are not finite or not in order")


def _indices(values: np.ndarray, n: int, entity: str) -> list[int]:
    """``values`` (floats as read) as indices into a list of ``n``: whole numbers in [0, n),
    since a negative index would silently name another entry."""
    ok = np.isfinite(values) & (values == np.round(values)) & (values >= 0) & (values < n)
    if not np.all(ok):
        raise ValueError(f"{entity} holds {values[~ok][0]!r}, not an index into the {n} entries")
    return values.astype(np.int64).tolist()


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
    _ordered_times(entry, "events/strips")
    return [{"mode": m, "name": n, "time": float(a), "exit_time": float(b)}
            for m, n, a, b in zip(columns.strings(ev, "mode"), columns.strings(ev, "name"), entry, exit_, strict=True)]


def _transitions(columns: Columns) -> list[dict[str, Any]]:
    """The rows of ``events/transitions``, with the states before and after the reset."""
    ev = "/events/transitions"
    text = {f: columns.strings(ev, f) for f in ("name", "source", "target")}
    nums = {f: columns.numbers(ev, f)[1] for f in ("index", "time", "landing_time", "exit_time", "depth")}
    before = columns.arrays(ev, "state_before")
    after = columns.arrays(ev, "state_after")
    _indices(nums["index"], 2 ** 31, "events/transitions:index")
    for field in ("time", "landing_time", "exit_time", "depth"):
        if not np.all(np.isfinite(nums[field])):
            raise ValueError(f"events/transitions:{field} holds values that are not finite")
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
    _ordered_times(f_times, "frames/t")
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
