"""Writing a run to a Rerun recording (``write_rrd``) headlessly, or streaming it to a viewer
(``legsim.output.rrd.live``): the entities of ``legsim.output.rrd.layout``.

The recording streams to its file while it is made: the samples come a chunk at a time
(``legsim.output.rrd.stream``), and each chunk's times, series and robot go to Rerun as columns
(``send_columns``) before the next is made, so the memory the writer takes beyond the
execution's own does not grow with the length of the run. rerun (and pyarrow, which it brings) is imported
inside the functions only, so that importing this module costs nothing.
"""

from __future__ import annotations

import json
import os
import uuid
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ...arguments import positive
from ...builders import Model
from ...errors import LegsimError, OutputError
from ...execution import Execution
from ...hybrid import HybridSystem
from ..files import write_atomic
from ..summary import run_summary
from ..trace import RecordingError, _draw, resolve_model, scenery_only, trace_series
from .bodies import BodyLogger
from .digest import Digest, DigestingStream, ends_with_footer, seal
from .layout import (
    APPLICATION_ID,
    DIGEST,
    FILE_DIGEST,
    FORMAT,
    META,
    MODE,
    PALETTE,
    SAMPLE_TIMELINE,
    SAMPLES,
    SCENERY,
    SCENERY_COLOUR,
    STATE,
    STRIP,
    STRIPS,
    SUMMARY,
    TIMELINE,
    TRANSITIONS,
    WARNINGS,
    WORLD,
    entity,
)
from .stream import CHUNK, Chunk, chunks, sample_count
from .urdf import UrdfLogger, urdf_source
from .views import UnitGroup, blueprint, coordinate_units, series_label, unit_groups

#: Rows sent to Rerun between waits for its pipeline to write them (``drain``): Rerun queues
#: what it is sent, some 150 bytes a row, until its file sink has written it.
DRAIN_ROWS = 65536


def write_rrd(
    execution: Execution,
    scene: Any = None,
    path: str | os.PathLike | None = None,
    *,
    model: Model | HybridSystem | None = None,
    rate: float | None = None,
) -> Path:
    """Record ``execution`` to the Rerun file ``path`` headlessly (no viewer, no network).

    ``scene`` is a ``legsim.scene.Scene`` (its model gives geometry, scenery and energy) or
    None with ``model=`` a ``legsim.builders.Model`` or a plain ``HybridSystem`` (or neither:
    states and events only).
    ``rate`` (per simulated second) thins the samples: see ``stream.kept_samples``. The file is written
    to a temporary name, streamed there, and renamed when complete (``legsim.output.files``).
    Returns the path; raises RecordingError naming the file.
    """
    if path is None:
        raise RecordingError("write_rrd needs a path to write to")
    path = Path(path)
    content = prepare(execution, scene, model, rate, str(path))

    def write(tmp: Path) -> None:
        with recording_stream() as rec:
            rec.save(tmp)
            record(rec, content)
            seal(rec, tmp, FILE_DIGEST)
        check_complete(tmp, path)

    try:
        write_atomic(path, write, what="recording")
    except OutputError as exc:
        # write_atomic chains the OSError behind a failed write: say what the OS said.
        reason = exc.__cause__
        if isinstance(reason, OSError):
            raise RecordingError(f"{path}: cannot write the recording: {reason.strerror or reason}") from exc
        raise RecordingError(str(exc)) from exc
    return path


def check_complete(written: Path, path: Path) -> None:
    """RecordingError naming ``path`` unless the file ``written`` ends with Rerun's footer: a
    recording the SDK could not finish (no space left as it closed) must not replace ``path``."""
    if not ends_with_footer(written):
        raise RecordingError(
            f"{path}: the recording is incomplete: Rerun did not finish the file ({written.stat().st_size} bytes, "
            f"no footer; is the disk full?); nothing was written"
        )


@dataclass
class Content:
    """What a recording holds: the execution, its model (or None), the rate its samples are
    thinned to (per s, or None), how many samples the run computed, and the run summary."""

    execution: Execution
    scene: Any
    model: Model | None
    computed_samples: int
    rate: float | None
    summary: dict[str, Any]


def prepare(
    execution: Execution, scene: Any, model: Model | HybridSystem | None, rate: float | None, where: str
) -> Content:
    """The content of a recording, its arguments checked (RecordingError naming ``where``)."""
    if not isinstance(execution, Execution):
        raise RecordingError(f"{where}: write_rrd needs a legsim Execution, got {type(execution).__name__}")
    if rate is not None:
        try:
            rate = positive("rate", rate)
        except LegsimError as exc:
            raise RecordingError(f"{where}: {exc}") from None
    model = resolve_model(scene, model, "write_rrd")
    return Content(execution, scene, model, sample_count(execution), rate, run_summary(execution, scene, model))


