"""Reading a recording written by ``write_rrd`` back into numbers (``read_rrd``), without the
model: what ``legsim replay`` prints and draws."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from ..files import input_size
from ..trace import RecordingError
from ..untrusted import check_list, check_object, load_json
from .columns import Columns, read_columns
from .digest import check_file, ends_with_footer, verify
from .frames import frames
from .layout import DIGEST, FORMAT, META, MODE, OLD_FORMATS, SAMPLES, SCENERY, STATE, STRIPS, TRANSITIONS, entity


def read_rrd(path: str | os.PathLike) -> dict[str, Any]:
    """Load a recording written by ``write_rrd`` with Rerun's reader (``rerun.chunk.RrdReader``).

    Returns a dict:

    * ``summary``: the run summary (keys of ``legsim run --json``); ``meta``: the whole
      ``legsim/meta`` document (state names and units per mode, mode list, part names, scene
      path, the rate the samples were thinned to or null).
    * ``times`` (N,), ``modes`` (N names), ``in_strip`` (N,) bool: the recorded samples (all
      the run computed, or with a rate the kept ones).
    * ``series``: coordinate name -> (times (M,), values (M,)) for the samples whose mode has it;
      ``series_rows``: name -> the sample indices (M,) of those values.
    * ``mode_sequence``: the mode of every segment, in order; ``segments``: (mode, t_start,
      t_end) of every segment (s).
    * ``strips``: list of dicts (mode, name, time, exit_time).
    * ``transitions``: list of dicts (name, source, target, index, time, landing_time,
      exit_time, depth, state_before, state_after arrays).
    * ``frames``: a ``Frames`` (the robot at a selection of the samples, float32 precision:
      ``legsim.output.rrd.frames``) or None, ``frame_rows`` the samples they show (or None);
      ``scenery``: part -> (k, 2).

    * ``verified``: True when the recording holds the digest of what legsim logged
      (``legsim.output.rrd.digest``) and every component matches it; False for a recording
      without one (written before legsim stored it).

    Raises RecordingError naming the file when it is missing, not a Rerun file, not written
    by legsim, written in an earlier layout (naming it), or damaged: a component that no longer
    matches the digest written with it.
    """
    path = Path(path)
    input_size(path, "recording file", RecordingError)
    try:
        # Before Rerun decodes anything: its reader aborts the process on some damaged files.
        sealed = check_file(path)
    except ValueError as exc:
        raise RecordingError(f"{path}: damaged legsim recording: {exc}") from None
    except OSError as exc:
        raise RecordingError(f"{path}: cannot read the recording: {exc.strerror or exc}") from None
    columns = read_columns(path, sealed)
    verified = _verify(path, columns)
    meta = _read_meta(path, columns)
    try:
        return {**_assemble(columns, meta), "verified": verified}
    except (KeyError, IndexError, ValueError, TypeError) as exc:
        raise RecordingError(f"{path}: incomplete or damaged legsim recording ({type(exc).__name__}: {exc})") from exc


def _verify(path: Path, columns: Columns) -> bool:
    """Whether the recording's components match the digest stored with them (False without a
    digest); RecordingError naming the first one that does not."""
    rows = columns.values(DIGEST, "TextDocument:text")
    if not rows:
        return False
    try:
        problem = verify(columns, rows[0][0] if rows[0] else None)
    except (ValueError, TypeError) as exc:
        raise RecordingError(f"{path}: damaged legsim recording: its digest is unreadable: {exc}") from None
    if problem is not None:
        raise RecordingError(
            f"{path}: damaged legsim recording: {problem} (the digest legsim stored with the data no longer matches)"
        )
    return True


#: The keys of ``legsim/meta`` and their JSON types (None: null).
META_KEYS = {
    "format": (str,),
    "summary": (dict,),
    "state_names": (dict,),
    "state_units": (dict,),
    "modes": (list,),
    "t0": (int, float),
    "t_end": (int, float),
    "parts": (list,),
    "point_parts": (list,),
    "scenery": (list,),
    "has_geometry": (bool,),
    "rate": (int, float, type(None)),
    "computed_samples": (int,),
    "samples": (int,),
}
NUMBER = (int, float)
MAYBE_NUMBER = (int, float, type(None))
MAYBE_TEXT = (str, type(None))
#: The run summary's keys that ``legsim replay`` prints, and their types.
SUMMARY_KEYS = {
    "status": (str,),
    "t_final": MAYBE_NUMBER,
    "final_mode": (str,),
    "final_state": (list,),
    "state_names": (list,),
    "mode_sequence": (list,),
    "transitions": (int,),
    "steps": (int,),
    "halvings": (int,),
    "field_evals": (int,),
    "guard_evals": (int,),
    "reset_evals": (int,),
    "wall_time_s": NUMBER,
}
SUMMARY_OPTIONAL = {
    "system": (str,),
    "message": MAYBE_TEXT,
    "scene": MAYBE_TEXT,
    "robot": MAYBE_TEXT,
    "scene_file": MAYBE_TEXT,
    "method": MAYBE_TEXT,
    "h": MAYBE_NUMBER,
    "eps": MAYBE_NUMBER,
    "final_in_strip": (bool,),
    "strip_time": MAYBE_NUMBER,
    "error_rejections": MAYBE_NUMBER,
    "energy_initial": MAYBE_NUMBER,
    "energy_final": MAYBE_NUMBER,
    "outputs": (dict,),
    "longest_strip_hold": MAYBE_NUMBER,
    "warnings": (list,),
}


def _read_meta(path: Path, columns: Columns) -> dict[str, Any]:
    """The ``legsim/meta`` document, checked to be of this format, every key of its type."""
    meta_rows = columns.values(META, "TextDocument:text")
    if not meta_rows:
        if not ends_with_footer(path):  # cut short: the data may have been in the part that is lost
            raise RecordingError(
                f"{path}: a Rerun recording cut short (it has no footer) without legsim data in what remains; "
                f"was it copied or written completely?"
            )
        raise RecordingError(
            f"{path}: a Rerun recording without legsim data (no legsim/meta entity); "
            f"was it written by `legsim run --rrd`?"
        )
    if not meta_rows[0]:
        raise RecordingError(f"{path}: legsim/meta is an empty document; was it written by `legsim run --rrd`?")
    try:
        meta = load_json(meta_rows[0][0])
    except ValueError as exc:
        raise RecordingError(f"{path}: legsim/meta is not valid JSON: {exc}") from exc
    found = meta.get("format") if isinstance(meta, dict) else meta
    if isinstance(found, str) and found in OLD_FORMATS:
        raise RecordingError(
            f"{path}: a legsim recording of layout {found}, written by an earlier legsim; this "
            f"version reads layout {FORMAT} only: record the run again (`legsim run SCENE --rrd "
            f"FILE`)"
        )
    if not isinstance(meta, dict) or found != FORMAT:
        raise RecordingError(f"{path}: unknown legsim recording format {found!r:.80} (expected {FORMAT})")
    try:
        return checked_meta(meta)
    except ValueError as exc:
        raise RecordingError(f"{path}: damaged legsim recording: {exc}") from None


def checked_meta(meta: dict[str, Any]) -> dict[str, Any]:
    """``meta`` when every key ``read_rrd`` and ``legsim replay`` use has its type (strings in
    the lists, numbers finite); ValueError naming the key otherwise."""
    check_object(meta, META_KEYS, "legsim/meta", optional={"urdf": (dict, type(None))})
    for key in ("modes", "parts", "point_parts", "scenery"):
        check_list(meta[key], (str,), f"legsim/meta.{key}")
    for key in ("state_names", "state_units"):
        for mode, names in meta[key].items():
            check_list(names, (str,), f"legsim/meta.{key}.{mode}")
    summary = check_object(meta["summary"], SUMMARY_KEYS, "summary", optional=SUMMARY_OPTIONAL)
    for key in ("state_names", "mode_sequence"):
        check_list(summary[key], (str,), f"summary.{key}")
    check_list(summary["final_state"], MAYBE_NUMBER, "summary.final_state")
    for k, warning in enumerate(summary.get("warnings", [])):
        check_object(warning, {"message": (str,)}, f"summary.warnings[{k}]")
    for key, value in summary.items():
        # Other keys are the model's counters, printed as numbers when they are numbers.
        if key not in SUMMARY_KEYS and key not in SUMMARY_OPTIONAL and isinstance(value, (int, float)):
            check_object({key: value}, {key: (int, float, bool)}, "summary")
    return meta


def _assemble(columns: Columns, meta: dict[str, Any]) -> dict[str, Any]:
    """The dict ``read_rrd`` returns; KeyError, IndexError or ValueError when parts are missing."""
    idx, times = columns.numbers(SAMPLES, "t")
    if not len(idx) or not np.array_equal(idx, np.arange(len(idx))):
        raise ValueError("sample rows are missing or not contiguous")
    _ordered_times(times, "legsim/samples")
    series, series_rows = _series(columns, meta, times)
    starts, t_start = columns.numbers(MODE, "t_start")
    _, t_end = columns.numbers(MODE, "t_end")
    mode_sequence = columns.strings(MODE, "StateChange:state")
    _ordered_times(np.column_stack([t_start, t_end]).ravel() if len(t_start) == len(t_end) else t_start, "mode")
    strips = _strips(columns, len(times))
    scenery = _scenery(columns, meta)
    drawn = meta.get("has_geometry") or meta.get("urdf")
    robot, robot_rows = frames(columns, meta, times, strips, scenery) if drawn else (None, None)
    return {
        "summary": meta["summary"],
        "meta": meta,
        "times": times,
        "modes": _sample_modes(starts, mode_sequence, meta["modes"], len(times)),
        "in_strip": _in_strip(strips, len(times)),
        "series": series,
        "series_rows": series_rows,
        "mode_sequence": mode_sequence,
        "segments": [(m, float(a), float(b)) for m, a, b in zip(mode_sequence, t_start, t_end, strict=True)],
        "strips": [{k: v for k, v in s.items() if k != "row"} for s in strips],
        "transitions": _transitions(columns),
        "frames": robot,
        "frame_rows": robot_rows,
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


def _series(
    columns: Columns, meta: dict[str, Any], times: np.ndarray
) -> tuple[dict[str, tuple[np.ndarray, np.ndarray]], dict[str, np.ndarray]]:
    """name -> (times, values) and name -> sample rows of every coordinate of ``meta``."""
    series: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    series_rows: dict[str, np.ndarray] = {}
    names = dict.fromkeys(name for names in meta["state_names"].values() for name in names)
    for name in names:
        rows, vals = columns.numbers(entity(STATE, name))
        if len(rows):
            _indices(rows, len(times), f"state/{name} rows")
            series[name] = (times[rows], vals)
            series_rows[name] = rows
    return series, series_rows


def _sample_modes(starts: np.ndarray, sequence: list[str], modes: list[str], n: int) -> list[str]:
    """The mode of every sample: that of the last segment that starts at or before it."""
    _indices(starts, n, "mode rows")
    if len(starts) != len(sequence) or not len(starts) or starts[0] != 0 or np.any(np.diff(starts) <= 0):
        raise ValueError("mode rows do not start each segment in order from the first sample")
    unknown = set(sequence) - set(modes)
    if unknown:
        raise ValueError(f"mode names a mode not in legsim/meta.modes: {sorted(unknown)[0]!r:.80}")
    lengths = np.diff(np.concatenate([starts, [n]])).astype(np.int64)
    return [mode for mode, count in zip(sequence, lengths.tolist(), strict=False) for _ in range(count)]


def _in_strip(strips: list[dict[str, Any]], n: int) -> np.ndarray:
    """True for the two samples (entry and exit, state held at q) of every strip."""
    flags = np.zeros(n, dtype=bool)
    for strip in strips:
        flags[strip["row"] : strip["row"] + 2] = True
    return flags


def _strips(columns: Columns, n: int) -> list[dict[str, Any]]:
    """The rows of ``events/strips``: mode, name, time (entry) and exit_time (s), and the
    sample ``row`` of the entry (the exit is the next sample)."""
    rows, entry = columns.numbers(STRIPS, "entry")
    _, exit_ = columns.numbers(STRIPS, "exit")
    _ordered_times(entry, "events/strips")
    _indices(rows, max(n - 1, 0), "events/strips rows")
    return [
        {"mode": m, "name": name, "time": float(a), "exit_time": float(b), "row": int(r)}
        for m, name, a, b, r in zip(
            columns.strings(STRIPS, "mode"), columns.strings(STRIPS, "name"), entry, exit_, rows, strict=True
        )
    ]


def _transitions(columns: Columns) -> list[dict[str, Any]]:
    """The rows of ``events/transitions``, with the states before and after the reset."""
    ev = TRANSITIONS
    text = {f: columns.strings(ev, f) for f in ("name", "source", "target")}
    nums = {f: columns.numbers(ev, f)[1] for f in ("index", "time", "landing_time", "exit_time", "depth")}
    before = columns.arrays(ev, "state_before")
    after = columns.arrays(ev, "state_after")
    _indices(nums["index"], 2**31, "events/transitions:index")
    for field in ("time", "landing_time", "exit_time", "depth"):
        if not np.all(np.isfinite(nums[field])):
            raise ValueError(f"events/transitions:{field} holds values that are not finite")
    return [
        {
            "name": text["name"][k],
            "source": text["source"][k],
            "target": text["target"][k],
            "index": int(nums["index"][k]),
            "time": float(nums["time"][k]),
            "landing_time": float(nums["landing_time"][k]),
            "exit_time": float(nums["exit_time"][k]),
            "depth": float(nums["depth"][k]),
            "state_before": before[k],
            "state_after": after[k],
        }
        for k in range(len(text["name"]))
    ]


def _scenery(columns: Columns, meta: dict[str, Any]) -> dict[str, np.ndarray]:
    scenery = {}
    for part in meta.get("scenery", []):
        rows = columns.values(entity(SCENERY, part), "LineStrips3D:strips")
        if rows and rows[0]:
            scenery[part] = np.array(rows[0][0], dtype=float)[:, [0, 2]].reshape(-1, 2)
    return scenery
