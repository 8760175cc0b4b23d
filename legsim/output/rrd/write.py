"""Writing a run to a Rerun recording (``write_rrd``), headlessly: no viewer, no network.

The entities and timelines written are described in ``legsim.output.rrd.layout``. rerun (and
pyarrow, which it brings) is imported inside the functions only, so that importing this
module costs nothing and the rest of legsim never needs rerun.
"""

from __future__ import annotations

import json
import os
import uuid
from pathlib import Path
from typing import Any

import numpy as np

from ...builders import Model
from ...errors import OutputError
from ...execution import Execution
from ..files import write_bytes_atomic
from ..summary import run_summary
from ..trace import (DEFAULT_FPS, DEFAULT_MAX_FRAMES, Frames, RecordingError, Trace, execution_trace,
                     geometry_frames, resolve_model, scenery_only, trace_series)
from .layout import (APPLICATION_ID, FORMAT, FRAME_TIMELINE, PART_COLOURS, SAMPLE_TIMELINE, SCENERY_COLOUR,
                     TIMELINE)


def write_rrd(execution: Execution, scene: Any = None, path: str | os.PathLike | None = None, *,
              model: Model | None = None, fps: float = DEFAULT_FPS,
              max_frames: int = DEFAULT_MAX_FRAMES) -> Path:
    """Record ``execution`` to the Rerun file ``path`` headlessly (no viewer, no network).

    ``scene`` is a ``legsim.scene.Scene`` (its model gives geometry, scenery and energy) or
    None with ``model=`` a ``legsim.builders.Model`` (or neither: states and events only).
    Geometry frames are drawn at ``frame_times(execution, fps, max_frames)``. The file is
    written completely or not at all: it is assembled in memory and written atomically
    (``legsim.output.files``). Returns the path; raises RecordingError naming the file.
    """
    if path is None:
        raise RecordingError("write_rrd needs a path to write to")
    path = Path(path)
    if not isinstance(execution, Execution):
        raise RecordingError(f"{path}: write_rrd needs a legsim Execution, got {type(execution).__name__}")
    model = resolve_model(scene, model, "write_rrd")
    summary = run_summary(execution, scene, model)
    trace = execution_trace(execution)
    frames = None
    if model is not None and model.geometry is not None:
        frames = geometry_frames(execution, model, fps=fps, max_frames=max_frames)
    scenery = frames.scenery if frames is not None else scenery_only(model)
    meta = _meta(execution, scene, summary, frames, scenery)
    _write(path, _record_bytes(execution, trace, frames, scenery, meta))
    return path


