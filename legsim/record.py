"""Rerun recordings of executions (``.rrd``), written headlessly and read back.

A recording holds everything needed to inspect a run later without the model:

* ``state/<name>``: every state coordinate by name (Rerun ``Scalars``), one row per *sample*.
  The samples are the computed points of every segment (the step ends, the strip entry point
  q) and, for every strip, its entry and exit with the held state q, in time order. A
  coordinate only has rows in the modes that have it.
* ``samples/t`` (the exact time as float64; the ``sim_time`` timeline only keeps nanoseconds),
  ``strip/active`` (1 inside a strip, 0 outside) and ``mode/index`` (index into the mode list
  of ``legsim/meta``) on the same rows.
* ``mode``: a text log row at the start of every segment (the mode sequence).
* ``events/strips`` and ``events/transitions``: one row per strip (mode, transition name, entry
  and exit times) and per transition (edge, times, depth, state before and after the reset),
  as text for the viewer and as typed values for reading back.
* ``robot/<part>``: the robot's polylines (``Model.geometry``) on frames of the ``frame``
  timeline, drawn in the x-z plane of a z-up 3D view; ``scenery/<part>`` the static ground and
  stops; ``frames/t`` the exact frame times.
* ``summary`` (markdown for the viewer) and ``legsim/meta`` (JSON: format, run summary with the
  keys of ``legsim run --json``, state names per mode, mode list, geometry part names).

Timelines: ``sim_time`` (simulated time, what the viewer scrubs), ``sample`` (row index of the
state samples) and ``frame`` (row index of the geometry frames).

rerun is imported inside the functions only: importing ``legsim.record`` costs nothing and the
rest of legsim never needs rerun.
"""

from __future__ import annotations

import json
import math
import os
import uuid
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from .builders import Model
from .errors import LegsimError, ModelError
from .execution import Execution

FORMAT = "legsim-rrd-1"
APPLICATION_ID = "legsim"
TIMELINE = "sim_time"
SAMPLE_TIMELINE = "sample"
FRAME_TIMELINE = "frame"

#: Default frame rate of geometry frames (per simulated second) and their most.
DEFAULT_FPS = 60.0
DEFAULT_MAX_FRAMES = 2000

# Colours (RGB) of robot parts in the viewer, in order of part name; scenery is grey.
PART_COLOURS = [(31, 119, 180), (214, 39, 40), (44, 160, 44), (255, 127, 14), (148, 103, 189),
                (140, 86, 75), (227, 119, 194), (23, 190, 207), (188, 189, 34)]
SCENERY_COLOUR = (110, 110, 110)


class RecordingError(LegsimError, ValueError):
    """A recording cannot be written or read; the message names the file."""


# -- what gets recorded -------------------------------------------------------------------------
@dataclass
class Trace:
    """An execution flattened to samples, in time order (what ``state/<name>`` holds).

    times: (N,) s; mode_names: the modes in order of first visit; mode_index: (N,) index of
    each sample's mode in mode_names; in_strip: (N,) bool, True for the strip entry/exit
    samples (state held at q); blocks: mode -> (rows (M,), states (M, n_mode)), the samples
    of that mode; segment_starts: sample index where each segment starts; strip_samples:
    sample index of each strip's entry sample.
    """

    times: np.ndarray
    mode_names: list[str]
    mode_index: np.ndarray
    in_strip: np.ndarray
    blocks: dict[str, tuple[np.ndarray, np.ndarray]]
    segment_starts: np.ndarray
    strip_samples: np.ndarray

    @property
    def modes(self) -> list[str]:
        """The mode of every sample (N names)."""
        return [self.mode_names[i] for i in self.mode_index]