class recording_stream:
    """A new Rerun recording stream (``with``: disconnected, its sinks flushed, on leaving)."""

    def __enter__(self) -> Any:
        import rerun as rr

        self.rec = rr.RecordingStream(APPLICATION_ID, recording_id=uuid.uuid4())
        if not rr.is_enabled(self.rec):
            raise RecordingError(
                "Rerun logging is disabled in this environment (RERUN=off?); unset RERUN to write recordings"
            )
        return self.rec

    def __exit__(self, *exc: object) -> None:
        try:
            self.rec.flush()
        finally:
            self.rec.disconnect()


def record(rec: Any, content: Content) -> Layout:
    """Log the whole recording of ``content`` to the stream ``rec``; the layout its blueprint was
    made from (``legsim.output.rrd.views.blueprint``'s arguments)."""
    import rerun as rr

    digest = Digest()
    digested = DigestingStream(rec, digest, SAMPLE_TIMELINE)
    log = _Logger(rr, digested, content)
    digested.log(WORLD, rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    bodies = log.stream()
    log.modes()
    log.events()
    scenery = log.scenery()
    log.header(_meta(content, bodies, scenery), bodies, scenery)
    layout = log.blueprint(log.entities, bodies, scenery)
    # Last, and not digested itself: the digest of everything logged above.
    rec.log(DIGEST, rr.TextDocument(json.dumps(digest.document()), media_type="text/plain"), static=True)
    return layout


#: A blueprint's arguments: the plot views by unit, and the (x, z) corners of what is drawn or None.
Layout = tuple[list[UnitGroup], tuple[np.ndarray, np.ndarray] | None]


def _meta(content: Content, bodies: BodyLogger | UrdfLogger | None, scenery: dict[str, np.ndarray]) -> dict[str, Any]:
    """The ``legsim/meta`` document: what reading the recording back needs besides the rows."""
    ex = content.execution
    return {
        "format": FORMAT,
        "summary": content.summary,
        "scene": None if content.scene is None else str(getattr(content.scene, "path", "")),
        "state_names": {m: list(v) for m, v in ex.state_names.items()},
        "state_units": {m: list(v) for m, v in ex.state_units.items()},
        "modes": _mode_list(ex),
        "t0": float(ex.t0),
        "t_end": float(ex.t_end),
        "parts": list(bodies.parts) if isinstance(bodies, BodyLogger) else [],
        "point_parts": bodies.point_parts if isinstance(bodies, BodyLogger) else [],
        "urdf": bodies.entities() if isinstance(bodies, UrdfLogger) else None,
        "scenery": list(scenery),
        "has_geometry": isinstance(bodies, BodyLogger),
        "rate": content.rate,
        "computed_samples": content.computed_samples,
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


def _summary_markdown(meta: dict[str, Any]) -> str:
    """The run summary as the markdown document the viewer shows."""
    s = meta["summary"]
    seq = s.get("mode_sequence", [])
    shown = " → ".join(seq[:30]) + (f" … ({len(seq) - 30} more)" if len(seq) > 30 else "")
    names = s.get("state_names", [])
    final = ", ".join(
        f"{n} = {v:.6g}" if isinstance(v, float) else f"{n} = {v}"
        for n, v in zip(names, s.get("final_state", []), strict=False)
    )
    lines = [
        f"# {s.get('scene') or s.get('system', 'legsim run')}",
        "",
        f"* status: **{s.get('status')}** {s.get('message') or ''}",
        f"* t_final: {s.get('t_final')} s, method {s.get('method')}, h = {s.get('h')}, eps = {s.get('eps')}",
        f"* steps {s.get('steps')}, halvings {s.get('halvings')}, transitions {s.get('transitions')}",
        f"* mode sequence: {shown}",
        f"* final mode {s.get('final_mode')}: {final}",
    ]
    if meta.get("rate"):
        lines.append(
            f"* recorded {meta.get('samples')} of {meta.get('computed_samples')} samples "
            f"(at most {meta['rate']:g} per second, every transition kept)"
        )
    if "energy_initial" in s:
        lines.append(f"* energy: {s.get('energy_initial')} J → {s.get('energy_final')} J")
    lines += ["", "```json", json.dumps(s, indent=2), "```"]
    return "\n".join(lines)


class _Logger:
    """Logs the parts of a recording to the stream ``rec`` (``rr`` is the rerun module)."""

    def __init__(self, rr: Any, rec: Any, content: Content) -> None:
        self.rr, self.rec, self.content = rr, rec, content
        ex = content.execution
        self.units = coordinate_units(ex.state_names, ex.state_units)
        self.unwritten = 0
        #: The chunk being logged; the samples logged before it; coordinate -> entity path.
        self.chunk: Chunk | None = None
        self.count = 0
        self.entities: dict[str, str] = {}
        # What the modes and events, logged after the samples, need of them: the rows where
        # the pieces start, the row at or before each warning, and the times of those rows.
        self.segment_starts: list[np.ndarray] = []
        self.strip_samples: list[np.ndarray] = []
        self.warning_times = np.array([w.time for w in ex.warnings], dtype=float)
        self.warning_rows = np.zeros(len(ex.warnings), dtype=np.int64)
        self.row_times: dict[int, float] = {}

    def indexes(self, rows: np.ndarray) -> list:
        """The ``sample`` and ``sim_time`` index columns of the sample rows ``rows``."""
        rr = self.rr
        return [
            rr.TimeColumn(SAMPLE_TIMELINE, sequence=np.asarray(rows, dtype=np.int64)),
            rr.TimeColumn(TIMELINE, duration=self.times_of(rows)),
        ]

    def times_of(self, rows: np.ndarray) -> np.ndarray:
        """The times (s) of sample ``rows``: of the chunk being logged, or noted by ``note``."""
        rows = np.asarray(rows, dtype=np.int64)
        chunk = self.chunk
        if chunk is not None and (
            not len(rows) or (rows.min() >= chunk.first and rows.max() < chunk.first + len(chunk.times))
        ):
            return chunk.times[rows - chunk.first]
        return np.array([self.row_times[row] for row in rows.tolist()], dtype=float)

    def stream(self) -> BodyLogger | UrdfLogger | None:
        """The samples, series and robot, a chunk at a time; returns what logged the robot."""
        bodies = self.start_robot()
        for chunk in chunks(self.content.execution, self.content.rate, CHUNK):
            self.chunk = chunk
            self.samples(chunk)
            self.series(chunk)
            self.robot(chunk, bodies)
            self.note(chunk)
            self.count += len(chunk.times)
        self.chunk = None
        if isinstance(bodies, BodyLogger):
            bodies.finish()
        return bodies

    def note(self, chunk: Chunk) -> None:
        """Keep the rows of the chunk that the modes and events are logged at, and their times."""
        if len(chunk.segment_starts):
            self.segment_starts.append(chunk.segment_starts)
        if len(chunk.strip_samples):
            self.strip_samples.append(chunk.strip_samples)
        for row in np.concatenate([chunk.segment_starts, chunk.strip_samples]).tolist():
            if row - chunk.first < len(chunk.times):
                self.row_times[row] = float(chunk.times[row - chunk.first])
        at = np.searchsorted(chunk.times, self.warning_times, side="right") - 1
        for i in np.flatnonzero(at >= 0).tolist():
            self.warning_rows[i] = chunk.first + at[i]
            self.row_times[int(self.warning_rows[i])] = float(chunk.times[at[i]])

    def send(self, path: str, rows: np.ndarray, columns: list) -> None:
        self.rec.send_columns(path, indexes=self.indexes(rows), columns=columns)
        self.drain(len(rows))

    def send_values(
        self, path: str, rows: np.ndarray, values: np.ndarray, columns: Callable[[np.ndarray], list]
    ) -> None:
        """``columns(values[piece])`` at ``rows[piece]``, a piece of ``DRAIN_ROWS`` at a time."""
        for start in range(0, len(rows), DRAIN_ROWS):
            piece = slice(start, start + DRAIN_ROWS)
            self.send(path, rows[piece], columns(values[piece]))

    def drain(self, rows: int) -> None:
        """Count ``rows`` sent; every ``DRAIN_ROWS`` wait until Rerun has written what it was
        sent, so that its queue, and memory, stay bounded however long the run."""
        self.unwritten += rows
        if self.unwritten >= DRAIN_ROWS:
            self.rec.flush()
            self.unwritten = 0

    def header(
        self, meta: dict[str, Any], bodies: BodyLogger | UrdfLogger | None, scenery: dict[str, np.ndarray]
    ) -> None:
        """``legsim/meta`` and the markdown ``summary``."""
        rr, rec = self.rr, self.rec
        meta = {**meta, "samples": self.count}
        rec.log(META, rr.TextDocument(json.dumps(meta), media_type="text/plain"), static=True)
        rec.log(SUMMARY, rr.TextDocument(_summary_markdown(meta), media_type="text/markdown"), static=True)

    def samples(self, chunk: Chunk) -> None:
        """``legsim/samples``: the exact time of every sample of ``chunk``."""
        self.send_values(SAMPLES, chunk.rows, chunk.times, lambda t: typed_columns(self.rr, t=t))

    def series(self, chunk: Chunk) -> None:
        """``state/<name>`` over ``chunk``, each named with its unit when it first appears."""
        rr, ex = self.rr, self.content.execution
        for name, (rows, values) in trace_series(ex, chunk).items():  # type: ignore[arg-type]
            if name not in self.entities:
                path = self.entities[name] = entity(STATE, name)
                self.rec.log(path, rr.SeriesLines(names=[series_label(name, self.units.get(name, ""))]), static=True)
            self.send_values(self.entities[name], rows, values, lambda v: rr.Scalars.columns(scalars=v))

    def modes(self) -> None:
        """``mode`` (a state change per segment, with its times) and ``strip`` (the band of
        the strips: the transition's name from a strip's entry, reset after its exit)."""
        rr, ex = self.rr, self.content.execution
        modes = _mode_list(ex)
        self.rec.log(
            MODE,
            rr.StateConfiguration(values=modes, colors=[PALETTE[i % len(PALETTE)] for i in range(len(modes))]),
            static=True,
        )
        segs = ex.segments
        self.send(
            MODE,
            _joined(self.segment_starts),
            [
                *rr.StateChange.columns(state=[s.mode for s in segs]),
                *typed_columns(
                    rr,
                    t_start=np.array([s.t_start for s in segs], dtype=float),
                    t_end=np.array([s.t_end for s in segs], dtype=float),
                ),
            ],
        )
        entries = _joined(self.strip_samples)
        resets = entries[entries + 2 < self.count] + 2
        rows = np.concatenate([entries, resets])
        states = [s.name for s in ex.strips] + [""] * len(resets)
        order = np.argsort(rows, kind="stable")
        if len(rows):
            self.send(STRIP, rows[order], rr.StateChange.columns(state=[states[i] for i in order]))

    def events(self) -> None:
        """``events/strips``, ``events/transitions`` and ``events/warnings`` (text with fields)."""
        rr, ex = self.rr, self.content.execution
        strips, trs = ex.strips, ex.transitions
        rows = _joined(self.strip_samples)
        if len(rows):
            self.send(
                STRIPS,
                rows,
                [
                    *rr.TextLog.columns(
                        text=[
                            f"strip of {s.name} in '{s.mode}': {s.time:.9g} s to {s.exit_time:.9g} s" for s in strips
                        ],
                        level=["DEBUG"] * len(strips),
                    ),
                    *typed_columns(
                        rr,
                        mode=[s.mode for s in strips],
                        name=[s.name for s in strips],
                        entry=np.array([s.time for s in strips], dtype=float),
                        exit=np.array([s.exit_time for s in strips], dtype=float),
                    ),
                ],
            )
        if trs:
            # A transition is logged on its strip's entry sample; strips and transitions pair up
            # in order, except a final strip cut short by t_final or the transition budget.
            self.send(TRANSITIONS, rows[: len(trs)], _transition_columns(rr, trs))
        if ex.warnings:
            self.send(
                WARNINGS,
                self.warning_rows,
                [
                    *rr.TextLog.columns(text=[w.message for w in ex.warnings], level=["WARN"] * len(ex.warnings)),
                    *typed_columns(
                        rr,
                        kind=[w.kind for w in ex.warnings],
                        time=np.array([w.time for w in ex.warnings], dtype=float),
                    ),
                ],
            )

    def start_robot(self) -> BodyLogger | UrdfLogger | None:
        """What logs ``world/robot/...``: a URDF robot through Rerun's loader (logged now:
        ``legsim.output.rrd.urdf``), any other robot by the parts it draws; None without one."""
        model = self.content.model
        if model is None or model.geometry is None:
            return None
        source = urdf_source(model)
        if source is None:
            return BodyLogger(self.rr, self.rec, self.indexes)
        robot = UrdfLogger(self.rr, self.rec, self.indexes, source["file"], source["root"])
        robot.start()
        return robot

    def robot(self, chunk: Chunk, bodies: BodyLogger | UrdfLogger | None) -> None:
        """The robot at the samples of ``chunk``: a URDF robot's joint and root transforms, or
        the parts the model draws."""
        ex = self.content.execution
        if isinstance(bodies, UrdfLogger):
            for mode, (rows, states) in chunk.blocks.items():
                bodies.add(rows, ex.state_names[mode], states)
                self.drain(len(rows) * (len(bodies.joints) + 1))
        elif isinstance(bodies, BodyLogger):
            model = self.content.model
            assert model is not None and model.geometry is not None
            state_at = _state_lookup(chunk)
            drawn = []
            for row in chunk.rows.tolist():
                mode, state = state_at(row)
                drawn.append(
                    _draw(model.geometry, model.system.name, mode, state, float(chunk.times[row - chunk.first]))
                )
            bodies.add(chunk.rows, drawn)
            self.drain(len(chunk.times) * len(bodies.tracks))

    def scenery(self) -> dict[str, np.ndarray]:
        """``world/scenery/<part>``, static."""
        from .poses import to_3d

        rr, scenery = self.rr, scenery_only(self.content.model)
        for part, line in scenery.items():
            self.rec.log(
                entity(SCENERY, part),
                rr.LineStrips3D([to_3d(line)], colors=[SCENERY_COLOUR], radii=[-1.5]),
                static=True,
            )
        return scenery

    def blueprint(
        self, entities: dict[str, str], bodies: BodyLogger | UrdfLogger | None, scenery: dict[str, np.ndarray]
    ) -> Layout:
        """The viewer's layout (``legsim.output.rrd.views``), sent with the recording; its arguments."""
        import rerun.blueprint as rrb

        ex = self.content.execution
        groups = unit_groups(entities, coordinate_units(ex.state_names, ex.state_units))
        box = bodies.box() if bodies is not None else None
        if box is None and scenery:
            allp = np.concatenate(list(scenery.values()))
            box = (allp.min(axis=0), allp.max(axis=0))
        self.rec.send_blueprint(blueprint(rrb, groups, box))
        return groups, box


def _joined(rows: list[np.ndarray]) -> np.ndarray:
    """The rows of every chunk, in order (none: an empty int64 array)."""
    return np.concatenate(rows) if rows else np.empty(0, dtype=np.int64)


def _state_lookup(chunk: Chunk) -> Callable[[int], tuple[str, np.ndarray]]:
    """row -> (mode, state) of a sample of ``chunk``."""
    position = np.zeros(len(chunk.times), dtype=np.int64)
    for rows, _ in chunk.blocks.values():
        position[rows - chunk.first] = np.arange(len(rows))

    def state_at(row: int) -> tuple[str, np.ndarray]:
        mode = chunk.mode_names[chunk.mode_index[row - chunk.first]]
        return mode, chunk.blocks[mode][1][position[row - chunk.first]]

    return state_at


def _transition_columns(rr: Any, trs: list) -> list:
    """The ``events/transitions`` columns: a text line and the fields of each transition."""
    return [
        *rr.TextLog.columns(
            text=[
                f"{t.name}: {t.source} -> {t.target} at {t.time:.9g} s "
                f"(reset at {t.exit_time:.9g} s, depth {t.depth:.3g})"
                for t in trs
            ],
            level=["INFO"] * len(trs),
        ),
        *typed_columns(
            rr,
            name=[t.name for t in trs],
            source=[t.source for t in trs],
            target=[t.target for t in trs],
            edge=[f"{t.source} -> {t.target}" for t in trs],
            index=np.array([t.index for t in trs], dtype=np.int64),
            time=np.array([t.time for t in trs], dtype=float),
            landing_time=np.array([t.landing_time for t in trs], dtype=float),
            exit_time=np.array([t.exit_time for t in trs], dtype=float),
            depth=np.array([t.depth for t in trs], dtype=float),
            state_before=[np.asarray(t.state_before, dtype=float) for t in trs],
            state_after=[np.asarray(t.state_after, dtype=float) for t in trs],
        ),
    ]


def typed_columns(rr: Any, **columns: Any) -> list:
    """``AnyValues`` columns from arrays (one number per row), lists of strings and lists of
    arrays (one variable-length list per row).

    The values go in as arrow arrays: AnyValues would otherwise convert every element through
    a Python list, which dominates the cost of runs with many transitions.
    """
    import pyarrow as pa

    arrays: dict[str, pa.Array] = {}
    for key, value in columns.items():
        if isinstance(value, list) and value and isinstance(value[0], np.ndarray):
            sizes = np.array([len(v) for v in value], dtype=np.int32)
            offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int32)
            arrays[key] = pa.ListArray.from_arrays(pa.array(offsets, type=pa.int32()), pa.array(np.concatenate(value)))
        elif isinstance(value, list):
            arrays[key] = pa.array(value, type=pa.string())
        else:
            arrays[key] = pa.array(value)
    return [*rr.AnyValues.columns(**arrays)]