def _meta(execution: Execution, scene: Any, summary: dict[str, Any], frames: Frames | None,
          scenery: dict[str, np.ndarray]) -> dict[str, Any]:
    """The ``legsim/meta`` document: what reading the recording back needs besides the rows."""
    return {
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


def _mode_list(execution: Execution) -> list[str]:
    """Every mode the run visited or was reset into, in order of first appearance."""
    seen: dict[str, None] = {}
    for seg in execution.segments:
        seen.setdefault(seg.mode, None)
    for strip in execution.strips:
        seen.setdefault(strip.mode, None)
    for tr in execution.transitions:
        seen.setdefault(tr.target, None)
    return list(seen)


def _write(path: Path, data: bytes) -> None:
    """Write the recording atomically; a failure is a RecordingError naming the file."""
    try:
        write_bytes_atomic(path, data, what="recording")
    except OutputError as exc:
        # write_bytes_atomic chains the OSError behind a failed write: say what the OS said.
        reason = exc.__cause__
        if isinstance(reason, OSError):
            raise RecordingError(f"{path}: cannot write the recording: {reason.strerror or reason}") from exc
        raise RecordingError(str(exc)) from exc


def _summary_markdown(meta: dict[str, Any]) -> str:
    """The run summary as the markdown document the viewer shows."""
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
    """The whole recording, logged to an in-memory Rerun stream."""
    import rerun as rr

    rec = rr.RecordingStream(APPLICATION_ID, recording_id=uuid.uuid4())
    if not rr.is_enabled(rec):
        raise RecordingError("Rerun logging is disabled in this environment (RERUN=off?); "
                             "unset RERUN to write recordings")
    memory = rec.memory_recording()
    try:
        log = _Logger(rr, rec, trace)
        log.header(meta, frames, scenery)
        log.samples(execution, meta["modes"])
        log.events(execution)
        log.geometry(frames, scenery, set(meta["point_parts"]))
        rec.flush()
        data = memory.drain_as_bytes()
    finally:
        rec.disconnect()
    return data


class _Logger:
    """Logs the parts of a recording to the stream ``rec`` (``rr`` is the rerun module)."""

    def __init__(self, rr: Any, rec: Any, trace: Trace) -> None:
        self.rr, self.rec, self.trace = rr, rec, trace

    def sample_indexes(self, rows: np.ndarray) -> list:
        """The ``sample`` and ``sim_time`` index columns of the sample rows ``rows``."""
        rr = self.rr
        return [rr.TimeColumn(SAMPLE_TIMELINE, sequence=np.asarray(rows, dtype=np.int64)),
                rr.TimeColumn(TIMELINE, duration=self.trace.times[rows])]

    def header(self, meta: dict[str, Any], frames: Frames | None, scenery: dict[str, np.ndarray]) -> None:
        """The viewer's layout, ``legsim/meta`` and the markdown ``summary``."""
        import rerun.blueprint as rrb

        rr, rec = self.rr, self.rec
        rec.send_blueprint(_blueprint(rrb, frames, scenery))
        rec.log("legsim/meta", rr.TextDocument(json.dumps(meta), media_type="text/plain"), static=True)
        rec.log("summary", rr.TextDocument(_summary_markdown(meta), media_type="text/markdown"), static=True)

    def samples(self, execution: Execution, modes: list[str]) -> None:
        """``samples/t``, ``strip/active``, ``mode/index`` and ``state/<name>``."""
        rr, rec, trace = self.rr, self.rec, self.trace
        every = self.sample_indexes(np.arange(len(trace.times)))
        rec.send_columns("samples/t", indexes=every, columns=rr.Scalars.columns(scalars=trace.times))
        rec.send_columns("strip/active", indexes=every,
                         columns=rr.Scalars.columns(scalars=trace.in_strip.astype(float)))
        position = {m: i for i, m in enumerate(modes)}
        lookup = np.array([position[m] for m in trace.mode_names], dtype=float)
        rec.send_columns("mode/index", indexes=every, columns=rr.Scalars.columns(scalars=lookup[trace.mode_index]))
        for name, (rows, values) in trace_series(execution, trace).items():
            rec.log(f"state/{name}", rr.SeriesLines(names=[name]), static=True)
            rec.send_columns(f"state/{name}", indexes=self.sample_indexes(rows),
                             columns=rr.Scalars.columns(scalars=values))

    def events(self, execution: Execution) -> None:
        """``mode`` (one row per segment), ``events/strips`` and ``events/transitions``."""
        rr, rec, trace = self.rr, self.rec, self.trace
        segs, strips, trs = execution.segments, execution.strips, execution.transitions
        if len(trace.segment_starts):
            rec.send_columns("mode", indexes=self.sample_indexes(trace.segment_starts), columns=[
                *rr.TextLog.columns(text=[s.mode for s in segs]),
                *_typed_columns(rr, t_start=np.array([s.t_start for s in segs], dtype=float),
                                t_end=np.array([s.t_end for s in segs], dtype=float)),
            ])
        strip_rows = np.asarray(trace.strip_samples, dtype=np.int64)
        if len(strip_rows):
            rec.send_columns("events/strips", indexes=self.sample_indexes(strip_rows), columns=[
                *rr.TextLog.columns(text=[f"strip of {s.name} in '{s.mode}': {s.time:.9g} s to {s.exit_time:.9g} s"
                                          for s in strips]),
                *_typed_columns(rr, mode=[s.mode for s in strips], name=[s.name for s in strips],
                                entry=np.array([s.time for s in strips], dtype=float),
                                exit=np.array([s.exit_time for s in strips], dtype=float)),
            ])
        if trs:
            # A transition is logged on its strip's entry sample; strips and transitions pair up
            # in order, except a final strip cut short by t_final or the transition budget.
            rec.send_columns("events/transitions", indexes=self.sample_indexes(strip_rows[:len(trs)]),
                             columns=_transition_columns(rr, trs))

    def geometry(self, frames: Frames | None, scenery: dict[str, np.ndarray], point_parts: set[str]) -> None:
        """``scenery/<part>`` (static), and ``frames/t``, ``frames/mode``, ``robot/<part>``."""
        rr, rec = self.rr, self.rec
        # The sagittal plane (x, z) is drawn at y = 0 of a z-up 3D view.
        rec.log("/", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        for part, line in scenery.items():
            rec.log(f"scenery/{part}", rr.LineStrips3D([_xz_to_3d(line)], colors=[SCENERY_COLOUR], radii=[-1.5]),
                    static=True)
        if frames is None or not len(frames):
            return
        f_idx = [rr.TimeColumn(FRAME_TIMELINE, sequence=np.arange(len(frames), dtype=np.int64)),
                 rr.TimeColumn(TIMELINE, duration=frames.times)]
        rec.send_columns("frames/t", indexes=f_idx, columns=rr.Scalars.columns(scalars=frames.times))
        rec.send_columns("frames/mode", indexes=f_idx, columns=rr.TextLog.columns(text=frames.modes))
        for k, (part, lines) in enumerate(frames.parts.items()):
            colour = PART_COLOURS[k % len(PART_COLOURS)]
            if part in point_parts:
                # A one-point "polyline" would not be drawn as a line strip: log it as a point.
                rec.log(f"robot/{part}", rr.Points3D.from_fields(colors=[colour], radii=[-6.0]), static=True)
                rec.send_columns(f"robot/{part}", indexes=f_idx, columns=_point_columns(rr, lines))
            else:
                rec.log(f"robot/{part}", rr.LineStrips3D.from_fields(colors=[colour], radii=[-2.5]), static=True)
                strips = [np.zeros((0, 3)) if line is None else _xz_to_3d(line) for line in lines]
                rec.send_columns(f"robot/{part}", indexes=f_idx, columns=rr.LineStrips3D.columns(strips=strips))


def _transition_columns(rr: Any, trs: list) -> list:
    """The ``events/transitions`` columns: a text line and the typed values of each transition."""
    return [
        *rr.TextLog.columns(text=[f"{t.name}: {t.source} -> {t.target} at {t.time:.9g} s "
                                  f"(reset at {t.exit_time:.9g} s, depth {t.depth:.3g})" for t in trs]),
        *_typed_columns(rr, name=[t.name for t in trs], source=[t.source for t in trs],
                        target=[t.target for t in trs],
                        index=np.array([t.index for t in trs], dtype=np.int64),
                        time=np.array([t.time for t in trs], dtype=float),
                        landing_time=np.array([t.landing_time for t in trs], dtype=float),
                        exit_time=np.array([t.exit_time for t in trs], dtype=float),
                        depth=np.array([t.depth for t in trs], dtype=float),
                        state_before=[np.asarray(t.state_before, dtype=float) for t in trs],
                        state_after=[np.asarray(t.state_after, dtype=float) for t in trs]),
    ]


def _typed_columns(rr: Any, **columns: Any) -> list:
    """``AnyValues`` columns from arrays (one number per row), lists of strings and lists of
    arrays (one variable-length list per row).

    The values go in as arrow arrays: AnyValues would otherwise convert every element through
    a Python list, which dominates the cost of runs with many transitions.
    """
    import pyarrow as pa

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


def _point_columns(rr: Any, lines: list[np.ndarray | None]) -> Any:
    """``Points3D`` columns of a point part: each frame's points (none where it is absent)."""
    present = [line for line in lines if line is not None and len(line)]
    positions = np.concatenate([_xz_to_3d(line) for line in present]) if present else np.zeros((0, 3))
    counts = [0 if line is None else len(line) for line in lines]
    return rr.Points3D.columns(positions=positions).partition(counts)


def _xz_to_3d(line: np.ndarray) -> np.ndarray:
    """(k, 2) points (x, z) as (k, 3) points (x, 0, z) of the z-up 3D view."""
    out = np.zeros((len(line), 3))
    out[:, 0] = line[:, 0]
    out[:, 2] = line[:, 1]
    return out


def _blueprint(rrb: Any, frames: Frames | None, scenery: dict[str, np.ndarray]) -> Any:
    """The viewer's layout: the robot (when there is geometry), the state plots, the summary
    and the event log, with the time panel on ``sim_time``."""
    views = []
    if frames is not None or scenery:
        views.append(rrb.Spatial3DView(origin="/", contents=["robot/**", "scenery/**"], name="robot",
                                       eye_controls=_eye(rrb, frames, scenery)))
    views.append(rrb.Vertical(
        rrb.TimeSeriesView(origin="state", name="state"),
        rrb.TimeSeriesView(contents=["strip/active", "mode/index"], name="strip and mode"),
        row_shares=[3, 1],
    ))
    side = rrb.Vertical(rrb.TextDocumentView(origin="summary", name="summary"),
                        rrb.TextLogView(contents=["mode", "events/**"], name="events"))
    return rrb.Blueprint(rrb.Horizontal(*views, side), rrb.TimePanel(timeline=TIMELINE), collapse_panels=True)


def _eye(rrb: Any, frames: Frames | None, scenery: dict[str, np.ndarray]) -> Any:
    """A camera looking along +y at the box of everything drawn (the robot's polylines, else
    the scenery), far enough back to see it whole; None when nothing is drawn."""
    pts = [line for lines in (frames.parts.values() if frames is not None else []) for line in lines
           if line is not None and len(line)]
    if not pts:
        pts = list(scenery.values())
    if not pts:
        return None
    allp = np.concatenate(pts)
    lo, hi = allp.min(axis=0), allp.max(axis=0)
    centre = (lo + hi) / 2
    size = float(max(hi[0] - lo[0], hi[1] - lo[1], 0.5))
    return rrb.EyeControls3D(position=(float(centre[0]), -1.6 * size, float(centre[1])),
                             look_target=(float(centre[0]), 0.0, float(centre[1])), eye_up=(0.0, 0.0, 1.0))