def _ranges(starts: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """concatenate(arange(s, s + n) for s, n in zip(starts, lengths)), without a Python loop."""
    lengths = np.asarray(lengths, dtype=np.int64)
    total = int(lengths.sum())
    if total == 0:
        return np.empty(0, dtype=np.int64)
    offsets = np.cumsum(lengths) - lengths
    return np.repeat(np.asarray(starts, dtype=np.int64) - offsets, lengths) + np.arange(total, dtype=np.int64)


def execution_trace(execution: Execution) -> Trace:
    """Flatten an execution into the samples a recording stores.

    Segment points are taken as computed (no interpolation); each strip adds two samples with
    the held guard point q, at its entry and at its exit, so that the recorded series show
    the state standing still through the strip. Pieces come in the execution's own order
    (``Execution._pieces``: segment, strip, segment, ...), which keeps zero-length pieces in
    place.
    """
    _, kinds = execution._pieces()
    segs, strips = execution.segments, execution.strips
    is_strip = np.array([kind == "strip" for kind, _ in kinds], dtype=bool)
    which = np.array([k for _, k in kinds], dtype=np.int64)
    seg_len = np.array([len(s.t) for s in segs], dtype=np.int64)
    lengths = np.where(is_strip, 2, seg_len[np.where(is_strip, 0, which)] if len(segs) else 0)
    starts = np.cumsum(lengths) - lengths
    strip_times = np.array([(s.time, s.exit_time) for s in strips], dtype=float).reshape(-1, 2)
    times = np.concatenate([strip_times[k] if kind == "strip" else segs[k].t for kind, k in kinds]) \
        if kinds else np.empty(0)
    piece_modes = [strips[k].mode if kind == "strip" else segs[k].mode for kind, k in kinds]
    mode_names = list(dict.fromkeys(piece_modes))
    code = {m: i for i, m in enumerate(mode_names)}
    piece_code = np.array([code[m] for m in piece_modes], dtype=np.int64)
    blocks: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for m, i in code.items():
        mine = np.nonzero(piece_code == i)[0]
        # A held strip state appears twice (entry and exit): stack the strips of this mode once.
        held_ids = which[mine][is_strip[mine]]
        held = {int(k): 2 * j for j, k in enumerate(held_ids)}
        q2 = np.repeat(np.array([strips[k].state for k in held_ids], dtype=float), 2, axis=0) if len(held_ids) \
            else None
        parts = [q2[held[int(which[p])]:held[int(which[p])] + 2] if is_strip[p] else segs[which[p]].x
                 for p in mine]
        blocks[m] = (_ranges(starts[mine], lengths[mine]), np.concatenate(parts).astype(float, copy=False))
    return Trace(
        times=times,
        mode_names=mode_names,
        mode_index=np.repeat(piece_code, lengths),
        in_strip=np.repeat(is_strip, lengths),
        blocks=blocks,
        segment_starts=starts[~is_strip],
        strip_samples=starts[is_strip],
    )


def trace_series(execution: Execution, trace: Trace | None = None) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Coordinate name -> (sample indices (M,), values (M,)) over the samples of ``trace``
    whose mode has that coordinate; a name present in several modes is one series."""
    if trace is None:
        trace = execution_trace(execution)
    names: dict[str, None] = {}
    for m in trace.mode_names:
        for nm in execution.state_names.get(m, ()):
            names.setdefault(nm, None)
    out: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for nm in names:
        rows_list, values = [], []
        for m, (rows, block) in trace.blocks.items():
            coords = tuple(execution.state_names.get(m, ()))
            if nm in coords:
                rows_list.append(rows)
                values.append(block[:, coords.index(nm)])
        rows = np.concatenate(rows_list)
        vals = np.concatenate(values)
        keep = np.argsort(rows, kind="stable")
        out[nm] = (rows[keep], vals[keep])
    return out


@dataclass
class Frames:
    """Robot geometry at a sequence of times (what ``robot/<part>`` holds).

    times: (F,) s; modes: F mode names; parts: part name -> F polylines, each an array (k, 2)
    of (x, z) in metres, or None where the part is absent in that frame; scenery: static
    polylines (k, 2).
    """

    times: np.ndarray
    modes: list[str]
    parts: dict[str, list[np.ndarray | None]]
    scenery: dict[str, np.ndarray] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.times)


def frame_times(execution: Execution, fps: float = DEFAULT_FPS, max_frames: int = DEFAULT_MAX_FRAMES) -> np.ndarray:
    """Times (s) at which to draw the robot: a uniform grid of ``fps`` frames per simulated
    second (coarser when that would exceed ``max_frames``), plus every strip entry and exit
    while the total stays within ``max_frames`` (so that the viewer shows each transition)."""
    if not (fps > 0 and math.isfinite(fps)):
        raise RecordingError(f"fps must be finite and > 0, got {fps!r}")
    if max_frames < 2:
        raise RecordingError(f"max_frames must be >= 2, got {max_frames!r}")
    t0, t1 = float(execution.t0), float(execution.t_end)
    span = t1 - t0
    if span <= 0:
        return np.array([t0])
    count = int(min(max_frames, math.floor(span * fps) + 1))
    grid = np.linspace(t0, t1, max(count, 2))
    events = np.array([t for s in execution.strips for t in (s.time, s.exit_time)])
    if len(grid) + len(events) <= max_frames and len(events):
        grid = np.union1d(grid, events[(events >= t0) & (events <= t1)])
    return grid


def _polyline(value: Any, part: str, mode: str, t: float, system: str) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ModelError(f"{system}: geometry part '{part}' in mode '{mode}' at t={t:.6g} is not numeric: {exc}") from exc
    if arr.ndim == 1 and arr.shape == (2,):
        arr = arr.reshape(1, 2)
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ModelError(f"{system}: geometry part '{part}' in mode '{mode}' at t={t:.6g} has shape {arr.shape}, "
                         f"expected (k, 2) points (x, z) in metres")
    if not np.all(np.isfinite(arr)):
        raise ModelError(f"{system}: geometry part '{part}' in mode '{mode}' at t={t:.6g} is not finite")
    return arr


def geometry_frames(execution: Execution, model: Model, times: np.ndarray | None = None, *,
                    fps: float = DEFAULT_FPS, max_frames: int = DEFAULT_MAX_FRAMES) -> Frames:
    """Evaluate ``model.geometry(mode, x)`` on the execution at ``times`` (default
    ``frame_times``). Raises ModelError naming the part, mode and time when the geometry is
    missing or malformed."""
    name = model.system.name
    if model.geometry is None:
        raise ModelError(f"{name}: the model has no geometry (Model.geometry is None), so there is no robot to draw")
    if times is None:
        times = frame_times(execution, fps, max_frames)
    samples = execution.sample(times)
    drawn: list[dict[str, np.ndarray]] = []
    for t, mode, x in zip(samples.times, samples.modes, samples.states):
        try:
            parts = model.geometry(mode, np.asarray(x, dtype=float))
        except ModelError:
            raise
        except Exception as exc:
            raise ModelError(f"{name}: geometry failed in mode '{mode}' at t={t:.6g}: {type(exc).__name__}: {exc}") from exc
        if not isinstance(parts, Mapping):
            raise ModelError(f"{name}: geometry must return a dict part -> (k, 2) array, got {type(parts).__name__}")
        drawn.append({str(p): _polyline(v, str(p), mode, float(t), name) for p, v in parts.items()})
    names = sorted({p for d in drawn for p in d})
    per_part = {p: [d.get(p) for d in drawn] for p in names}
    scenery = {str(p): _polyline(v, str(p), "scenery", float(execution.t0), name) for p, v in model.scenery.items()}
    return Frames(np.asarray(samples.times, dtype=float), list(samples.modes), per_part, scenery)


def scenery_only(model: Model | None) -> dict[str, np.ndarray]:
    """The model's static polylines, validated (empty without a model)."""
    if model is None:
        return {}
    return {str(p): _polyline(v, str(p), "scenery", 0.0, model.system.name) for p, v in model.scenery.items()}


def _resolve_model(scene: Any, model: Model | None) -> Model | None:
    if scene is not None:
        if model is not None and model is not scene.model:
            raise RecordingError("give either a scene or model=, not both")
        return scene.model
    return model


def run_summary(execution: Execution, scene: Any = None, model: Model | None = None) -> dict[str, Any]:
    """The run summary with the keys of ``legsim run --json``.

    With a scene this is ``legsim.scene.run_summary`` plus ``scene_file``; without one,
    ``Execution.summary()`` plus the energies at the start and end of the run (J) when
    ``model.system`` defines one. (``legsim run --json`` adds ``outputs``, the files written,
    and so does ``legsim replay --json``.)
    """
    from .scene import run_summary as scene_summary

    out = scene_summary(execution, scene)
    if scene is not None and getattr(scene, "path", None) is not None:
        out["scene_file"] = str(scene.path)
    if scene is None and model is not None and model.system.energy is not None and execution.segments:
        first = execution.segments[0]
        energy = model.system.energy
        try:
            out["energy_initial"] = _finite(float(energy(first.mode, first.x[0].copy())))
            out["energy_final"] = _finite(float(energy(execution.final_mode, execution.final_state)))
        except Exception as exc:
            raise ModelError(f"{model.system.name}: energy failed: {type(exc).__name__}: {exc}") from exc
    return out


def _finite(value: float) -> float | None:
    return value if math.isfinite(value) else None


# -- writing ------------------------------------------------------------------------------------
def write_rrd(execution: Execution, scene: Any = None, path: str | os.PathLike | None = None, *,
              model: Model | None = None, fps: float = DEFAULT_FPS,
              max_frames: int = DEFAULT_MAX_FRAMES) -> Path:
    """Record ``execution`` to the Rerun file ``path`` headlessly (no viewer, no network).

    ``scene`` is a ``legsim.scene.Scene`` (its model gives geometry, scenery and energy) or
    None with ``model=`` a ``legsim.builders.Model`` (or neither: states and events only).
    Geometry frames are drawn at ``frame_times(execution, fps, max_frames)``. The file is
    written completely or not at all: it is assembled in memory, written to a temporary name
    in the same folder and renamed; nothing is left behind on failure. Returns the path.
    """
    if path is None:
        raise RecordingError("write_rrd needs a path to write to")
    path = Path(path)
    if not isinstance(execution, Execution):
        raise RecordingError(f"{path}: write_rrd needs a legsim Execution, got {type(execution).__name__}")
    model = _resolve_model(scene, model)
    summary = run_summary(execution, scene, model)
    trace = execution_trace(execution)
    frames = None
    if model is not None and model.geometry is not None:
        frames = geometry_frames(execution, model, fps=fps, max_frames=max_frames)
    scenery = frames.scenery if frames is not None else scenery_only(model)
    meta = {
        "format": FORMAT,
        "summary": summary,
        "scene": None if scene is None else str(getattr(scene, "path", "")),
        "state_names": {m: list(v) for m, v in execution.state_names.items()},
        "modes": _mode_list(execution),
        "t0": float(execution.t0),
        "t_end": float(execution.t_end),
        "parts": [] if frames is None else list(frames.parts),
        # Parts that are a single point in every frame (a centre of mass, a foot) are points.
        "point_parts": [] if frames is None else [p for p, lines in frames.parts.items()
                                                  if all(line is None or len(line) <= 1 for line in lines)],
        "scenery": list(scenery),
        "has_geometry": frames is not None,
    }
    data = _record_bytes(execution, trace, frames, scenery, meta)
    _write_atomic(path, data)
    return path


def _mode_list(execution: Execution) -> list[str]:
    seen: dict[str, None] = {}
    for seg in execution.segments:
        seen.setdefault(seg.mode, None)
    for strip in execution.strips:
        seen.setdefault(strip.mode, None)
    for tr in execution.transitions:
        seen.setdefault(tr.target, None)
    return list(seen)


def _write_atomic(path: Path, data: bytes) -> None:
    # The temporary file is created with open(..., "xb") rather than mkstemp so that it gets
    # the usual permissions (0666 less the umask), which the renamed file keeps.
    tmp = path.parent / f".{path.name}.{uuid.uuid4().hex[:12]}.tmp"
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fh = open(tmp, "xb")
    except OSError as exc:
        raise RecordingError(f"{path}: cannot write the recording: {exc}") from exc
    try:
        with fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException as exc:
        tmp.unlink(missing_ok=True)
        if isinstance(exc, OSError):
            raise RecordingError(f"{path}: cannot write the recording: {exc}") from exc
        raise


def _summary_markdown(meta: dict[str, Any]) -> str:
    s = meta["summary"]
    seq = s.get("mode_sequence", [])
    shown = " → ".join(seq[:30]) + (f" … ({len(seq) - 30} more)" if len(seq) > 30 else "")
    names = s.get("state_names", [])
    final = ", ".join(f"{n} = {v:.6g}" if isinstance(v, float) else f"{n} = {v}"
                      for n, v in zip(names, s.get("final_state", [])))
    lines = [
        f"# {s.get('scene') or s.get('system', 'legsim run')}",
        "",
        f"* status: **{s.get('status')}** {s.get('message') or ''}",
        f"* t_final: {s.get('t_final')} s, method {s.get('method')}, h = {s.get('h')}, eps = {s.get('eps')}",
        f"* steps {s.get('steps')}, halvings {s.get('halvings')}, transitions {s.get('transitions')}",
        f"* mode sequence: {shown}",
        f"* final mode {s.get('final_mode')}: {final}",
    ]
    if "energy_initial" in s:
        lines.append(f"* energy: {s.get('energy_initial')} J → {s.get('energy_final')} J")
    lines += ["", "```json", json.dumps(s, indent=2), "```"]
    return "\n".join(lines)


def _record_bytes(execution: Execution, trace: Trace, frames: Frames | None,
                  scenery: dict[str, np.ndarray], meta: dict[str, Any]) -> bytes:
    import rerun as rr
    import rerun.blueprint as rrb

    rec = rr.RecordingStream(APPLICATION_ID, recording_id=uuid.uuid4())
    if not rr.is_enabled(rec):
        raise RecordingError("Rerun logging is disabled in this environment (RERUN=off?); "
                             "unset RERUN to write recordings")
    memory = rec.memory_recording()
    try:
        _log_all(rr, rrb, rec, execution, trace, frames, scenery, meta)
        rec.flush()
        data = memory.drain_as_bytes()
    finally:
        rec.disconnect()
    return data


def _log_all(rr, rrb, rec, execution, trace: Trace, frames: Frames | None, scenery, meta) -> None:
    modes = meta["modes"]
    mode_index = {m: i for i, m in enumerate(modes)}
    n = len(trace.times)
    sample_idx = np.arange(n, dtype=np.int64)

    def sample_indexes(rows: np.ndarray) -> list:
        return [rr.TimeColumn(SAMPLE_TIMELINE, sequence=sample_idx[rows]),
                rr.TimeColumn(TIMELINE, duration=trace.times[rows])]

    rec.send_blueprint(_blueprint(rrb, meta, frames, scenery))
    rec.log("legsim/meta", rr.TextDocument(json.dumps(meta), media_type="text/plain"), static=True)
    rec.log("summary", rr.TextDocument(_summary_markdown(meta), media_type="text/markdown"), static=True)

    every = np.arange(n)
    rec.send_columns("samples/t", indexes=sample_indexes(every), columns=rr.Scalars.columns(scalars=trace.times))
    rec.send_columns("strip/active", indexes=sample_indexes(every),
                     columns=rr.Scalars.columns(scalars=trace.in_strip.astype(float)))
    lookup = np.array([mode_index[m] for m in trace.mode_names], dtype=float)
    rec.send_columns("mode/index", indexes=sample_indexes(every),
                     columns=rr.Scalars.columns(scalars=lookup[trace.mode_index]))

    for nm, (rows, vals) in trace_series(execution, trace).items():
        rec.log(f"state/{nm}", rr.SeriesLines(names=[nm]), static=True)
        rec.send_columns(f"state/{nm}", indexes=sample_indexes(rows), columns=rr.Scalars.columns(scalars=vals))

    # Typed values go in as arrow arrays: AnyValues would otherwise convert every element
    # through a Python list, which dominates the cost of runs with many transitions.
    import pyarrow as pa

    def values(**columns: Any) -> list:
        arrays = {}
        for key, value in columns.items():
            if isinstance(value, list) and value and isinstance(value[0], np.ndarray):
                sizes = np.array([len(v) for v in value], dtype=np.int32)
                offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int32)
                arrays[key] = pa.ListArray.from_arrays(pa.array(offsets), pa.array(np.concatenate(value)))
            elif isinstance(value, list):
                arrays[key] = pa.array(value, type=pa.string())
            else:
                arrays[key] = pa.array(value)
        return [*rr.AnyValues.columns(**arrays)]

    seg_rows = np.asarray(trace.segment_starts, dtype=np.int64)
    segs = execution.segments
    if len(seg_rows):
        rec.send_columns("mode", indexes=sample_indexes(seg_rows), columns=[
            *rr.TextLog.columns(text=[s.mode for s in segs]),
            *values(t_start=np.array([s.t_start for s in segs], dtype=float),
                    t_end=np.array([s.t_end for s in segs], dtype=float)),
        ])

    strip_rows = np.asarray(trace.strip_samples, dtype=np.int64)
    if len(strip_rows):
        strips = execution.strips
        rec.send_columns("events/strips", indexes=sample_indexes(strip_rows), columns=[
            *rr.TextLog.columns(text=[f"strip of {s.name} in '{s.mode}': {s.time:.9g} s to {s.exit_time:.9g} s"
                                      for s in strips]),
            *values(mode=[s.mode for s in strips], name=[s.name for s in strips],
                    entry=np.array([s.time for s in strips], dtype=float),
                    exit=np.array([s.exit_time for s in strips], dtype=float)),
        ])

    trs = execution.transitions
    if trs:
        # A transition is logged on its strip's entry sample; strips and transitions pair up
        # in order, except a final strip cut short by t_final or the transition budget.
        tr_rows = strip_rows[:len(trs)]
        rec.send_columns("events/transitions", indexes=sample_indexes(tr_rows), columns=[
            *rr.TextLog.columns(text=[f"{t.name}: {t.source} -> {t.target} at {t.time:.9g} s "
                                      f"(reset at {t.exit_time:.9g} s, depth {t.depth:.3g})" for t in trs]),
            *values(name=[t.name for t in trs], source=[t.source for t in trs], target=[t.target for t in trs],
                    index=np.array([t.index for t in trs], dtype=np.int64),
                    time=np.array([t.time for t in trs], dtype=float),
                    landing_time=np.array([t.landing_time for t in trs], dtype=float),
                    exit_time=np.array([t.exit_time for t in trs], dtype=float),
                    depth=np.array([t.depth for t in trs], dtype=float),
                    state_before=[np.asarray(t.state_before, dtype=float) for t in trs],
                    state_after=[np.asarray(t.state_after, dtype=float) for t in trs]),
        ])

    # Geometry: the sagittal plane (x, z) drawn at y = 0 of a z-up 3D view.
    rec.log("/", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    for k, (part, line) in enumerate(scenery.items()):
        rec.log(f"scenery/{part}", rr.LineStrips3D([_xz_to_3d(line)], colors=[SCENERY_COLOUR], radii=[-1.5]),
                static=True)
    if frames is not None and len(frames):
        f_idx = [rr.TimeColumn(FRAME_TIMELINE, sequence=np.arange(len(frames), dtype=np.int64)),
                 rr.TimeColumn(TIMELINE, duration=frames.times)]
        rec.send_columns("frames/t", indexes=f_idx, columns=rr.Scalars.columns(scalars=frames.times))
        rec.send_columns("frames/mode", indexes=f_idx, columns=rr.TextLog.columns(text=frames.modes))
        point_parts = set(meta["point_parts"])
        for k, (part, lines) in enumerate(frames.parts.items()):
            colour = PART_COLOURS[k % len(PART_COLOURS)]
            if part in point_parts:
                # A one-point "polyline" would not be drawn as a line strip: log it as a point.
                rec.log(f"robot/{part}", rr.Points3D.from_fields(colors=[colour], radii=[-6.0]), static=True)
                present = [line for line in lines if line is not None and len(line)]
                positions = np.concatenate([_xz_to_3d(line) for line in present]) if present else np.zeros((0, 3))
                counts = [0 if line is None else len(line) for line in lines]
                rec.send_columns(f"robot/{part}", indexes=f_idx,
                                 columns=rr.Points3D.columns(positions=positions).partition(counts))
                continue
            rec.log(f"robot/{part}", rr.LineStrips3D.from_fields(colors=[colour], radii=[-2.5]), static=True)
            strips = [np.zeros((0, 3)) if line is None else _xz_to_3d(line) for line in lines]
            rec.send_columns(f"robot/{part}", indexes=f_idx, columns=rr.LineStrips3D.columns(strips=strips))


def _xz_to_3d(line: np.ndarray) -> np.ndarray:
    out = np.zeros((len(line), 3))
    out[:, 0] = line[:, 0]
    out[:, 2] = line[:, 1]
    return out


def _blueprint(rrb, meta: dict[str, Any], frames: Frames | None, scenery: dict[str, np.ndarray]):
    views = []
    if frames is not None or scenery:
        eye = None
        pts = [line for lines in (frames.parts.values() if frames is not None else []) for line in lines
               if line is not None and len(line)]
        if not pts:
            pts = list(scenery.values())
        if pts:
            allp = np.concatenate(pts)
            lo, hi = allp.min(axis=0), allp.max(axis=0)
            centre = (lo + hi) / 2
            size = float(max(hi[0] - lo[0], hi[1] - lo[1], 0.5))
            eye = rrb.EyeControls3D(position=(float(centre[0]), -1.6 * size, float(centre[1])),
                                    look_target=(float(centre[0]), 0.0, float(centre[1])), eye_up=(0.0, 0.0, 1.0))
        views.append(rrb.Spatial3DView(origin="/", contents=["robot/**", "scenery/**"], name="robot",
                                       eye_controls=eye))
    plots = rrb.Vertical(
        rrb.TimeSeriesView(origin="state", name="state"),
        rrb.TimeSeriesView(contents=["strip/active", "mode/index"], name="strip and mode"),
        row_shares=[3, 1],
    )
    views.append(plots)
    side = rrb.Vertical(rrb.TextDocumentView(origin="summary", name="summary"),
                        rrb.TextLogView(contents=["mode", "events/**"], name="events"))
    return rrb.Blueprint(rrb.Horizontal(*views, side), rrb.TimePanel(timeline=TIMELINE), collapse_panels=True)


# -- reading ------------------------------------------------------------------------------------
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
    columns = _read_columns(path)
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
    try:
        return _assemble(columns, meta)
    except (KeyError, IndexError, ValueError, TypeError) as exc:
        raise RecordingError(f"{path}: incomplete or damaged legsim recording ({type(exc).__name__}: {exc})") from exc


class _Columns:
    """The recorded components, per entity, as arrow arrays with their row index (the
    ``sample`` or ``frame`` timeline; -1 for static rows), converted only when asked for."""

    SKIP = ("rerun.controls.RowId", TIMELINE, SAMPLE_TIMELINE, FRAME_TIMELINE, "log_time", "log_tick")

    def __init__(self) -> None:
        self.data: dict[str, dict[str, list[tuple[np.ndarray, Any]]]] = {}

    def add(self, entity: str, index: np.ndarray, batch) -> None:
        comps = self.data.setdefault(entity, {})
        for name in batch.schema.names:
            if name not in self.SKIP:
                comps.setdefault(name, []).append((index, batch.column(name)))

    def entities(self) -> list[str]:
        return list(self.data)

    def _pieces(self, entity: str, component: str):
        for index, column in self.data.get(entity, {}).get(component, []):
            valid = column.is_valid()
            yield index[np.asarray(valid.to_numpy(zero_copy_only=False), dtype=bool)], column.filter(valid)

    def numbers(self, entity: str, component: str = "Scalars:scalars") -> tuple[np.ndarray, np.ndarray]:
        """(row indices, values) of a one-number-per-row component, sorted by row."""
        idx_parts, val_parts = [], []
        for index, column in self._pieces(entity, component):
            if len(column) and not np.all(column.value_lengths().to_numpy(zero_copy_only=False) == 1):
                raise ValueError(f"{entity}:{component} holds more than one value per row")
            idx_parts.append(index)
            val_parts.append(np.asarray(column.flatten().to_numpy(zero_copy_only=False), dtype=float))
        if not idx_parts:
            return np.empty(0, dtype=np.int64), np.empty(0)
        idx = np.concatenate(idx_parts)
        vals = np.concatenate(val_parts)
        order = np.argsort(idx, kind="stable")
        return idx[order], vals[order]

    def _sorted_flat(self, entity: str, component: str):
        """(row indices sorted, flat values in that order, row lengths in that order)."""
        idx_parts, flat_parts, len_parts = [], [], []
        for index, column in self._pieces(entity, component):
            idx_parts.append(index)
            len_parts.append(np.asarray(column.value_lengths().to_numpy(zero_copy_only=False), dtype=np.int64))
            flat_parts.append(column.flatten())
        if not idx_parts:
            return np.empty(0, dtype=np.int64), [], np.empty(0, dtype=np.int64)
        idx = np.concatenate(idx_parts)
        lengths = np.concatenate(len_parts)
        import pyarrow as pa

        flat = pa.concat_arrays([f.cast(flat_parts[0].type) for f in flat_parts]) if len(flat_parts) > 1 \
            else flat_parts[0]
        order = np.argsort(idx, kind="stable")
        if np.any(order != np.arange(len(order))):
            offsets = np.cumsum(lengths) - lengths
            take = _ranges(offsets[order], lengths[order])
            flat = flat.take(pa.array(take))
            lengths = lengths[order]
        return idx[order], flat, lengths

    def strings(self, entity: str, component: str) -> list[str]:
        """Each row's single string, sorted by row."""
        _, flat, lengths = self._sorted_flat(entity, component)
        if len(lengths) and not np.all(lengths == 1):
            raise ValueError(f"{entity}:{component} holds more than one value per row")
        return [] if not len(lengths) else flat.to_pylist()

    def arrays(self, entity: str, component: str) -> list[np.ndarray]:
        """Each row's values as a float array (rows may differ in length), sorted by row."""
        _, flat, lengths = self._sorted_flat(entity, component)
        if not len(lengths):
            return []
        values = np.asarray(flat.to_numpy(zero_copy_only=False), dtype=float)
        return np.split(values, np.cumsum(lengths)[:-1])

    def rows(self, entity: str, component: str) -> list[tuple[int, list]]:
        """(row index, Python list of the row's values), sorted by row (small entities only)."""
        out: list[tuple[int, list]] = []
        for index, column in self._pieces(entity, component):
            out.extend(zip(index.tolist(), column.to_pylist()))
        out.sort(key=lambda r: r[0])
        return out

    def values(self, entity: str, component: str) -> list:
        """Each row's Python list of values, sorted by row (small entities only)."""
        return [r[1] for r in self.rows(entity, component)]


def _read_columns(path: Path) -> _Columns:
    try:
        from rerun.chunk import RrdReader

        with warnings.catch_warnings():
            # A damaged file also draws a RerunWarning about a missing footer; our error says it.
            warnings.simplefilter("ignore")
            reader = RrdReader(path)
            chunks = list(reader.stream())
    except Exception as exc:  # rerun raises its own error types for foreign or truncated files
        raise RecordingError(f"{path}: not a readable Rerun recording ({type(exc).__name__}: {exc})") from exc
    out = _Columns()
    for chunk in chunks:
        batch = chunk.to_record_batch()
        names = batch.schema.names
        if chunk.is_static:
            index = np.full(batch.num_rows, -1, dtype=np.int64)
        elif SAMPLE_TIMELINE in names:
            index = np.asarray(batch.column(SAMPLE_TIMELINE).to_numpy(zero_copy_only=False), dtype=np.int64)
        elif FRAME_TIMELINE in names:
            index = np.asarray(batch.column(FRAME_TIMELINE).to_numpy(zero_copy_only=False), dtype=np.int64)
        else:
            continue
        out.add(chunk.entity_path, index, batch)
    return out


def _assemble(columns: _Columns, meta: dict[str, Any]) -> dict[str, Any]:
    idx, times = columns.numbers("/samples/t")
    if not np.array_equal(idx, np.arange(len(idx))):
        raise ValueError("sample rows are not contiguous")
    _, in_strip = columns.numbers("/strip/active")
    _, mode_idx = columns.numbers("/mode/index")
    if not (len(in_strip) == len(mode_idx) == len(times)):
        raise ValueError("sample columns differ in length")
    modes_list = meta["modes"]
    modes = [modes_list[i] for i in mode_idx.astype(np.int64)]
    series: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    series_rows: dict[str, np.ndarray] = {}
    for entity in columns.entities():
        if entity.startswith("/state/"):
            rows, vals = columns.numbers(entity)
            if len(rows):
                series[entity[len("/state/"):]] = (times[rows], vals)
                series_rows[entity[len("/state/"):]] = rows
    mode_sequence = columns.strings("/mode", "TextLog:text")
    _, t_start = columns.numbers("/mode", "t_start")
    _, t_end = columns.numbers("/mode", "t_end")
    segments = [(m, float(a), float(b)) for m, a, b in zip(mode_sequence, t_start, t_end, strict=True)]

    _, entry = columns.numbers("/events/strips", "entry")
    _, exit_ = columns.numbers("/events/strips", "exit")
    strips = [{"mode": m, "name": n, "time": float(a), "exit_time": float(b)}
              for m, n, a, b in zip(columns.strings("/events/strips", "mode"),
                                    columns.strings("/events/strips", "name"), entry, exit_, strict=True)]

    ev = "/events/transitions"
    text = {f: columns.strings(ev, f) for f in ("name", "source", "target")}
    nums = {f: columns.numbers(ev, f)[1] for f in ("index", "time", "landing_time", "exit_time", "depth")}
    before = columns.arrays(ev, "state_before")
    after = columns.arrays(ev, "state_after")
    transitions = []
    for k in range(len(text["name"])):
        transitions.append({
            "name": text["name"][k], "source": text["source"][k], "target": text["target"][k],
            "index": int(nums["index"][k]), "time": float(nums["time"][k]),
            "landing_time": float(nums["landing_time"][k]), "exit_time": float(nums["exit_time"][k]),
            "depth": float(nums["depth"][k]),
            "state_before": before[k], "state_after": after[k],
        })

    scenery = {}
    for part in meta.get("scenery", []):
        rows = columns.values(f"/scenery/{part}", "LineStrips3D:strips")
        if rows and rows[0]:
            scenery[part] = np.array(rows[0][0], dtype=float)[:, [0, 2]].reshape(-1, 2)
    frames = None
    if meta.get("has_geometry"):
        _, f_times = columns.numbers("/frames/t")
        f_modes = columns.strings("/frames/mode", "TextLog:text")
        parts: dict[str, list[np.ndarray | None]] = {}
        point_parts = set(meta.get("point_parts", []))
        for part in meta.get("parts", []):
            lines: list[np.ndarray | None] = [None] * len(f_times)
            if part in point_parts:
                for i, points in columns.rows(f"/robot/{part}", "Points3D:positions"):
                    if 0 <= i < len(lines) and points:
                        lines[i] = np.array(points, dtype=float)[:, [0, 2]].reshape(-1, 2)
            else:
                for i, strips_row in columns.rows(f"/robot/{part}", "LineStrips3D:strips"):
                    if 0 <= i < len(lines) and strips_row and len(strips_row[0]):
                        lines[i] = np.array(strips_row[0], dtype=float)[:, [0, 2]].reshape(-1, 2)
            parts[part] = lines
        frames = Frames(f_times, f_modes, parts, scenery)

    return {
        "summary": meta["summary"],
        "meta": meta,
        "times": times,
        "modes": modes,
        "in_strip": in_strip.astype(bool),
        "series": series,
        "series_rows": series_rows,
        "mode_sequence": mode_sequence,
        "segments": segments,
        "strips": strips,
        "transitions": transitions,
        "frames": frames,
        "scenery": scenery,
    }
